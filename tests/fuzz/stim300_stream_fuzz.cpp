// STIM300 byte streams (proto/stim300.md) as zerog-rt reads them from the serial port: the stream
// decoder fed in chunks of varying size (as read() returns them), and the single-datagram decoder
// on the raw input. Both report failures as statuses and counters (never throw).
//
// Input: byte 0 picks the decoder's configuration (accepted identifier, accelerometer range),
// byte 1 seeds the chunk sizes, the rest is the serial stream.
//
// Properties: every datagram the decoders accept re-encodes to the same bytes (encode ∘ decode is
// the identity on good datagrams); the stream counters agree with the samples delivered; a
// datagram's SI values are finite.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>

#include "fuzz_util.hpp"
#include "zerog/proto/stim300.hpp"

namespace stim = zerog::proto::stim300;

namespace {

bool same_triplet(const stim::Triplet24& a, const stim::Triplet24& b) {
  return a.counts == b.counts && a.status == b.status;
}
bool same_triplet(const stim::Triplet16& a, const stim::Triplet16& b) {
  return a.counts == b.counts && a.status == b.status;
}
bool same_raw(const stim::RawDatagram& a, const stim::RawDatagram& b) {
  return a.identifier == b.identifier && same_triplet(a.rate, b.rate) &&
         same_triplet(a.accel, b.accel) && same_triplet(a.incl, b.incl) && a.pps == b.pps &&
         a.pps_status == b.pps_status && same_triplet(a.rate_temperature, b.rate_temperature) &&
         same_triplet(a.accel_temperature, b.accel_temperature) &&
         same_triplet(a.incl_temperature, b.incl_temperature) && a.counter == b.counter &&
         a.latency_us == b.latency_us;
}

/// encode(raw) must decode to raw again; returns the encoded bytes' size.
std::size_t check_reencode(const stim::RawDatagram& raw,
                           std::array<std::uint8_t, stim::kMaxDatagramLength + 2>& bytes) {
  const stim::EncodeResult encoded = stim::encode_datagram(raw, false, bytes);
  ZEROG_FUZZ_CHECK(encoded.status == stim::EncodeStatus::ok);
  const stim::DatagramContent* content = stim::find_content(raw.identifier);
  ZEROG_FUZZ_CHECK(content != nullptr);
  ZEROG_FUZZ_CHECK(encoded.size == stim::datagram_length(*content));
  stim::RawDatagram back;
  ZEROG_FUZZ_CHECK(stim::decode_datagram(std::span(bytes.data(), encoded.size), back) ==
                   stim::DecodeStatus::ok);
  ZEROG_FUZZ_CHECK(same_raw(raw, back));
  return encoded.size;
}

void check_sample(const stim::Sample& s) {
  for (double v : s.rate_rad_s) ZEROG_FUZZ_CHECK(std::isfinite(v));
  for (double v : s.accel_m_s2) ZEROG_FUZZ_CHECK(std::isfinite(v));
  for (double v : s.incl_m_s2) ZEROG_FUZZ_CHECK(std::isfinite(v));
  ZEROG_FUZZ_CHECK(std::isfinite(s.latency_s));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  zerog::fuzz::ByteReader in(data, size);
  const std::uint8_t config_byte = in.u8();
  std::uint32_t chunk_seed = in.u8() | 1u;
  const std::span<const std::uint8_t> stream = in.rest();

  // The single-datagram decoder on the stream as it is: a good datagram re-encodes byte for byte.
  std::array<std::uint8_t, stim::kMaxDatagramLength + 2> bytes{};
  stim::RawDatagram raw;
  if (stim::decode_datagram(stream, raw) == stim::DecodeStatus::ok) {
    const std::size_t n = check_reencode(raw, bytes);
    ZEROG_FUZZ_CHECK(n <= stream.size());
    ZEROG_FUZZ_CHECK(std::memcmp(bytes.data(), stream.data(), n) == 0);
  }

  stim::StreamConfig config;
  // 0: any identifier of the table; else one of the table's rows (the configured identifier).
  const std::size_t row = config_byte % (stim::kDatagramTable.size() + 1);
  config.identifier = row == 0 ? 0 : stim::kDatagramTable[row - 1].identifier;
  config.scale.accel_range = static_cast<stim::AccelRange>((config_byte >> 5) % 4);
  stim::StreamDecoder decoder(config);

  std::uint64_t samples = 0;
  std::uint64_t invalid = 0;
  std::uint64_t missed = 0;
  auto sink = [&](const stim::Sample& s) {
    ++samples;
    check_sample(s);
    ZEROG_FUZZ_CHECK(config.identifier == 0 || s.raw.identifier == config.identifier);
    check_reencode(s.raw, bytes);
    missed += s.missed_before;
    if (!s.rate_valid) ++invalid;
  };
  std::span<const std::uint8_t> rest = stream;
  while (!rest.empty()) {
    chunk_seed = chunk_seed * 1103515245u + 12345u;
    const std::size_t chunk = std::min<std::size_t>(rest.size(), 1 + (chunk_seed >> 16) % 64);
    decoder.feed(rest.first(chunk), sink);
    rest = rest.subspan(chunk);
  }
  const stim::StreamCounters& c = decoder.counters();
  ZEROG_FUZZ_CHECK(c.datagrams == samples);
  ZEROG_FUZZ_CHECK(c.datagrams_missed == missed);
  ZEROG_FUZZ_CHECK(c.invalid_samples >= invalid);
  ZEROG_FUZZ_CHECK(c.bytes_skipped <= stream.size());
  return 0;
}
