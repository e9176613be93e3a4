#pragma once
// An emulated Sensonor STIM300 (datasheet TS1524, proto/stim300.md): writes normal-mode
// datagrams made by the codec's encoder (zerog::proto::stim300) into a pseudo-terminal, which
// the real rtio::Stim300Imu opens like any tty (directly or through a symlink such as
// /tmp/zerog/stim300). Values come from a physics simulation plus seeded white noise; faults
// (garbage, bad CRCs, counter gaps, silence, status bits, unplugging) can be switched on while it
// runs.
//
// The pty: open() creates the master (non-blocking) and opens the slave once itself, in raw mode
// (cfmakeraw: no echo, no line editing, no translation), and keeps it open until unplug() or
// destruction. So the bytes arrive unmodified, and the kernel buffers what is written while no
// reader is there (kernel-dependent: about 20 KB, 534 datagrams of 38 bytes, on Linux 6.18;
// beyond that datagrams are dropped and counted). A reader that opens the slave with tcflush
// (Stim300Imu does) starts with fresh datagrams.
//
// Emulator code, not real-time code, but write_sample() neither allocates nor blocks.
// Thread-safety: set_fault() and counters() from any thread; open(), write_sample() and unplug()
// are serialised by a mutex; slave_path() must not race with open().
#include <array>
#include <atomic>
#include <cstdint>
#include <mutex>
#include <random>
#include <span>
#include <string>

#include <Eigen/Core>

#include "zerog/proto/stim300.hpp"
#include "zerog/status.hpp"

namespace zerog::emu {

struct Stim300EmulatorConfig {
  /// Datagram identifier (proto::stim300::kDatagramTable, any of the 16 rows of TS1524 rev.31).
  /// 0x93 carries rate, acceleration and inclination and is what rtio::Stim300Imu's default
  /// configuration accepts. Every group the identifier carries is filled.
  std::uint8_t identifier = 0x93;
  bool crlf = false;  ///< append CR LF to each datagram (a configuration of the unit)
  /// White noise per datagram, standard deviations in SI. The defaults are the raw 2 kHz sample
  /// noise of a STIM300 behind its 262 Hz filter (host/sim simulator.hpp, NoiseConfig comment).
  double gyro_noise_radps = 9e-4;
  double accel_noise_mps2 = 0.024;
  double incl_noise_mps2 = 0.024;  ///< the inclinometers, same σ as the accelerometers
  /// Bias instability per axis (proto/sim_robot.md): a first-order Gauss–Markov process of this σ
  /// and correlation time, one step per datagram of `datagram_period_s`, started at a random
  /// value of the same σ; 0: none. A scenario's noise.gyro_bias / noise.accel_bias set them.
  double gyro_bias_radps = 0.0;
  double accel_bias_mps2 = 0.0;
  double bias_tau_s = 300.0;
  double datagram_period_s = 1.0 / 2000.0;
  std::uint64_t seed = 1;
  std::uint16_t latency_us = 400;  ///< the datagram's latency field (sampling → transmission)
  /// Accelerometer range of the emulated unit: must match the reader's
  /// Stim300Config::stream.scale (both default to proto::stim300::Scale{}: ±10 g).
  proto::stim300::Scale scale{};
  /// Written into every temperature field of identifiers that carry temperatures, °C.
  double temperature_c = 25.0;
  /// Raw 24-bit PPS field of identifiers that carry PPS (0xF0–0xF7). Its meaning is unverified
  /// (proto/stim300.md), so the emulator writes this value as it is.
  std::uint32_t pps_raw = 0;
};

/// What the IMU experiences, in the IMU frame I, SI.
struct ImuTruthSample {
  Eigen::Vector3d rate_imu_radps = Eigen::Vector3d::Zero();  ///< angular rate of I
  /// Specific force (acceleration minus gravity) at the IMU; the inclinometers, whose axes are
  /// taken to be those of I, measure the same.
  Eigen::Vector3d specific_force_imu_mps2 = Eigen::Vector3d::Zero();
};

enum class ImuFault : std::uint8_t {
  none,
  garbage,       ///< random bytes (one datagram's length) instead of each datagram
  crc_errors,    ///< datagrams with a wrong CRC (one bit of the CRC flipped)
  counter_gaps,  ///< every other datagram (odd counter values) is not sent
  silent,        ///< nothing is written (the counter keeps running, as the unit keeps sampling)
  status_bits,   ///< the rate status byte is set (kFaultRateStatus): rate invalid
};
const char* imu_fault_name(ImuFault fault);

class Stim300Emulator {
 public:
  /// The rate status byte written by ImuFault::status_bits.
  static constexpr std::uint8_t kFaultRateStatus = 0x01;

  /// Throws std::invalid_argument for an identifier not in the content table, a negative or
  /// non-finite noise σ, a non-finite temperature or a PPS value beyond 24 bits.
  explicit Stim300Emulator(const Stim300EmulatorConfig& config = {});
  /// Closes the pty; removes the symlink it created if it still points to its slave.
  ~Stim300Emulator();
  Stim300Emulator(const Stim300Emulator&) = delete;
  Stim300Emulator& operator=(const Stim300Emulator&) = delete;

  /// Opens a pty (master non-blocking, slave in raw mode, see above). If `link_path` is not
  /// empty, a symlink there points to the slave: an existing symlink is replaced atomically
  /// (rename), anything else is refused. Called again, it replaces the pty (a re-plug after
  /// unplug()) and moves the link. Returns ok(), or system_error (invalid_setting for a
  /// link_path that is not a symlink) with a message naming the path and the reason (errno
  /// text); a failure about the link names the setting "link_path". Not real-time safe.
  Status open(const std::string& link_path = "");
  /// The slave's path (/dev/pts/N); empty before open().
  const std::string& slave_path() const { return slave_path_; }
  /// The symlink made by open(), or empty.
  const std::string& link_path() const { return link_path_; }

  /// Encodes one datagram of `truth` plus noise (proto::stim300::rate_counts / accel_counts /
  /// incl_counts with config.scale; values beyond the 24-bit range saturate), advances the
  /// counter (by one per call, also when the fault drops or silences the datagram) and writes
  /// it. A datagram goes out whole or not at all: if the pty takes only part of it, the rest is
  /// written first on the next call. Never blocks and never allocates. Returns false when the
  /// datagram was dropped: the pty buffer is full (no reader) or the pty is not open (before
  /// open(), after unplug()).
  bool write_sample(const ImuTruthSample& truth);

  /// Encodes the next datagram of `truth` with `identifier` (any row of the content table, not
  /// only config.identifier) into `out`, as write_sample() would send it (same counter, noise,
  /// latency, temperatures, PPS and CR LF setting; no fault), without writing it anywhere: for
  /// byte streams of mixed identifiers in tests. Advances the counter. Returns the size, 0 for
  /// an identifier not in the table or a buffer shorter than kMaxDatagramLength + 2. Never
  /// allocates.
  std::size_t encode_next(const ImuTruthSample& truth, std::uint8_t identifier,
                          std::span<std::uint8_t> out);

  void set_fault(ImuFault fault) { fault_.store(fault, std::memory_order_relaxed); }
  ImuFault fault() const { return fault_.load(std::memory_order_relaxed); }
  /// Closes the pty (master and the emulator's slave fd): a reader sees a hang-up
  /// (rtio::ImuReadStatus::disconnected). The symlink stays (dangling) until open() or
  /// destruction.
  void unplug();

  /// Lockstep (proto/lockstep.md): bytes the pty accepted since the last open(), how often it
  /// was unplugged, whether it is open, and a flush of a partly written datagram (true when
  /// nothing is pending).
  std::uint64_t bytes_since_plug() const { return bytes_.load(std::memory_order_acquire); }
  std::uint32_t unplugs() const { return unplugs_.load(std::memory_order_acquire); }
  bool plugged() const;
  bool flush_pending();

  struct Counters {
    std::uint64_t written = 0;        ///< datagrams written (including bad-CRC and status ones)
    std::uint64_t dropped = 0;        ///< datagrams dropped: pty full or not open
    std::uint64_t garbage_bytes = 0;  ///< random bytes written instead of datagrams
    std::uint64_t bad_crc = 0;        ///< datagrams written with a wrong CRC
    std::uint64_t skipped = 0;        ///< datagrams left out by ImuFault::counter_gaps
  };
  Counters counters() const;

 private:
  static constexpr std::size_t kBufferSize = proto::stim300::kMaxDatagramLength + 2;
  void close_locked();
  // The datagram of `truth` plus noise with `identifier`; the fault's status bits if any.
  proto::stim300::RawDatagram make_raw_locked(const ImuTruthSample& truth, std::uint8_t identifier,
                                              std::uint8_t counter, ImuFault fault);
  // Writes the rest of a partially written datagram; false if some of it is still pending.
  bool flush_pending_locked();

  Stim300EmulatorConfig config_;
  mutable std::mutex mutex_;
  int master_ = -1;
  int slave_ = -1;
  std::string slave_path_;
  std::string link_path_;
  std::atomic<ImuFault> fault_{ImuFault::none};
  std::uint8_t counter_ = 0;
  std::mt19937_64 rng_;
  std::normal_distribution<double> normal_{0.0, 1.0};
  double bias_a_ = 1.0;                 // exp(−period/τ) of the bias process
  std::array<double, 3> gyro_bias_{};   // rad/s, I axes
  std::array<double, 3> accel_bias_{};  // m/s², I axes
  std::array<std::uint8_t, kBufferSize> buffer_{};
  std::array<std::uint8_t, kBufferSize> pending_{};
  std::size_t pending_begin_ = 0;
  std::size_t pending_end_ = 0;
  std::atomic<std::uint64_t> bytes_{0};
  std::atomic<std::uint32_t> unplugs_{0};
  std::atomic<std::uint64_t> written_{0};
  std::atomic<std::uint64_t> dropped_{0};
  std::atomic<std::uint64_t> garbage_bytes_{0};
  std::atomic<std::uint64_t> bad_crc_{0};
  std::atomic<std::uint64_t> skipped_{0};
};

}  // namespace zerog::emu
