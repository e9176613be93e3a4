// ATI NETCANOEM frames (proto/netcanoem.md) as zerog-rt receives them from the CAN bus: the
// sample assembler, the calibration read-out state machine and the single-response decoders, fed
// any sequence of classic CAN frames. All report failures as statuses (never throw).
//
// Input: byte 0 is the board's base id, byte 1 the calibration index asked for; then frames of
// 6–13 bytes: identifier (u32, big-endian, flag bits included), length byte (mod 9: SocketCAN
// never hands over more than 8 bytes), that many data bytes. A 0xFF length byte stands for a
// receive timeout instead of a frame (the read-out then retries).
//
// Properties: a gauge sample re-encodes (encode_sample) into frames that assemble to the same
// sample; each decoded response re-encodes into the frame it came from; a finished read-out's
// calibration converts gauges to finite wrenches; the assembler's counters add up.
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>

#include "fuzz_util.hpp"
#include "zerog/proto/netcanoem.hpp"

namespace can = zerog::proto::netcanoem;
using zerog::proto::CanFrame;

namespace {

void check_sample_round_trip(std::uint8_t base_id, const can::GaugeSample& sample) {
  const auto frames = can::encode_sample(base_id, sample.gauges, sample.status);
  ZEROG_FUZZ_CHECK(frames.has_value());
  can::SampleAssembler assembler(base_id);
  can::GaugeSample back;
  ZEROG_FUZZ_CHECK(assembler.feed((*frames)[0], back) == can::FeedResult::pending);
  ZEROG_FUZZ_CHECK(assembler.feed((*frames)[1], back) == can::FeedResult::sample);
  ZEROG_FUZZ_CHECK(back.gauges == sample.gauges && back.status == sample.status);
  ZEROG_FUZZ_CHECK(back.status_class == sample.status_class);
  ZEROG_FUZZ_CHECK(back.saturated_mask == sample.saturated_mask);
}

void check_same_frame(const std::optional<CanFrame>& encoded, const CanFrame& frame) {
  ZEROG_FUZZ_CHECK(encoded.has_value());
  ZEROG_FUZZ_CHECK(*encoded == frame);
}

void check_decoders(std::uint8_t base_id, std::uint8_t index, const CanFrame& frame) {
  for (int part = 0; part < 3; ++part) {
    std::array<double, 2> coefficients{};
    if (can::decode_matrix_part(frame, base_id, part, coefficients) == can::DecodeStatus::ok) {
      for (double c : coefficients) ZEROG_FUZZ_CHECK(std::isfinite(c));
    }
  }
  std::array<char, can::kSerialNumberLength + 1> serial{};
  if (can::decode_serial_number(frame, base_id, serial) == can::DecodeStatus::ok) {
    ZEROG_FUZZ_CHECK(serial[can::kSerialNumberLength] == '\0');
  }
  if (can::decode_active_calibration(frame, base_id, index) == can::DecodeStatus::ok) {
    check_same_frame(can::encode_active_calibration(base_id, index), frame);
  }
  std::uint32_t per_force = 0, per_torque = 0;
  if (can::decode_counts(frame, base_id, per_force, per_torque) == can::DecodeStatus::ok) {
    check_same_frame(can::encode_counts(base_id, per_force, per_torque), frame);
  }
  std::uint8_t force_unit = 0, torque_unit = 0;
  if (can::decode_units(frame, base_id, force_unit, torque_unit) == can::DecodeStatus::ok) {
    check_same_frame(can::encode_units(base_id, force_unit, torque_unit), frame);
  }
  can::FirmwareVersion version;
  if (can::decode_firmware_version(frame, base_id, version) == can::DecodeStatus::ok) {
    check_same_frame(can::encode_firmware_version(base_id, version), frame);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  zerog::fuzz::ByteReader in(data, size);
  const std::uint8_t base_id = in.u8() & can::kMaxBaseId;
  const std::uint8_t index = in.u8() % (can::kMaxCalibrationIndex + 1);

  can::SampleAssembler assembler(base_id);
  can::CalibrationReadout readout(base_id, index);
  std::uint64_t frames = 0, samples = 0;
  constexpr std::array<double, can::kGaugeCount> kNoBias{};

  while (!in.empty()) {
    if (readout.state() == can::ReadoutState::send_request) {
      const CanFrame request = readout.take_request();
      ZEROG_FUZZ_CHECK(request.len <= zerog::proto::kCanMaxDataLength);
    }
    CanFrame frame;
    frame.id = in.u32();
    const std::uint8_t length_byte = in.u8();
    if (length_byte == 0xFF) {
      if (readout.state() == can::ReadoutState::awaiting_response) readout.retry();
      continue;
    }
    frame.len = length_byte % (zerog::proto::kCanMaxDataLength + 1);
    for (std::uint8_t i = 0; i < frame.len; ++i) frame.data[i] = in.u8();
    ++frames;

    can::GaugeSample sample;
    if (assembler.feed(frame, sample) == can::FeedResult::sample) {
      ++samples;
      check_sample_round_trip(base_id, sample);
    }
    if (readout.state() == can::ReadoutState::awaiting_response) readout.feed(frame);
    check_decoders(base_id, index, frame);
  }

  const can::AssemblerCounters& c = assembler.counters();
  ZEROG_FUZZ_CHECK(c.samples == samples);
  ZEROG_FUZZ_CHECK(c.samples + c.stray + c.wrong_length + c.out_of_order + c.requests <= frames);

  if (readout.state() == can::ReadoutState::done) {
    ZEROG_FUZZ_CHECK(readout.error() == can::ReadoutError::none);
    const can::Calibration& calibration = readout.calibration();
    ZEROG_FUZZ_CHECK(calibration.serial_number[can::kSerialNumberLength] == '\0');
    const std::array<std::int16_t, can::kGaugeCount> gauges{1000, -2000, 32767, -32768, 5, 0};
    const auto wrench = can::gauges_to_wrench(calibration, gauges, kNoBias);
    // Counts per unit of 0 would divide by zero: the read-out must not accept them.
    for (double w : wrench) ZEROG_FUZZ_CHECK(std::isfinite(w));
    if (const auto si = can::gauges_to_wrench_si(calibration, gauges, kNoBias)) {
      for (double w : *si) ZEROG_FUZZ_CHECK(std::isfinite(w));
    }
  } else if (readout.state() == can::ReadoutState::failed) {
    ZEROG_FUZZ_CHECK(readout.error() != can::ReadoutError::none);
  }
  return 0;
}
