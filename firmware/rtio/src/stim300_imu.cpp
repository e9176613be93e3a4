#include "zerog/rtio/stim300_imu.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdint>

#include "wait.hpp"

namespace zerog::rtio {

namespace stim300 = proto::stim300;

Stim300Imu::Stim300Imu(const Stim300Config& config) : config_(config), decoder_(config.stream) {}

ImuStartStatus Stim300Imu::start() {
  started_ = false;
  disconnected_ = false;
  const SerialOpenResult opened = port_.open(config_.path, config_.serial);
  if (!opened.ok()) {
    last_errno_ = opened.error_number;
    return opened.status == SerialOpenStatus::open_failed ? ImuStartStatus::open_failed
                                                          : ImuStartStatus::bad_config;
  }
  decoder_.reset();
  chunk_used_ = chunk_size_ = 0;
  started_ = true;
  return ImuStartStatus::ok;
}

bool Stim300Imu::pop_buffered(ImuSample& out) {
  if (disconnected_ || !started_) return false;
  stim300::Sample sample;
  while (true) {
    if (decoder_.pop(sample)) {
      out.rate_rad_s = sample.rate_rad_s;
      out.accel_m_s2 = sample.accel_m_s2;
      out.incl_m_s2 = sample.incl_m_s2;
      out.rate_valid = sample.rate_valid;
      out.accel_valid = sample.accel_valid;
      out.incl_valid = sample.incl_valid;
      out.rate_status = sample.raw.rate.status;
      out.accel_status = sample.raw.accel.status;
      out.incl_status = sample.raw.incl.status;
      out.counter = sample.raw.counter;
      out.missed_before = sample.missed_before;
      out.latency_s = sample.latency_s;
      out.arrived_ns = chunk_time_ns_;
      out.sequence = ++sequence_;
      return true;
    }
    if (chunk_used_ >= chunk_size_) return false;
    const std::size_t taken = decoder_.push(
        std::span<const std::uint8_t>(chunk_.data() + chunk_used_, chunk_size_ - chunk_used_));
    chunk_used_ += taken;
    // The decoder's buffer holds more than two datagrams and pop() leaves less than one in it,
    // so push() always takes something; if not, start over rather than spin.
    if (taken == 0) decoder_.reset();
  }
}

ImuReadStatus Stim300Imu::read_sample(ImuSample& out) {
  return read_sample_upto(out, UINT64_MAX, config_.read_timeout);
}

ImuReadStatus Stim300Imu::read_sample_upto(ImuSample& out, std::uint64_t bytes_limit,
                                           std::chrono::nanoseconds timeout) {
  if (disconnected_) return ImuReadStatus::disconnected;
  if (!started_) return ImuReadStatus::not_started;
  const std::int64_t deadline = detail::monotonic_ns() + timeout.count();
  bool have_read = false;  // bounded even when garbage streams in faster than the deadline
  while (true) {
    if (pop_buffered(out)) return ImuReadStatus::sample;
    if (own_.bytes_read >= bytes_limit) return ImuReadStatus::drained;
    const std::int64_t left = deadline - detail::monotonic_ns();
    if (left <= 0 && have_read) {
      ++own_.timeouts;
      return ImuReadStatus::timeout;
    }
    have_read = true;
    const std::size_t room = static_cast<std::size_t>(
        std::min<std::uint64_t>(chunk_.size(), bytes_limit - own_.bytes_read));
    const SerialReadResult r = port_.read(std::span<std::uint8_t>(chunk_.data(), room),
                                          std::chrono::nanoseconds(left > 0 ? left : 0));
    switch (r.status) {
      case SerialReadStatus::data:
        chunk_size_ = r.size;
        chunk_used_ = 0;
        chunk_time_ns_ = detail::monotonic_ns();
        own_.bytes_read += r.size;
        continue;
      case SerialReadStatus::timeout:
        ++own_.timeouts;
        return ImuReadStatus::timeout;
      case SerialReadStatus::hangup:
        ++own_.disconnects;
        disconnected_ = true;
        started_ = false;
        port_.close();
        return ImuReadStatus::disconnected;
      case SerialReadStatus::io_error:
        last_errno_ = port_.last_errno();
        ++own_.io_errors;
        return ImuReadStatus::io_error;
      case SerialReadStatus::not_open:
        return ImuReadStatus::not_started;
    }
  }
}

ImuCounters Stim300Imu::counters() const {
  ImuCounters c = own_;
  const stim300::StreamCounters& d = decoder_.counters();
  c.samples = d.datagrams;
  c.invalid_samples = d.invalid_samples;
  c.bytes_skipped = d.bytes_skipped;
  c.crc_failures = d.crc_failures;
  c.sync_losses = d.sync_losses;
  c.counter_gaps = d.counter_gaps;
  c.datagrams_missed = d.datagrams_missed;
  return c;
}

}  // namespace zerog::rtio
