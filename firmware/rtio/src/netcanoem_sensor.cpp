#include "zerog/rtio/netcanoem_sensor.hpp"

#include <algorithm>

#include "wait.hpp"

namespace zerog::rtio {

namespace netcanoem = proto::netcanoem;

namespace {

// A standard data frame of the board's diagnostic opcode (0x9)?
bool is_diagnostic(const proto::CanFrame& frame, std::uint8_t base_id) {
  return frame.id == netcanoem::can_id(base_id, netcanoem::Opcode::diagnostic_adc);
}

}  // namespace

NetcanoemSensor::NetcanoemSensor(CanBus& bus, const NetcanoemConfig& config)
    : bus_(bus), config_(config), assembler_(config.base_id) {}

CanSocketConfig NetcanoemSensor::socket_config(std::uint8_t base_id, int buffer_frames) {
  CanSocketConfig config;
  config.filters[0] = netcanoem::filter_for(base_id);
  config.filter_count = 1;
  config.error_mask = kCanAllErrors;
  // A classic frame costs about 1 KiB of socket memory with the skb overhead (candump's rule
  // of thumb for -r); the kernel doubles what we ask for and reports that.
  config.receive_buffer_bytes = buffer_frames * 1024;
  config.timestamps = true;
  return config;
}

void NetcanoemSensor::drain_stale() {
  CanRxFrame rx;
  netcanoem::GaugeSample ignored;
  for (int i = 0; i < config_.max_stale_frames; ++i) {
    const CanReadStatus status = bus_.read(rx, std::chrono::nanoseconds(0));
    if (status == CanReadStatus::frame) {
      // The thermistor's answer usually comes after its poll's sample: expected, not stale.
      if (!is_diagnostic(rx.frame, config_.base_id)) ++own_.stale_frames;
      feed(rx, ignored);  // before the next request: anything it completes is late
    } else if (status != CanReadStatus::error_frame && status != CanReadStatus::bad_length) {
      break;  // empty (or failing: the request path reports it)
    }
  }
}

bool NetcanoemSensor::feed(const CanRxFrame& rx, netcanoem::GaugeSample& out) {
  if (is_diagnostic(rx.frame, config_.base_id)) {
#ifndef ZEROG_MUTANT_DIAGNOSTIC_AS_GAUGE
    take_diagnostic(rx);
    return false;
#else
    // TEST ONLY (tests/unit/CMakeLists.txt, netcanoem_mutant_test): the broken variant the
    // interleaving tests must catch: the 0x9 payload taken as the gauge stream's second half.
    CanRxFrame as_gauge = rx;
    as_gauge.frame.id = netcanoem::can_id(config_.base_id, netcanoem::Opcode::sample_b);
    as_gauge.frame.len = netcanoem::kSampleBLength;
    return feed(as_gauge, out);
#endif
  }
  // A 0x0 half is tagged with the poll that is open when it arrives; its 0x1 completes it in
  // order, whatever came between.
  if (assembler_.feed(rx.frame, out, poll_) != netcanoem::FeedResult::sample) return false;
  if (in_poll_ && out.tag == poll_) return true;
  ++late_samples_;  // answers an earlier request: its own two frames, but too old
  late_pairing_ = true;
  return false;
}

void NetcanoemSensor::take_diagnostic(const CanRxFrame& rx) {
  if (rx.frame.len == netcanoem::kDiagnosticRequestLength) return;  // a request, looped back
  std::uint16_t counts = 0;
  if (netcanoem::decode_diagnostic_adc(rx.frame, config_.base_id, counts) !=
      netcanoem::DecodeStatus::ok) {
    ++own_.thermistor_wrong_length;
    return;
  }
  // The answer does not name its channel: only one we asked for (and not yet had) is taken, so
  // someone else's read of another channel on the bus cannot pass for a temperature.
  if (!thermistor_open_) {
    ++own_.thermistor_unrequested;
    return;
  }
  thermistor_open_ = false;
  have_thermistor_ = true;
  thermistor_counts_ = counts;
  thermistor_rx_ns_ = rx.arrived_ns;
  thermistor_poll_ = poll_;
  thermistor_stale_ = false;  // fresh again
  ++own_.thermistor_readings;
}

void NetcanoemSensor::check_thermistor_age() {
#ifndef ZEROG_MUTANT_THERMISTOR_NEVER_EXPIRES
  if (thermistor_stale_ || config_.thermistor_every_polls <= 0 || !config_.thermistor) return;
  if (poll_ - thermistor_poll_ <= static_cast<std::uint64_t>(config_.thermistor_max_age_polls))
    return;
  thermistor_stale_ = true;  // the board stopped answering 0x9 (thermistor_lost counts them)
  ++own_.thermistor_expired;
#else
  // TEST ONLY (tests/unit/CMakeLists.txt, netcanoem_mutant_no_expiry_test): the broken variant
  // the expiry test must catch: a held reading of any age.
#endif
}

void NetcanoemSensor::request_thermistor() {
  if (config_.thermistor_every_polls <= 0) return;
  if (polls_to_thermistor_ > 0) {
    --polls_to_thermistor_;
    return;
  }
  polls_to_thermistor_ = config_.thermistor_every_polls - 1;
  if (thermistor_open_) ++own_.thermistor_lost;  // the last read never got its answer
  thermistor_open_ = false;
  const CanWriteStatus written = bus_.write(thermistor_request_);
  if (written == CanWriteStatus::ok) {
    ++own_.thermistor_requests;
    thermistor_open_ = true;
  } else if (written == CanWriteStatus::would_block) {
    ++own_.tx_would_block;  // tried again at the next due poll; the sample is not affected
  } else {
    ++own_.io_errors;  // the sample path reports a failing bus
  }
}

void NetcanoemSensor::fill_temperature(FtSample& out) const {
  out.thermistor_valid = have_thermistor_;
  out.thermistor_counts = thermistor_counts_;
  out.temperature_stale = thermistor_stale_;
  out.temperature_valid = have_thermistor_ && config_.thermistor.has_value() && !thermistor_stale_;
  out.temperature_C = out.temperature_valid
                          ? netcanoem::thermistor_celsius(*config_.thermistor, thermistor_counts_)
                          : 0.0;
  const bool times_known = out.arrived_ns != 0 && thermistor_rx_ns_ != 0;
  out.temperature_age_s =
      have_thermistor_ && times_known
          ? std::max(0.0, static_cast<double>(out.arrived_ns - thermistor_rx_ns_) * 1e-9)
          : 0.0;
}

FtStartStatus NetcanoemSensor::start() {
  started_ = false;
  readout_error_ = netcanoem::ReadoutError::none;
  if (config_.base_id > netcanoem::kMaxBaseId ||
      config_.calibration_index > netcanoem::kMaxCalibrationIndex || config_.startup_attempts < 1 ||
      config_.thermistor_every_polls < 0 ||
      (config_.thermistor && !netcanoem::thermistor_conversion_valid(*config_.thermistor)) ||
      (config_.thermistor && config_.thermistor_every_polls > 0 &&
       config_.thermistor_max_age_polls <= config_.thermistor_every_polls)) {
    return FtStartStatus::bad_config;
  }
  drain_stale();
  netcanoem::CalibrationReadout readout(config_.base_id, config_.calibration_index);
  int attempts = 0;  // of the current request
  std::int64_t deadline = 0;
  CanRxFrame rx;
  while (readout.state() != netcanoem::ReadoutState::done &&
         readout.state() != netcanoem::ReadoutState::failed) {
    if (readout.state() == netcanoem::ReadoutState::send_request) {
      ++attempts;
      const CanWriteStatus written = bus_.write(readout.take_request());
      if (written == CanWriteStatus::io_error || written == CanWriteStatus::not_open) {
        ++own_.io_errors;
        startup_ignored_ = readout.ignored_frames();
        return FtStartStatus::io_error;
      }
      // would_block: nothing went out, the wait below times out and the request is retried.
      deadline = detail::monotonic_ns() + config_.startup_timeout.count();
      continue;
    }
    const std::int64_t left = deadline - detail::monotonic_ns();
    const CanReadStatus status =
        left > 0 ? bus_.read(rx, std::chrono::nanoseconds(left)) : CanReadStatus::timeout;
    if (status == CanReadStatus::frame) {
      if (readout.feed(rx.frame) == netcanoem::ReadoutState::send_request) attempts = 0;
    } else if (status == CanReadStatus::timeout) {
      if (attempts >= config_.startup_attempts) {
        startup_ignored_ = readout.ignored_frames();
        return FtStartStatus::no_response;
      }
      ++startup_retries_;
      readout.retry();
    } else if (status == CanReadStatus::io_error || status == CanReadStatus::not_open) {
      ++own_.io_errors;
      startup_ignored_ = readout.ignored_frames();
      return FtStartStatus::io_error;
    }
    // error frames and bad-length reads are counted by the bus; keep waiting.
  }
  startup_ignored_ = readout.ignored_frames();
  if (readout.state() == netcanoem::ReadoutState::failed) {
    readout_error_ = readout.error();
    return readout_error_ == netcanoem::ReadoutError::bad_argument ? FtStartStatus::bad_config
                                                                   : FtStartStatus::readout_failed;
  }
  calibration_ = readout.calibration();
  if (!netcanoem::newton_per_force_unit(calibration_.force_unit) ||
      !netcanoem::newton_metre_per_torque_unit(calibration_.torque_unit)) {
    return FtStartStatus::unknown_units;
  }
  request_ = netcanoem::request_sample(config_.base_id).value_or(proto::CanFrame{});
  thermistor_request_ =
      netcanoem::request_diagnostic_adc(config_.base_id, netcanoem::DiagnosticIndex::thermistor)
          .value_or(proto::CanFrame{});
  thermistor_open_ = false;
  have_thermistor_ = false;
  thermistor_poll_ = poll_;  // the first reading is due within the maximum age, too
  thermistor_stale_ = false;
  polls_to_thermistor_ = 0;  // the first poll reads it: a temperature from the start
  assembler_.reset();
  started_ = true;
  return FtStartStatus::ok;
}

FtReadStatus NetcanoemSensor::read_sample(FtSample& out) {
  return read_sample_waiting(out, config_.sample_timeout);
}

FtReadStatus NetcanoemSensor::read_sample_waiting(FtSample& out,
                                                  std::chrono::nanoseconds at_least) {
  if (!started_) return FtReadStatus::not_started;
  // A response to an earlier, timed-out request must not pass for the answer to this one: its
  // frames are fed in order (drain_stale, then below), and only the last poll's first half may
  // still wait for its 0x1; older ones are dropped (counted dropped_incomplete).
  in_poll_ = false;
  drain_stale();
  assembler_.drop_pending_before(poll_);
  late_pairing_ = false;
  const CanWriteStatus written = bus_.write(request_);
  if (written != CanWriteStatus::ok) {
    if (written == CanWriteStatus::would_block) {
      ++own_.tx_would_block;
      return FtReadStatus::tx_failed;
    }
    ++own_.io_errors;
    return FtReadStatus::io_error;
  }
  ++own_.requests;
  ++poll_;
  in_poll_ = true;
  request_thermistor();
  check_thermistor_age();
  const std::int64_t deadline =
      detail::monotonic_ns() + std::max(config_.sample_timeout, at_least).count();
  CanRxFrame rx;
  netcanoem::GaugeSample gauges;
  while (true) {
    const std::int64_t left = deadline - detail::monotonic_ns();
    const CanReadStatus status =
        left > 0 ? bus_.read(rx, std::chrono::nanoseconds(left)) : CanReadStatus::timeout;
    if (status == CanReadStatus::timeout) break;
    if (status == CanReadStatus::io_error || status == CanReadStatus::not_open) {
      ++own_.io_errors;
      return FtReadStatus::io_error;
    }
    if (status != CanReadStatus::frame) continue;  // error frame / bad length: counted by the bus
    if (!feed(rx, gauges)) continue;

    // Cannot fail: start() checked the unit codes.
    const auto wrench =
        netcanoem::gauges_to_wrench_si(calibration_, gauges.gauges, config_.bias_gauges);
    out.wrench_si = wrench.value_or(std::array<double, 6>{});
    out.gauges = gauges.gauges;
    out.status_word = gauges.status;
    out.saturated_mask = gauges.saturated_mask;
    if (gauges.status_class == netcanoem::StatusClass::critical) {
      out.status = FtSampleStatus::critical;
    } else if (gauges.saturated_mask != 0) {
      out.status = FtSampleStatus::saturated;
    } else if (gauges.status_class == netcanoem::StatusClass::warning) {
      out.status = FtSampleStatus::warning;
    } else {
      out.status = FtSampleStatus::ok;
    }
    out.valid = gauges.usable() && wrench.has_value();
    out.arrived_ns = rx.arrived_ns;
    out.sequence = ++sequence_;
    fill_temperature(out);
    ++own_.samples;
    return FtReadStatus::sample;
  }
  ++own_.timeouts;
  // This poll's first half may wait for a 0x1 still on its way. But if a 0x1 completed an older
  // half in this poll and ours did not come, that 0x1 may have been ours (its own lost): the
  // pairing cannot be trusted any more, so start over (the halves are counted as dropped).
  if (late_pairing_) assembler_.drop_pending_before(poll_ + 1);
  return FtReadStatus::timeout;
}

FtCounters NetcanoemSensor::counters() const {
  FtCounters c = own_;
  const netcanoem::AssemblerCounters& a = assembler_.counters();
  c.samples_warning = a.warning;
  c.samples_critical = a.critical;
  c.samples_saturated = a.saturated;
  c.stray_frames = a.stray;
  c.wrong_length = a.wrong_length;
  c.out_of_order = a.out_of_order;
  c.dropped_incomplete = a.dropped_incomplete;
  c.overtaken = a.overtaken;
  c.late_samples = late_samples_;
  const CanBusCounters& bus = bus_.counters();
  c.error_frames = bus.error_frames;
  c.kernel_drops = bus.kernel_drops;
  c.bad_length = bus.bad_length;
  c.tx_would_block = own_.tx_would_block;
  return c;  // the thermistor counters are own_'s
}

}  // namespace zerog::rtio
