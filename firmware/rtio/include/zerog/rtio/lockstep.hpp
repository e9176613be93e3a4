#pragma once
// Lockstep with the emulated rig (proto/lockstep.md): for acceptance tests, zerog-emu is the
// clock. Over a unix datagram socket beside the real RSI/UDP, CAN and pty links it tells zerog-rt
// what happened in emulated time before each event of the robot link — "a datagram went out,
// and by now the F/T board has produced F samples and the IMU written B bytes" or "your receive
// timeout expired" — and zerog-rt acknowledges each event once it has handled it (replied). So
// the samples that make each cycle's row, the cycle a timeout falls in and the cycle a command
// takes effect depend on the emulated time only, not on the host's load.
//
// Only the timing is the emulator's: the frames, bytes and datagrams still travel the real
// sockets and are read by the same code as in real time. Not for the cabinet PC (zerog-rt
// refuses --lockstep together with [realtime] priority; rt_config.md).
//
// The messages are fixed-size structs in host byte order (both ends run on one machine).
#include <chrono>
#include <cstdint>
#include <string_view>

#include "zerog/status.hpp"

namespace zerog::rtio {

inline constexpr std::uint32_t kLockstepMagic = 0x5a474c53;  // "ZGLS"
inline constexpr std::uint32_t kLockstepVersion = 2;

enum class LockstepKind : std::uint32_t {
  hello = 1,     ///< zerog-rt → emulator, once: its receive timeout and F/T rate
  datagram = 2,  ///< emulator → zerog-rt: one robot datagram was sent (not a foreign one)
  timeout = 3,   ///< emulator → zerog-rt: the receive timeout expired, no datagram came
  end = 4,       ///< emulator → zerog-rt: the run is over; stop
  done = 5,      ///< zerog-rt → emulator: the event of `seq` is handled (replied, if any)
};

/// Emulator → zerog-rt.
struct LockstepEvent {
  std::uint32_t magic = kLockstepMagic;
  LockstepKind kind = LockstepKind::datagram;
  std::uint64_t seq = 0;          ///< 1, 2, … per event
  std::int64_t time_ns = 0;       ///< emulated time of the event since the run started
  std::uint64_t ft_samples = 0;   ///< F/T samples the board has produced so far (one per request)
  std::uint64_t imu_bytes = 0;    ///< bytes written to the IMU's pty since it was (re)plugged
  std::uint32_t imu_epoch = 0;    ///< +1 each time the IMU is unplugged (0: never)
  std::uint32_t imu_plugged = 1;  ///< 0 while the IMU is unplugged
  /// 1: the F/T board answers this event's sample requests within zerog-rt's sample timeout
  /// (emulated time), so zerog-rt waits for each answer however slow the host; 0: it does not
  /// (silent), and zerog-rt waits its configured timeout only.
  std::uint32_t ft_answers = 1;
};

/// zerog-rt → emulator.
struct LockstepReply {
  std::uint32_t magic = kLockstepMagic;
  LockstepKind kind = LockstepKind::done;
  std::uint64_t seq = 0;                  ///< the event handled (0 for hello)
  std::uint64_t replies_sent = 0;         ///< RSI replies sent so far (the emulator waits for them)
  std::int64_t receive_timeout_ns = 0;    ///< hello: zerog-rt's robot receive timeout
  double ft_rate_hz = 0.0;                ///< hello: F/T samples requested per second
  std::int64_t ft_sample_timeout_ns = 0;  ///< hello: F/T request → answer timeout
  std::uint32_t version = kLockstepVersion;
};

enum class LockstepStatus : std::uint8_t {
  ok,
  timeout,      ///< nothing within the guard time
  bad_message,  ///< wrong size, magic or kind (counted)
  io_error,     ///< errno kept
  not_open,
};
const char* lockstep_status_name(LockstepStatus status);

/// zerog-rt's end: connects to the emulator's socket. wait() and send() are real-time safe (no
/// allocation, no exceptions, no locks).
class LockstepClient {
 public:
  LockstepClient() = default;
  ~LockstepClient();
  LockstepClient(const LockstepClient&) = delete;
  LockstepClient& operator=(const LockstepClient&) = delete;

  /// Connects to the emulator's socket at `path`. ok(), or invalid_setting ("path": empty or
  /// longer than an AF_UNIX address holds), or system_error (no emulator listening there; errno
  /// also in last_errno()). Not real-time safe.
  Status open(std::string_view path);
  /// Announces zerog-rt (after its devices started, before the first cycle).
  LockstepStatus hello(std::chrono::nanoseconds receive_timeout, double ft_rate_hz,
                       std::chrono::nanoseconds ft_sample_timeout);
  /// Waits up to `guard` for the emulator's next event.
  LockstepStatus wait(LockstepEvent& out, std::chrono::nanoseconds guard);
  /// Acknowledges event `seq`.
  LockstepStatus done(std::uint64_t seq, std::uint64_t replies_sent);
  int last_errno() const { return last_errno_; }
  std::uint64_t bad_messages() const { return bad_messages_; }

 private:
  LockstepStatus send(const LockstepReply& reply);
  int fd_ = -1;
  int last_errno_ = 0;
  std::uint64_t bad_messages_ = 0;
};

}  // namespace zerog::rtio
