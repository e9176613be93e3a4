#include "zerog/emu/ati_board.hpp"

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>

namespace zerog::emu {

namespace netcanoem = proto::netcanoem;
using Clock = std::chrono::steady_clock;

namespace {

// Fault bits of the status word (manual 9610-05-1030, status code table).
constexpr std::uint16_t kCriticalFaultBits = (1u << 1) | netcanoem::kStatusAnyError;
constexpr std::uint16_t kBusErrorFaultBits =
    netcanoem::kStatusCanBusError | netcanoem::kStatusAnyError;
constexpr auto kServeReadTimeout = std::chrono::milliseconds(5);

std::int16_t to_gauge(double counts) {
  return static_cast<std::int16_t>(std::clamp(std::round(counts), -32768.0, 32767.0));
}

// A request the board answers: standard data frame of its id, the opcode's request length.
bool is_request(const proto::CanFrame& frame, std::uint8_t base_id) {
  if ((frame.id & ~proto::kCanStandardIdMask) != 0 || netcanoem::base_id_of(frame.id) != base_id) {
    return false;
  }
  switch (static_cast<netcanoem::Opcode>(netcanoem::opcode_of(frame.id))) {
    case netcanoem::Opcode::sample_a:
    case netcanoem::Opcode::serial_number:
    case netcanoem::Opcode::counts:
    case netcanoem::Opcode::units:
    case netcanoem::Opcode::firmware_version:
      return frame.len == 0;
    case netcanoem::Opcode::matrix_sg01:
    case netcanoem::Opcode::active_calibration:
    case netcanoem::Opcode::diagnostic_adc:
      return frame.len == 1;
    default:
      return false;
  }
}

}  // namespace

const char* ft_fault_name(FtFault fault) {
  switch (fault) {
    case FtFault::none:
      return "none";
    case FtFault::silent:
      return "silent";
    case FtFault::critical:
      return "critical";
    case FtFault::saturated:
      return "saturated";
    case FtFault::bus_error_bit:
      return "bus_error_bit";
  }
  return "?";
}

AtiBoard::AtiBoard(const AtiBoardConfig& config) : config_(config), rng_(config.seed) {
  const std::string where = "AtiBoardConfig.";
  if (config.base_id > netcanoem::kMaxBaseId) {
    throw std::invalid_argument(where + "base_id " + std::to_string(config.base_id) +
                                " is above 127 (a 7-bit CAN base id)");
  }
  if (config.firmware.has_counts() &&
      (config.counts_per_force == 0 || config.counts_per_torque == 0)) {
    throw std::invalid_argument(where +
                                "counts_per_force/counts_per_torque must be positive (got " +
                                std::to_string(config.counts_per_force) + ", " +
                                std::to_string(config.counts_per_torque) + ")");
  }
  if (!(config.gauge_noise_counts >= 0.0) || !std::isfinite(config.gauge_noise_counts)) {
    throw std::invalid_argument(where + "gauge_noise_counts must be finite and >= 0 (got " +
                                std::to_string(config.gauge_noise_counts) + ")");
  }

  // The calibration exactly as the sensor will read it: each row through the wire (float32).
  calibration_.firmware = config.firmware;
  std::copy(config.serial.begin(), config.serial.end(), calibration_.serial_number.begin());
  for (int row = 0; row < 6; ++row) {
    const auto frames = netcanoem::encode_matrix_row(config.base_id, config.matrix[row]);
    for (int part = 0; part < 3; ++part) {
      std::array<double, 2> pair{};
      if (!frames || netcanoem::decode_matrix_part((*frames)[part], config.base_id, part, pair) !=
                         netcanoem::DecodeStatus::ok) {
        throw std::invalid_argument(where + "matrix row " + std::to_string(row) +
                                    " has a coefficient that is not a finite float32");
      }
      calibration_.matrix[row][2 * part] = pair[0];
      calibration_.matrix[row][2 * part + 1] = pair[1];
    }
  }
  calibration_.counts_from_device = config.firmware.has_counts();
  calibration_.counts_per_force =
      calibration_.counts_from_device ? config.counts_per_force : netcanoem::kDefaultCounts;
  calibration_.counts_per_torque =
      calibration_.counts_from_device ? config.counts_per_torque : netcanoem::kDefaultCounts;
  calibration_.force_unit = config.force_unit;
  calibration_.torque_unit = config.torque_unit;

  // A: one count on gauge j → the wrench the sensor computes (the codec's own formula, probed
  // column by column; it is linear in the gauges).
  const std::array<double, 6> no_bias{};
  Eigen::Matrix<double, 6, 6> wire;  // the same in the calibration's units, for the rank check
  si_known_ = true;
  for (int j = 0; j < 6; ++j) {
    std::array<std::int16_t, 6> unit{};
    unit[j] = 1;
    const std::array<double, 6> w = netcanoem::gauges_to_wrench(calibration_, unit, no_bias);
    const auto w_si = netcanoem::gauges_to_wrench_si(calibration_, unit, no_bias);
    for (int i = 0; i < 6; ++i) {
      wire(i, j) = w[i];
      forward_(i, j) = w_si ? (*w_si)[i] : 0.0;
    }
    si_known_ = si_known_ && w_si.has_value();
  }
  const Eigen::FullPivLU<Eigen::Matrix<double, 6, 6>> lu(wire);
  if (!lu.isInvertible()) {
    throw std::invalid_argument(where + "matrix is singular (rank " + std::to_string(lu.rank()) +
                                " of 6): no gauges produce an arbitrary wrench");
  }
  inverse_ = si_known_ ? Eigen::Matrix<double, 6, 6>(forward_.inverse())
                       : Eigen::Matrix<double, 6, 6>::Zero();
  if (!si_known_) forward_.setZero();
  for (int j = 0; j < 6; ++j) gauges_exact_[j] = config.gauge_bias[j];
  if (!netcanoem::thermistor_conversion_valid(config.thermistor)) {
    throw std::invalid_argument(where +
                                "thermistor: celsius_at_zero_counts and celsius_per_count must be "
                                "finite and celsius_per_count not 0");
  }
  set_temperature(config.temperature_C);
}

void AtiBoard::set_temperature(double temperature_C) {
  const std::optional<std::uint16_t> counts =
      netcanoem::thermistor_counts(config_.thermistor, temperature_C);
  if (!counts) {
    throw std::invalid_argument("AtiBoard::set_temperature: " + std::to_string(temperature_C) +
                                " °C is not finite or outside the thermistor channel's 0–65535 "
                                "counts (AtiBoardConfig.thermistor)");
  }
  const std::lock_guard lock(mutex_);
  thermistor_counts_ = *counts;
}

std::uint16_t AtiBoard::thermistor_counts() const {
  const std::lock_guard lock(mutex_);
  return thermistor_counts_;
}

std::array<double, 6> AtiBoard::count_resolution_si() const {
  std::array<double, 6> r{};
  for (int i = 0; i < 6; ++i) r[i] = forward_.row(i).cwiseAbs().sum();
  return r;
}

std::array<double, 6> AtiBoard::full_scale_si() const {
  std::array<double, 6> range{};
  if (!si_known_) return range;
  for (int i = 0; i < 6; ++i) {
    double best = std::numeric_limits<double>::infinity();
    for (int j = 0; j < 6; ++j) {
      const double g = std::abs(inverse_(j, i));
      if (g > 0) best = std::min(best, (32766.0 - std::abs(config_.gauge_bias[j])) / g);
    }
    range[i] = best;
  }
  return range;
}

std::array<double, 6> AtiBoard::gauges_of(const std::array<double, 6>& wrench_sensor_si) const {
  if (!si_known_) {
    throw std::logic_error("AtiBoard::set_wrench: unknown unit codes (force " +
                           std::to_string(config_.force_unit) + ", torque " +
                           std::to_string(config_.torque_unit) +
                           "): no conversion from N and N·m to gauges");
  }
  Eigen::Matrix<double, 6, 1> w;
  for (int i = 0; i < 6; ++i) {
    if (!std::isfinite(wrench_sensor_si[i])) {
      throw std::invalid_argument("AtiBoard::set_wrench: component " + std::to_string(i) +
                                  " is not finite");
    }
    w(i) = wrench_sensor_si[i];
  }
  const Eigen::Matrix<double, 6, 1> g = inverse_ * w;
  std::array<double, 6> out{};
  for (int j = 0; j < 6; ++j) out[j] = config_.gauge_bias[j] + g(j);
  return out;
}

void AtiBoard::set_wrench(const std::array<double, 6>& wrench_sensor_si) {
  const std::array<double, 6> g = gauges_of(wrench_sensor_si);
  const std::lock_guard lock(mutex_);
  gauges_exact_ = g;
}

void AtiBoard::queue_sample(const std::array<double, 6>& wrench_sensor_si) {
  const std::array<double, 6> g = gauges_of(wrench_sensor_si);
  const std::lock_guard lock(mutex_);
  lockstep_ = true;
  queue_.push_back(g);
  ++counters_.queued;
}

bool AtiBoard::answers_within(std::chrono::nanoseconds timeout) const {
  const std::lock_guard lock(mutex_);
  return fault_ != FtFault::silent && quirks_.ignore_requests == 0 && !quirks_.no_sample_response &&
         delay_ < timeout;
}

std::size_t AtiBoard::samples_queued() const {
  const std::lock_guard lock(mutex_);
  return queue_.size();
}

void AtiBoard::set_gauges(const std::array<std::int16_t, 6>& gauges) {
  const std::lock_guard lock(mutex_);
  for (int j = 0; j < 6; ++j) gauges_exact_[j] = gauges[j];
}

std::array<std::int16_t, 6> AtiBoard::gauges() const {
  const std::lock_guard lock(mutex_);
  std::array<std::int16_t, 6> g{};
  for (int j = 0; j < 6; ++j) g[j] = to_gauge(gauges_exact_[j]);
  return g;
}

void AtiBoard::set_status_word(std::uint16_t status) {
  const std::lock_guard lock(mutex_);
  status_word_ = status;
}

void AtiBoard::set_fault(FtFault fault) {
  const std::lock_guard lock(mutex_);
  fault_ = fault;
}

FtFault AtiBoard::fault() const {
  const std::lock_guard lock(mutex_);
  return fault_;
}

void AtiBoard::set_response_delay(std::chrono::microseconds delay) {
  const std::lock_guard lock(mutex_);
  delay_ = std::max(delay, std::chrono::microseconds(0));
}

void AtiBoard::set_quirks(const AtiBoardQuirks& quirks) {
  if (quirks.before_sample_count > quirks.before_sample.size()) {
    throw std::invalid_argument("AtiBoardQuirks.before_sample_count " +
                                std::to_string(quirks.before_sample_count) + " is above 4");
  }
  const std::lock_guard lock(mutex_);
  quirks_ = quirks;
}

AtiBoardQuirks AtiBoard::quirks() const {
  const std::lock_guard lock(mutex_);
  return quirks_;
}

AtiBoard::Counters AtiBoard::counters() const {
  const std::lock_guard lock(mutex_);
  return counters_;
}

std::size_t AtiBoard::respond(const proto::CanFrame& request, Response& out) {
  const std::lock_guard lock(mutex_);
  return respond_locked(request, out).frames;
}

AtiBoard::Step AtiBoard::respond_locked(const proto::CanFrame& request, Response& out) {
  const std::uint8_t base = config_.base_id;
  if (!is_request(request, base)) {
    ++counters_.other_frames;
    return {};
  }
  const auto opcode = static_cast<netcanoem::Opcode>(netcanoem::opcode_of(request.id));
  ++counters_.requests;
  if (opcode == netcanoem::Opcode::sample_a) {
    ++counters_.sample_requests;
    if (lockstep_ && queue_.empty()) {
      ++counters_.queue_underruns;
    } else if (lockstep_) {
      gauges_exact_ = queue_.front();
      queue_.pop_front();
    }
  }
  if (fault_ == FtFault::silent || quirks_.ignore_requests > 0) {
    if (fault_ != FtFault::silent) --quirks_.ignore_requests;
    ++counters_.ignored;
    if (opcode == netcanoem::Opcode::sample_a) ++counters_.sample_requests_ignored;
    return {};
  }
  Step step;
  auto put = [&](const std::optional<proto::CanFrame>& frame) {
    if (frame && step.frames < out.size()) out[step.frames++] = *frame;
  };
  switch (opcode) {
    case netcanoem::Opcode::sample_a: {
      step.sample = true;
      for (std::size_t i = 0; i < quirks_.before_sample_count; ++i) put(quirks_.before_sample[i]);
      if (quirks_.no_sample_response) break;
      std::array<std::int16_t, 6> gauges{};
      for (int j = 0; j < 6; ++j) {
        const double noise =
            config_.gauge_noise_counts > 0 ? config_.gauge_noise_counts * normal_(rng_) : 0.0;
        gauges[j] = to_gauge(gauges_exact_[j] + noise);
      }
      std::uint16_t status = status_word_;
      if (fault_ == FtFault::saturated) gauges[0] = 32767;
      if (fault_ == FtFault::critical) status |= kCriticalFaultBits;
      if (fault_ == FtFault::bus_error_bit) status |= kBusErrorFaultBits;
      if (const auto frames = netcanoem::encode_sample(base, gauges, status)) {
        put((*frames)[0]);
        put((*frames)[1]);
        ++counters_.samples_sent;
        if (netcanoem::saturated_gauges(gauges) != 0) ++counters_.saturated_samples;
        if (netcanoem::classify_status(status) == netcanoem::StatusClass::critical) {
          ++counters_.critical_samples;
        }
      }
      break;
    }
    case netcanoem::Opcode::matrix_sg01:
      if (request.data[0] < 6) {
        if (const auto frames =
                netcanoem::encode_matrix_row(base, config_.matrix[request.data[0]])) {
          for (const proto::CanFrame& f : *frames) put(f);
        }
      }
      break;
    case netcanoem::Opcode::serial_number:
      put(netcanoem::encode_serial_number(base, config_.serial));
      break;
    case netcanoem::Opcode::active_calibration:
      put(netcanoem::encode_active_calibration(
          base, static_cast<std::uint8_t>((request.data[0] + (quirks_.wrong_echo ? 1 : 0)) &
                                          netcanoem::kMaxCalibrationIndex)));
      break;
    case netcanoem::Opcode::counts:
      if (config_.firmware.has_counts()) {  // older firmware does not know opcode 0x7
        put(netcanoem::encode_counts(base, config_.counts_per_force, config_.counts_per_torque));
      }
      break;
    case netcanoem::Opcode::units:
      put(netcanoem::encode_units(base, config_.force_unit, config_.torque_unit));
      break;
    case netcanoem::Opcode::firmware_version:
      put(netcanoem::encode_firmware_version(base, config_.firmware));
      break;
    case netcanoem::Opcode::diagnostic_adc: {
      // Only the thermistor is emulated; the other channels answer mid-scale (not a board fact).
      const std::uint8_t index = request.data[0];
      if (index > netcanoem::kMaxDiagnosticIndex) break;  // not a channel: no answer
      if (quirks_.no_diagnostic_response) break;          // 0x9 reads go unanswered
      const bool thermistor =
          index == static_cast<std::uint8_t>(netcanoem::DiagnosticIndex::thermistor);
      put(netcanoem::encode_diagnostic_adc(base, thermistor ? thermistor_counts_ : 0x8000));
      ++counters_.diagnostic_reads;
      if (thermistor) ++counters_.thermistor_reads;
      break;
    }
    default:
      break;
  }
  if (step.frames == 0) {
    ++counters_.ignored;
    if (opcode == netcanoem::Opcode::sample_a) ++counters_.sample_requests_ignored;
  }
  return step;
}

void AtiBoard::serve(rtio::CanBus& bus, const std::atomic<bool>& stop) {
  rtio::CanRxFrame rx;
  Response out{};
  while (!stop.load(std::memory_order_acquire)) {
    const rtio::CanReadStatus status = bus.read(rx, kServeReadTimeout);
    if (status == rtio::CanReadStatus::io_error || status == rtio::CanReadStatus::not_open) {
      std::this_thread::sleep_for(kServeReadTimeout);  // a broken bus returns at once: no spin
      continue;
    }
    if (status != rtio::CanReadStatus::frame) continue;
    const Clock::time_point received = Clock::now();
    Step step;
    std::chrono::microseconds delay{0};
    {
      const std::lock_guard lock(mutex_);
      step = respond_locked(rx.frame, out);
      delay = delay_;
    }
    if (step.sample && delay.count() > 0) {
      const Clock::time_point due = received + delay;
      for (Clock::time_point now = Clock::now(); now < due; now = Clock::now()) {
        if (stop.load(std::memory_order_acquire)) return;
        std::this_thread::sleep_for(std::min<Clock::duration>(due - now, kServeReadTimeout));
      }
    }
    for (std::size_t i = 0; i < step.frames; ++i) {
      if (bus.write(out[i]) != rtio::CanWriteStatus::ok) {
        const std::lock_guard lock(mutex_);
        ++counters_.tx_failed;
      }
    }
  }
}

void AtiBoardResponder::on_write(const proto::CanFrame& frame, rtio::FakeCanBus& bus) {
  AtiBoard::Response out{};
  const std::size_t n = board_.respond(frame, out);
  for (std::size_t i = 0; i < n; ++i) {
    bus.inject(rtio::CanRxFrame{out[i], arrived_ns_ + static_cast<std::int64_t>(i)});
  }
}

}  // namespace zerog::emu
