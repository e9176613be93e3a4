// Modbus TCP requests as zerog-rt's supervisory server sees them (proto/modbus.md): the byte
// stream of one connection is framed (frame_request) and each complete request decided (decide)
// against the current tunables and state. Both are noexcept and must be safe on any bytes.
//
// Input: byte 0 picks the loop state, the rest is the connection's byte stream.
//
// Properties: framing consumes at least the MBAP header and at most the bytes there are and one
// maximal ADU; a decision is an exception with a code and a reason, or names a table range that
// the request asked for; proposed tunables are finite.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>

#include "fuzz_util.hpp"
#include "zerog/modbus/request.hpp"

namespace mb = zerog::modbus;

namespace {

void check_decision(const mb::Decision& d, std::span<const std::uint8_t> adu) {
  ZEROG_FUZZ_CHECK(d.why != nullptr);
  if (adu.size() > mb::kMbapBytes) ZEROG_FUZZ_CHECK(d.function == adu[mb::kMbapBytes]);
  switch (d.action) {
    case mb::Action::exception:
      ZEROG_FUZZ_CHECK(d.exception != mb::ExceptionCode::none);
      break;
    case mb::Action::write_tunables: {
      const zerog::loop::Tunables& t = d.tunables;
      ZEROG_FUZZ_CHECK(std::isfinite(t.body.mass_kg) && t.body.mass_kg > 0.0);
      for (int i = 0; i < 3; ++i) ZEROG_FUZZ_CHECK(std::isfinite(t.p_sensor_com_m[i]));
      ZEROG_FUZZ_CHECK(d.exception == mb::ExceptionCode::none);
      break;
    }
    default:
      ZEROG_FUZZ_CHECK(d.exception == mb::ExceptionCode::none);
      break;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  zerog::fuzz::ByteReader in(data, size);
  const auto state = static_cast<zerog::loop::State>(in.u8() % 4);
  const zerog::loop::Tunables current{};
  std::span<const std::uint8_t> stream = in.rest();
  while (!stream.empty()) {
    const mb::Frame frame = mb::frame_request(stream);
    if (frame.status == mb::FrameStatus::incomplete) break;
    if (frame.status == mb::FrameStatus::invalid) {
      ZEROG_FUZZ_CHECK(frame.why != nullptr && frame.why[0] != '\0');
      break;  // the server closes the connection
    }
    ZEROG_FUZZ_CHECK(frame.length > mb::kMbapBytes);
    ZEROG_FUZZ_CHECK(frame.length <= stream.size() && frame.length <= mb::kMaxAduBytes);
    const std::span<const std::uint8_t> adu = stream.first(frame.length);
    check_decision(mb::decide(adu, current, state), adu);
    stream = stream.subspan(frame.length);
  }
  return 0;
}
