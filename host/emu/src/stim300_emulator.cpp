#include "zerog/emu/stim300_emulator.hpp"

#include <fcntl.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <span>
#include <stdexcept>

namespace zerog::emu {

namespace stim300 = proto::stim300;

namespace {

std::string errno_text(int error_number) { return std::strerror(error_number); }

bool finite_non_negative(double x) { return std::isfinite(x) && x >= 0.0; }

// The target of the symlink at `path`, or "" when it is not a readable symlink.
std::string read_link(const std::string& path) {
  std::array<char, 4096> target{};
  const ssize_t n = ::readlink(path.c_str(), target.data(), target.size() - 1);
  return n > 0 ? std::string(target.data(), static_cast<std::size_t>(n)) : std::string();
}

// Points `link` at `target`: an existing symlink is replaced atomically, anything else refused.
// The link's failures name the setting they concern: open()'s link_path.
Status make_link(const std::string& link, const std::string& target) {
  struct stat st {};
  if (::lstat(link.c_str(), &st) == 0) {
    if (!S_ISLNK(st.st_mode)) {
      return Status::invalid("link_path", "Stim300Emulator: refusing to replace '" + link +
                                              "': it exists and is not a symlink");
    }
  } else if (errno != ENOENT) {
    return {StatusCode::system_error, "link_path",
            "Stim300Emulator: cannot check '" + link + "': " + errno_text(errno)};
  }
  const std::string temporary = link + ".tmp-" + std::to_string(::getpid());
  ::unlink(temporary.c_str());  // a leftover of a crashed run, if any
  if (::symlink(target.c_str(), temporary.c_str()) != 0) {
    return {StatusCode::system_error, "link_path",
            "Stim300Emulator: cannot create symlink '" + temporary + "': " + errno_text(errno)};
  }
  if (::rename(temporary.c_str(), link.c_str()) != 0) {
    const int error_number = errno;
    ::unlink(temporary.c_str());
    return {StatusCode::system_error, "link_path",
            "Stim300Emulator: cannot move symlink to '" + link + "': " + errno_text(error_number)};
  }
  return {};
}

}  // namespace

const char* imu_fault_name(ImuFault fault) {
  switch (fault) {
    case ImuFault::none:
      return "none";
    case ImuFault::garbage:
      return "garbage";
    case ImuFault::crc_errors:
      return "crc_errors";
    case ImuFault::counter_gaps:
      return "counter_gaps";
    case ImuFault::silent:
      return "silent";
    case ImuFault::status_bits:
      return "status_bits";
  }
  return "?";
}

Stim300Emulator::Stim300Emulator(const Stim300EmulatorConfig& config)
    : config_(config), rng_(config.seed) {
  if (stim300::find_content(config.identifier) == nullptr) {
    throw std::invalid_argument("Stim300EmulatorConfig.identifier " +
                                std::to_string(config.identifier) +
                                " is not a normal-mode datagram of proto::stim300::kDatagramTable");
  }
  if (!finite_non_negative(config.gyro_bias_radps) ||
      !finite_non_negative(config.accel_bias_mps2) || !(config.bias_tau_s > 0.0) ||
      !(config.datagram_period_s > 0.0) || !std::isfinite(config.bias_tau_s) ||
      !std::isfinite(config.datagram_period_s))
    throw std::invalid_argument(
        "Stim300EmulatorConfig: gyro_bias_radps and accel_bias_mps2 must be finite and >= 0, "
        "bias_tau_s and datagram_period_s finite and > 0");
  bias_a_ = std::exp(-config.datagram_period_s / config.bias_tau_s);
  for (int i = 0; i < 3; ++i) {  // the turn-on value: the process's stationary spread
    if (config.gyro_bias_radps > 0.0) gyro_bias_[i] = config.gyro_bias_radps * normal_(rng_);
    if (config.accel_bias_mps2 > 0.0) accel_bias_[i] = config.accel_bias_mps2 * normal_(rng_);
  }
  if (!finite_non_negative(config.gyro_noise_radps) ||
      !finite_non_negative(config.accel_noise_mps2) ||
      !finite_non_negative(config.incl_noise_mps2)) {
    throw std::invalid_argument(
        "Stim300EmulatorConfig: gyro_noise_radps, accel_noise_mps2 and incl_noise_mps2 must be "
        "finite and >= 0");
  }
  if (!std::isfinite(config.temperature_c) || config.pps_raw > 0xFFFFFFu) {
    throw std::invalid_argument(
        "Stim300EmulatorConfig: temperature_c must be finite and pps_raw fit in 24 bits");
  }
}

Stim300Emulator::~Stim300Emulator() {
  const std::lock_guard lock(mutex_);
  close_locked();
  if (!link_path_.empty() && read_link(link_path_) == slave_path_) ::unlink(link_path_.c_str());
}

void Stim300Emulator::close_locked() {
  if (master_ >= 0) ::close(master_);
  if (slave_ >= 0) ::close(slave_);
  master_ = slave_ = -1;
  pending_begin_ = pending_end_ = 0;
}

void Stim300Emulator::unplug() {
  const std::lock_guard lock(mutex_);
  close_locked();
  unplugs_.fetch_add(1, std::memory_order_acq_rel);
}

bool Stim300Emulator::plugged() const {
  const std::lock_guard lock(mutex_);
  return master_ >= 0;
}

bool Stim300Emulator::flush_pending() {
  const std::lock_guard lock(mutex_);
  return master_ < 0 || flush_pending_locked();
}

Status Stim300Emulator::open(const std::string& link_path) {
  const std::lock_guard lock(mutex_);
  close_locked();
  const std::string old_slave = slave_path_;
  slave_path_.clear();
  auto fail = [this](Status why) {
    close_locked();
    slave_path_.clear();
    return why;
  };
  auto os_error = [](std::string message) {
    return Status(StatusCode::system_error, std::move(message));
  };
  bytes_.store(0, std::memory_order_release);
  master_ = ::posix_openpt(O_RDWR | O_NOCTTY | O_CLOEXEC);
  if (master_ < 0)
    return fail(os_error("Stim300Emulator: posix_openpt failed: " + errno_text(errno)));
  const int flags = ::fcntl(master_, F_GETFL);
  if (flags < 0 || ::fcntl(master_, F_SETFL, flags | O_NONBLOCK) != 0 || ::grantpt(master_) != 0 ||
      ::unlockpt(master_) != 0) {
    return fail(os_error("Stim300Emulator: cannot set up the pty master: " + errno_text(errno)));
  }
  std::array<char, 128> name{};
  if (::ptsname_r(master_, name.data(), name.size()) != 0) {
    return fail(os_error("Stim300Emulator: ptsname failed: " + errno_text(errno)));
  }
  const std::string slave(name.data());
  slave_ = ::open(slave.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (slave_ < 0)
    return fail(os_error("Stim300Emulator: cannot open '" + slave + "': " + errno_text(errno)));
  termios tio{};
  if (::tcgetattr(slave_, &tio) != 0) {
    return fail(os_error("Stim300Emulator: tcgetattr on '" + slave + "': " + errno_text(errno)));
  }
  ::cfmakeraw(&tio);
  if (::tcsetattr(slave_, TCSANOW, &tio) != 0) {
    return fail(os_error("Stim300Emulator: tcsetattr on '" + slave + "': " + errno_text(errno)));
  }
  slave_path_ = slave;

  // The link: drop an old one of ours elsewhere, then (re)point the requested one.
  if (!link_path_.empty() && link_path_ != link_path && read_link(link_path_) == old_slave) {
    ::unlink(link_path_.c_str());
  }
  link_path_.clear();
  if (!link_path.empty()) {
    if (Status st = make_link(link_path, slave_path_); !st.ok()) return fail(std::move(st));
    link_path_ = link_path;
  }
  return {};
}

bool Stim300Emulator::flush_pending_locked() {
  while (pending_begin_ < pending_end_) {
    const ssize_t n =
        ::write(master_, pending_.data() + pending_begin_, pending_end_ - pending_begin_);
    if (n > 0) {
      pending_begin_ += static_cast<std::size_t>(n);
      bytes_.fetch_add(static_cast<std::uint64_t>(n), std::memory_order_acq_rel);
    } else if (n < 0 && errno == EINTR) {
      continue;
    } else {
      return false;
    }
  }
  pending_begin_ = pending_end_ = 0;
  return true;
}

bool Stim300Emulator::write_sample(const ImuTruthSample& truth) {
  const std::lock_guard lock(mutex_);
  const std::uint8_t counter = counter_++;
  if (master_ < 0) {
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  const ImuFault fault = fault_.load(std::memory_order_relaxed);
  if (fault == ImuFault::silent) return true;
  if (fault == ImuFault::counter_gaps && (counter & 1u) != 0) {
    skipped_.fetch_add(1, std::memory_order_relaxed);
    return true;
  }

  const stim300::RawDatagram raw = make_raw_locked(truth, config_.identifier, counter, fault);
  const stim300::EncodeResult encoded = stim300::encode_datagram(raw, config_.crlf, buffer_);
  if (encoded.status != stim300::EncodeStatus::ok) {  // cannot happen: identifier checked
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  const std::size_t size = encoded.size;
  if (fault == ImuFault::crc_errors) {
    const std::size_t crc_last = size - 1 - (config_.crlf ? 2 : 0);
    buffer_[crc_last] ^= 0x01;
  } else if (fault == ImuFault::garbage) {
    for (std::size_t i = 0; i < size; ++i) buffer_[i] = static_cast<std::uint8_t>(rng_() & 0xFFu);
  }

  if (!flush_pending_locked()) {
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  ssize_t n = -1;
  do {
    n = ::write(master_, buffer_.data(), size);
  } while (n < 0 && errno == EINTR);
  if (n <= 0) {  // EAGAIN: the pty buffer is full; anything else: the pty is broken
    dropped_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  bytes_.fetch_add(static_cast<std::uint64_t>(n), std::memory_order_acq_rel);
  if (static_cast<std::size_t>(n) < size) {  // the rest goes first next time
    std::copy(buffer_.begin() + n, buffer_.begin() + static_cast<std::ptrdiff_t>(size),
              pending_.begin());
    pending_begin_ = 0;
    pending_end_ = size - static_cast<std::size_t>(n);
  }
  if (fault == ImuFault::garbage) {
    garbage_bytes_.fetch_add(size, std::memory_order_relaxed);
  } else {
    written_.fetch_add(1, std::memory_order_relaxed);
    if (fault == ImuFault::crc_errors) bad_crc_.fetch_add(1, std::memory_order_relaxed);
  }
  return true;
}

stim300::RawDatagram Stim300Emulator::make_raw_locked(const ImuTruthSample& truth,
                                                      std::uint8_t identifier, std::uint8_t counter,
                                                      ImuFault fault) {
  stim300::RawDatagram raw;
  raw.identifier = identifier;
  const double bias_gain = std::sqrt(1.0 - bias_a_ * bias_a_);
  for (int i = 0; i < 3; ++i) {  // bias instability: one Gauss–Markov step per datagram
    if (config_.gyro_bias_radps > 0.0)
      gyro_bias_[i] = bias_a_ * gyro_bias_[i] + config_.gyro_bias_radps * bias_gain * normal_(rng_);
    if (config_.accel_bias_mps2 > 0.0)
      accel_bias_[i] =
          bias_a_ * accel_bias_[i] + config_.accel_bias_mps2 * bias_gain * normal_(rng_);
  }
  for (int i = 0; i < 3; ++i) {  // the same noise draws whatever the identifier carries
    raw.rate.counts[i] = stim300::rate_counts(truth.rate_imu_radps[i] + gyro_bias_[i] +
                                              config_.gyro_noise_radps * normal_(rng_));
    raw.accel.counts[i] = stim300::accel_counts(truth.specific_force_imu_mps2[i] + accel_bias_[i] +
                                                    config_.accel_noise_mps2 * normal_(rng_),
                                                config_.scale);
    raw.incl.counts[i] = stim300::incl_counts(truth.specific_force_imu_mps2[i] +
                                              config_.incl_noise_mps2 * normal_(rng_));
  }
  const std::int16_t t = stim300::temperature_counts(config_.temperature_c);
  raw.rate_temperature.counts = raw.accel_temperature.counts =
      raw.incl_temperature.counts = {t, t, t};
  raw.pps = config_.pps_raw;
  if (fault == ImuFault::status_bits) raw.rate.status = kFaultRateStatus;
  raw.counter = counter;
  raw.latency_us = config_.latency_us;
  return raw;
}

std::size_t Stim300Emulator::encode_next(const ImuTruthSample& truth, std::uint8_t identifier,
                                         std::span<std::uint8_t> out) {
  const std::lock_guard lock(mutex_);
  if (stim300::find_content(identifier) == nullptr || out.size() < kBufferSize) return 0;
  const stim300::RawDatagram raw = make_raw_locked(truth, identifier, counter_++, ImuFault::none);
  const stim300::EncodeResult encoded = stim300::encode_datagram(raw, config_.crlf, out);
  return encoded.status == stim300::EncodeStatus::ok ? encoded.size : 0;
}

Stim300Emulator::Counters Stim300Emulator::counters() const {
  Counters c;
  c.written = written_.load(std::memory_order_relaxed);
  c.dropped = dropped_.load(std::memory_order_relaxed);
  c.garbage_bytes = garbage_bytes_.load(std::memory_order_relaxed);
  c.bad_crc = bad_crc_.load(std::memory_order_relaxed);
  c.skipped = skipped_.load(std::memory_order_relaxed);
  return c;
}

}  // namespace zerog::emu
