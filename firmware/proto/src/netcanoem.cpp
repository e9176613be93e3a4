#include "zerog/proto/netcanoem.hpp"

#include <cmath>

#include "big_endian.hpp"

namespace zerog::proto::netcanoem {

using detail::load_f32;
using detail::load_i16;
using detail::load_u16;
using detail::load_u32;

namespace {

constexpr bool base_ok(std::uint8_t base_id) { return base_id <= kMaxBaseId; }

CanFrame make_frame(std::uint8_t base_id, Opcode opcode, std::uint8_t len) {
  CanFrame frame;
  frame.id = can_id(base_id, opcode);
  frame.len = len;
  return frame;
}

std::optional<CanFrame> empty_request(std::uint8_t base_id, Opcode opcode) {
  if (!base_ok(base_id)) return std::nullopt;
  return make_frame(base_id, opcode, 0);
}

// A standard data frame of `base_id` with opcode `opcode` and length `len`?
DecodeStatus check(const CanFrame& frame, std::uint8_t base_id, Opcode opcode, std::uint8_t len) {
  if (frame.id != can_id(base_id, opcode)) return DecodeStatus::wrong_id;  // flags must be clear
  if (frame.len != len) return DecodeStatus::wrong_length;
  return DecodeStatus::ok;
}

}  // namespace

std::optional<CanFrame> request_sample(std::uint8_t base_id) {
  return empty_request(base_id, Opcode::sample_a);
}

std::optional<CanFrame> request_matrix_row(std::uint8_t base_id, std::uint8_t row) {
  if (!base_ok(base_id) || row >= kGaugeCount) return std::nullopt;
  CanFrame frame = make_frame(base_id, Opcode::matrix_sg01, 1);
  frame.data[0] = row;
  return frame;
}

std::optional<CanFrame> request_serial_number(std::uint8_t base_id) {
  return empty_request(base_id, Opcode::serial_number);
}

std::optional<CanFrame> request_set_active_calibration(std::uint8_t base_id, std::uint8_t index) {
  if (!base_ok(base_id) || index > kMaxCalibrationIndex) return std::nullopt;
  CanFrame frame = make_frame(base_id, Opcode::active_calibration, 1);
  frame.data[0] = index;
  return frame;
}

std::optional<CanFrame> request_counts(std::uint8_t base_id) {
  return empty_request(base_id, Opcode::counts);
}

std::optional<CanFrame> request_units(std::uint8_t base_id) {
  return empty_request(base_id, Opcode::units);
}

std::optional<CanFrame> request_firmware_version(std::uint8_t base_id) {
  return empty_request(base_id, Opcode::firmware_version);
}

std::optional<CanFrame> request_diagnostic_adc(std::uint8_t base_id, DiagnosticIndex index) {
  const auto i = static_cast<std::uint8_t>(index);
  if (!base_ok(base_id) || i > kMaxDiagnosticIndex) return std::nullopt;
  CanFrame frame = make_frame(base_id, Opcode::diagnostic_adc, kDiagnosticRequestLength);
  frame.data[0] = i;
  return frame;
}

std::uint8_t saturated_gauges(const std::array<std::int16_t, kGaugeCount>& gauges) {
  std::uint8_t mask = 0;
  for (int i = 0; i < kGaugeCount; ++i) {
    if (gauges[i] == 32767 || gauges[i] == -32768) mask = static_cast<std::uint8_t>(mask | 1u << i);
  }
  return mask;
}

FeedResult SampleAssembler::feed(const CanFrame& frame, GaugeSample& out, std::uint64_t tag) {
  // Standard data frame (no flag bits) of this board?
  const bool ours = (frame.id & ~kCanStandardIdMask) == 0 && base_id_of(frame.id) == base_id_;
  const std::uint8_t opcode = opcode_of(frame.id);
  if (!ours || opcode > static_cast<std::uint8_t>(Opcode::sample_b)) {
    ++counters_.stray;
    return FeedResult::stray;
  }
  if (opcode == static_cast<std::uint8_t>(Opcode::sample_a)) {
    if (frame.len == 0) {
      ++counters_.requests;
      return FeedResult::request;
    }
    if (frame.len != kSampleALength) {
      ++counters_.wrong_length;
      return FeedResult::wrong_length;
    }
    const bool dropped = pending_count_ == kPendingCapacity;
    if (dropped) {  // the oldest half never got its 0x1
      ++counters_.dropped_incomplete;
      pending_head_ = (pending_head_ + 1) % kPendingCapacity;
      --pending_count_;
    }
    Half& half = pending_[(pending_head_ + pending_count_) % kPendingCapacity];
    half.status = load_u16(&frame.data[0]);
    for (int i = 0; i < 3; ++i) half.even[i] = load_i16(&frame.data[2 + 2 * i]);
    half.tag = tag;
    ++pending_count_;
    return dropped ? FeedResult::dropped_previous : FeedResult::pending;
  }
  // sample_b
  if (frame.len != kSampleBLength) {
    ++counters_.wrong_length;
    return FeedResult::wrong_length;
  }
  if (pending_count_ == 0) {
    ++counters_.out_of_order;
    return FeedResult::out_of_order;
  }
  const Half& half = pending_[pending_head_];  // the oldest: pairs in order
  pending_head_ = (pending_head_ + 1) % kPendingCapacity;
  --pending_count_;
  if (pending_count_ != 0) ++counters_.overtaken;
  for (int i = 0; i < 3; ++i) {
    out.gauges[2 * i] = half.even[i];
    out.gauges[2 * i + 1] = load_i16(&frame.data[2 * i]);
  }
  out.status = half.status;
  out.tag = half.tag;
  out.status_class = classify_status(out.status);
  out.saturated_mask = saturated_gauges(out.gauges);
  ++counters_.samples;
  if (out.status_class == StatusClass::critical) ++counters_.critical;
  if (out.status_class == StatusClass::warning) ++counters_.warning;
  if (out.saturated_mask != 0) ++counters_.saturated;
  return FeedResult::sample;
}

std::size_t SampleAssembler::drop_pending_before(std::uint64_t tag) {
  std::size_t dropped = 0;
  while (pending_count_ != 0 && pending_[pending_head_].tag < tag) {
    pending_head_ = (pending_head_ + 1) % kPendingCapacity;
    --pending_count_;
    ++dropped;
  }
  counters_.dropped_incomplete += dropped;
  return dropped;
}

std::optional<double> newton_per_force_unit(std::uint8_t code) {
  constexpr double kLbf = 4.4482216152605;  // N per pound-force (exact by definition)
  switch (static_cast<ForceUnit>(code)) {
    case ForceUnit::lbf:
      return kLbf;
    case ForceUnit::N:
      return 1.0;
    case ForceUnit::klbf:
      return 1000.0 * kLbf;
    case ForceUnit::kN:
      return 1000.0;
    case ForceUnit::kgf:
      return 9.80665;
    case ForceUnit::gf:
      return 9.80665e-3;
  }
  return std::nullopt;
}

std::optional<double> newton_metre_per_torque_unit(std::uint8_t code) {
  constexpr double kLbf = 4.4482216152605;
  switch (static_cast<TorqueUnit>(code)) {
    case TorqueUnit::lbf_in:
      return kLbf * 0.0254;
    case TorqueUnit::lbf_ft:
      return kLbf * 0.3048;
    case TorqueUnit::N_m:
      return 1.0;
    case TorqueUnit::N_mm:
      return 1e-3;
    case TorqueUnit::kgf_cm:
      return 9.80665e-2;
    case TorqueUnit::kN_m:
      return 1000.0;
  }
  return std::nullopt;
}

DecodeStatus decode_matrix_part(const CanFrame& frame, std::uint8_t base_id, int part,
                                std::array<double, 2>& coefficients) {
  if (part < 0 || part > 2) return DecodeStatus::wrong_id;
  const auto opcode =
      static_cast<Opcode>(static_cast<int>(Opcode::matrix_sg01) + part);  // 0x2, 0x3, 0x4
  if (DecodeStatus s = check(frame, base_id, opcode, kMatrixPartLength); s != DecodeStatus::ok) {
    return s;
  }
  const float a = load_f32(&frame.data[0]);
  const float b = load_f32(&frame.data[4]);
  if (!std::isfinite(a) || !std::isfinite(b)) return DecodeStatus::bad_value;
  coefficients = {a, b};
  return DecodeStatus::ok;
}

DecodeStatus decode_serial_number(const CanFrame& frame, std::uint8_t base_id,
                                  std::array<char, kSerialNumberLength + 1>& serial) {
  if (DecodeStatus s = check(frame, base_id, Opcode::serial_number, kSerialNumberLength);
      s != DecodeStatus::ok) {
    return s;
  }
  for (int i = 0; i < kSerialNumberLength; ++i) serial[i] = static_cast<char>(frame.data[i]);
  serial[kSerialNumberLength] = '\0';
  return DecodeStatus::ok;
}

DecodeStatus decode_active_calibration(const CanFrame& frame, std::uint8_t base_id,
                                       std::uint8_t expected_index) {
  if (DecodeStatus s = check(frame, base_id, Opcode::active_calibration, kActiveCalibrationLength);
      s != DecodeStatus::ok) {
    return s;
  }
  return frame.data[0] == expected_index ? DecodeStatus::ok : DecodeStatus::bad_value;
}

DecodeStatus decode_counts(const CanFrame& frame, std::uint8_t base_id, std::uint32_t& per_force,
                           std::uint32_t& per_torque) {
  if (DecodeStatus s = check(frame, base_id, Opcode::counts, kCountsLength);
      s != DecodeStatus::ok) {
    return s;
  }
  const std::uint32_t f = load_u32(&frame.data[0]);
  const std::uint32_t t = load_u32(&frame.data[4]);
  if (f == 0 || t == 0) return DecodeStatus::bad_value;  // would divide by zero
  per_force = f;
  per_torque = t;
  return DecodeStatus::ok;
}

DecodeStatus decode_units(const CanFrame& frame, std::uint8_t base_id, std::uint8_t& force_unit,
                          std::uint8_t& torque_unit) {
  if (DecodeStatus s = check(frame, base_id, Opcode::units, kUnitsLength); s != DecodeStatus::ok) {
    return s;
  }
  force_unit = frame.data[0];
  torque_unit = frame.data[1];
  return DecodeStatus::ok;
}

DecodeStatus decode_firmware_version(const CanFrame& frame, std::uint8_t base_id,
                                     FirmwareVersion& version) {
  if (DecodeStatus s = check(frame, base_id, Opcode::firmware_version, kFirmwareVersionLength);
      s != DecodeStatus::ok) {
    return s;
  }
  version.major = frame.data[0];
  version.minor = frame.data[1];
  version.build = load_u16(&frame.data[2]);
  return DecodeStatus::ok;
}

DecodeStatus decode_diagnostic_adc(const CanFrame& frame, std::uint8_t base_id,
                                   std::uint16_t& counts) {
  if (DecodeStatus s = check(frame, base_id, Opcode::diagnostic_adc, kDiagnosticAdcLength);
      s != DecodeStatus::ok) {
    return s;
  }
  counts = load_u16(&frame.data[0]);
  return DecodeStatus::ok;
}

const char* decode_status_name(DecodeStatus status) {
  switch (status) {
    case DecodeStatus::ok:
      return "ok";
    case DecodeStatus::wrong_id:
      return "wrong_id";
    case DecodeStatus::wrong_length:
      return "wrong_length";
    case DecodeStatus::bad_value:
      return "bad_value";
  }
  return "?";
}

// --- Thermistor ------------------------------------------------------------------------------

bool thermistor_conversion_valid(const ThermistorConversion& c) {
  return std::isfinite(c.celsius_at_zero_counts) && std::isfinite(c.celsius_per_count) &&
         c.celsius_per_count != 0.0;
}

double thermistor_celsius(const ThermistorConversion& c, std::uint16_t counts) {
  return c.celsius_at_zero_counts + c.celsius_per_count * static_cast<double>(counts);
}

std::optional<std::uint16_t> thermistor_counts(const ThermistorConversion& c, double celsius) {
  if (!thermistor_conversion_valid(c) || !std::isfinite(celsius)) return std::nullopt;
  const double counts = std::round((celsius - c.celsius_at_zero_counts) / c.celsius_per_count);
  if (!(counts >= 0.0 && counts <= 65535.0)) return std::nullopt;
  return static_cast<std::uint16_t>(counts);
}

// --- CalibrationReadout -----------------------------------------------------------------------

CalibrationReadout::CalibrationReadout(std::uint8_t base_id, std::uint8_t calibration_index)
    : base_id_(base_id), index_(calibration_index) {
  if (base_id > kMaxBaseId || calibration_index > kMaxCalibrationIndex) {
    fail(ReadoutError::bad_argument);
  }
}

CanFrame CalibrationReadout::current_request() const {
  std::optional<CanFrame> request;
  switch (step_) {
    case Step::set_calibration:
      request = request_set_active_calibration(base_id_, index_);
      break;
    case Step::firmware:
      request = request_firmware_version(base_id_);
      break;
    case Step::serial:
      request = request_serial_number(base_id_);
      break;
    case Step::matrix:
      request = request_matrix_row(base_id_, row_);
      break;
    case Step::counts:
      request = request_counts(base_id_);
      break;
    case Step::units:
      request = request_units(base_id_);
      break;
  }
  return request.value_or(CanFrame{});  // arguments were checked in the constructor
}

CanFrame CalibrationReadout::take_request() {
  sent_ = current_request();
  if (state_ == ReadoutState::send_request) state_ = ReadoutState::awaiting_response;
  return sent_;
}

void CalibrationReadout::retry() {
  if (state_ != ReadoutState::awaiting_response) return;
  part_ = 0;  // a matrix row is re-read whole
  state_ = ReadoutState::send_request;
}

ReadoutState CalibrationReadout::fail(ReadoutError error) {
  error_ = error;
  state_ = ReadoutState::failed;
  return state_;
}

void CalibrationReadout::advance() {
  state_ = ReadoutState::send_request;
  switch (step_) {
    case Step::set_calibration:
      calibration_.active_calibration = index_;
      step_ = Step::firmware;
      break;
    case Step::firmware:
      step_ = Step::serial;
      break;
    case Step::serial:
      step_ = Step::matrix;
      row_ = 0;
      part_ = 0;
      break;
    case Step::matrix:
      if (++row_ < kGaugeCount) {
        part_ = 0;
      } else if (calibration_.firmware.has_counts()) {
        step_ = Step::counts;
      } else {
        calibration_.counts_per_force = kDefaultCounts;
        calibration_.counts_per_torque = kDefaultCounts;
        calibration_.counts_from_device = false;
        step_ = Step::units;
      }
      break;
    case Step::counts:
      calibration_.counts_from_device = true;
      step_ = Step::units;
      break;
    case Step::units:
      state_ = ReadoutState::done;
      break;
  }
}

ReadoutState CalibrationReadout::feed(const CanFrame& frame) {
  if (state_ != ReadoutState::awaiting_response) {
    if (state_ == ReadoutState::send_request) ++ignored_;
    return state_;
  }
  const bool ours = (frame.id & ~kCanStandardIdMask) == 0 && base_id_of(frame.id) == base_id_;
  // Our own request looped back is ignored, except for set-active-calibration, whose response
  // is byte-identical to the request (the driver must not enable CAN_RAW_RECV_OWN_MSGS).
  const bool own_request = frame == sent_ && step_ != Step::set_calibration;
  if (!ours || own_request) {
    ++ignored_;
    return state_;
  }
  const auto opcode = static_cast<Opcode>(opcode_of(frame.id));
  auto map = [](DecodeStatus s) {
    return s == DecodeStatus::wrong_length ? ReadoutError::wrong_length : ReadoutError::bad_value;
  };
  switch (step_) {
    case Step::set_calibration:
      if (opcode != Opcode::active_calibration) break;
      if (DecodeStatus s = decode_active_calibration(frame, base_id_, index_);
          s != DecodeStatus::ok) {
        return fail(s == DecodeStatus::bad_value ? ReadoutError::echo_mismatch : map(s));
      }
      advance();
      return state_;
    case Step::firmware:
      if (opcode != Opcode::firmware_version) break;
      if (DecodeStatus s = decode_firmware_version(frame, base_id_, calibration_.firmware);
          s != DecodeStatus::ok) {
        return fail(map(s));
      }
      advance();
      return state_;
    case Step::serial:
      if (opcode != Opcode::serial_number) break;
      if (DecodeStatus s = decode_serial_number(frame, base_id_, calibration_.serial_number);
          s != DecodeStatus::ok) {
        return fail(map(s));
      }
      advance();
      return state_;
    case Step::matrix: {
      const int part = static_cast<int>(opcode) - static_cast<int>(Opcode::matrix_sg01);
      if (part < 0 || part > 2) break;
      if (part != part_) return fail(ReadoutError::out_of_order);
      std::array<double, 2> c{};
      if (DecodeStatus s = decode_matrix_part(frame, base_id_, part, c); s != DecodeStatus::ok) {
        return fail(map(s));
      }
      calibration_.matrix[row_][2 * part] = c[0];
      calibration_.matrix[row_][2 * part + 1] = c[1];
      if (++part_ == 3) advance();
      return state_;
    }
    case Step::counts:
      if (opcode != Opcode::counts) break;
      if (DecodeStatus s = decode_counts(frame, base_id_, calibration_.counts_per_force,
                                         calibration_.counts_per_torque);
          s != DecodeStatus::ok) {
        return fail(map(s));
      }
      advance();
      return state_;
    case Step::units:
      if (opcode != Opcode::units) break;
      if (DecodeStatus s =
              decode_units(frame, base_id_, calibration_.force_unit, calibration_.torque_unit);
          s != DecodeStatus::ok) {
        return fail(map(s));
      }
      advance();
      return state_;
  }
  ++ignored_;  // the sample stream or another response of this board
  return state_;
}

// --- Conversion ------------------------------------------------------------------------------

std::array<double, 6> gauges_to_wrench(const Calibration& calibration,
                                       const std::array<std::int16_t, kGaugeCount>& gauges,
                                       const std::array<double, kGaugeCount>& bias_gauges) {
  std::array<double, kGaugeCount> sg{};
  for (int j = 0; j < kGaugeCount; ++j) sg[j] = gauges[j] - bias_gauges[j];
  std::array<double, 6> wrench{};
  for (int i = 0; i < 6; ++i) {
    double sum = 0.0;
    for (int j = 0; j < kGaugeCount; ++j) sum += calibration.matrix[i][j] * sg[j];
    const double counts = i < 3 ? calibration.counts_per_force : calibration.counts_per_torque;
    wrench[i] = sum / counts;
  }
  return wrench;
}

std::optional<std::array<double, 6>> gauges_to_wrench_si(
    const Calibration& calibration, const std::array<std::int16_t, kGaugeCount>& gauges,
    const std::array<double, kGaugeCount>& bias_gauges) {
  const std::optional<double> n = newton_per_force_unit(calibration.force_unit);
  const std::optional<double> nm = newton_metre_per_torque_unit(calibration.torque_unit);
  if (!n || !nm) return std::nullopt;
  std::array<double, 6> wrench = gauges_to_wrench(calibration, gauges, bias_gauges);
  for (int i = 0; i < 6; ++i) wrench[i] *= i < 3 ? *n : *nm;
  return wrench;
}

// --- Response encoders ------------------------------------------------------------------------

std::optional<std::array<CanFrame, 2>> encode_sample(std::uint8_t base_id,
                                                     const std::array<std::int16_t, 6>& gauges,
                                                     std::uint16_t status) {
  if (!base_ok(base_id)) return std::nullopt;
  std::array<CanFrame, 2> frames{make_frame(base_id, Opcode::sample_a, kSampleALength),
                                 make_frame(base_id, Opcode::sample_b, kSampleBLength)};
  detail::store_u16(&frames[0].data[0], status);
  for (int i = 0; i < 3; ++i) {
    detail::store_i16(&frames[0].data[2 + 2 * i], gauges[2 * i]);
    detail::store_i16(&frames[1].data[2 * i], gauges[2 * i + 1]);
  }
  return frames;
}

std::optional<std::array<CanFrame, 3>> encode_matrix_row(std::uint8_t base_id,
                                                         const std::array<double, 6>& row) {
  if (!base_ok(base_id)) return std::nullopt;
  std::array<CanFrame, 3> frames{};
  for (int part = 0; part < 3; ++part) {
    frames[part] =
        make_frame(base_id, static_cast<Opcode>(static_cast<int>(Opcode::matrix_sg01) + part),
                   kMatrixPartLength);
    detail::store_f32(&frames[part].data[0], static_cast<float>(row[2 * part]));
    detail::store_f32(&frames[part].data[4], static_cast<float>(row[2 * part + 1]));
  }
  return frames;
}

std::optional<CanFrame> encode_serial_number(std::uint8_t base_id,
                                             const std::array<char, kSerialNumberLength>& serial) {
  if (!base_ok(base_id)) return std::nullopt;
  CanFrame frame = make_frame(base_id, Opcode::serial_number, kSerialNumberLength);
  for (int i = 0; i < kSerialNumberLength; ++i)
    frame.data[i] = static_cast<std::uint8_t>(serial[i]);
  return frame;
}

std::optional<CanFrame> encode_active_calibration(std::uint8_t base_id, std::uint8_t index) {
  if (!base_ok(base_id) || index > kMaxCalibrationIndex) return std::nullopt;
  CanFrame frame = make_frame(base_id, Opcode::active_calibration, kActiveCalibrationLength);
  frame.data[0] = index;
  return frame;
}

std::optional<CanFrame> encode_counts(std::uint8_t base_id, std::uint32_t per_force,
                                      std::uint32_t per_torque) {
  if (!base_ok(base_id)) return std::nullopt;
  CanFrame frame = make_frame(base_id, Opcode::counts, kCountsLength);
  detail::store_u32(&frame.data[0], per_force);
  detail::store_u32(&frame.data[4], per_torque);
  return frame;
}

std::optional<CanFrame> encode_units(std::uint8_t base_id, std::uint8_t force_unit,
                                     std::uint8_t torque_unit) {
  if (!base_ok(base_id)) return std::nullopt;
  CanFrame frame = make_frame(base_id, Opcode::units, kUnitsLength);
  frame.data[0] = force_unit;
  frame.data[1] = torque_unit;
  return frame;
}

std::optional<CanFrame> encode_firmware_version(std::uint8_t base_id, FirmwareVersion version) {
  if (!base_ok(base_id)) return std::nullopt;
  CanFrame frame = make_frame(base_id, Opcode::firmware_version, kFirmwareVersionLength);
  frame.data[0] = version.major;
  frame.data[1] = version.minor;
  detail::store_u16(&frame.data[2], version.build);
  return frame;
}

std::optional<CanFrame> encode_diagnostic_adc(std::uint8_t base_id, std::uint16_t counts) {
  if (!base_ok(base_id)) return std::nullopt;
  CanFrame frame = make_frame(base_id, Opcode::diagnostic_adc, kDiagnosticAdcLength);
  detail::store_u16(&frame.data[0], counts);
  return frame;
}

}  // namespace zerog::proto::netcanoem
