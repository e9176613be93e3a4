#pragma once
// A serial tty in raw mode (termios: no echo, no line editing, no character translation, 8N1,
// no flow control, CLOCAL), opened non-blocking; reads wait with ppoll() and fill a caller's
// fixed buffer. Works with any tty path: /dev/ttyUSB0, /dev/ttyS1, a pty slave.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

namespace zerog::rtio {

struct SerialConfig {
  /// Bits per second; one of the standard termios rates from 1200 to 4000000 (921600 for the
  /// STIM300).
  std::uint32_t baud = 921600;
  bool exclusive = true;      ///< TIOCEXCL: nobody else may open the tty while we hold it
  bool flush_on_open = true;  ///< drop bytes received before open
};

enum class SerialOpenStatus : std::uint8_t {
  ok,
  open_failed,  ///< open(2) failed (errno kept): no such device, permission, busy
  not_a_tty,
  unsupported_baud,
  configure_failed,  ///< tcsetattr or TIOCEXCL failed
};
struct SerialOpenResult {
  SerialOpenStatus status = SerialOpenStatus::ok;
  int error_number = 0;
  bool ok() const { return status == SerialOpenStatus::ok; }
};
const char* serial_open_status_name(SerialOpenStatus status);

enum class SerialReadStatus : std::uint8_t {
  data,      ///< `size` bytes (≥ 1) were read
  timeout,   ///< nothing within the timeout
  hangup,    ///< the device is gone (USB adapter unplugged, pty master closed)
  io_error,  ///< another read error (errno kept)
  not_open,
};
struct SerialReadResult {
  SerialReadStatus status = SerialReadStatus::timeout;
  std::size_t size = 0;
};

/// Termios speed constant for `baud`, or 0 when it is not a standard rate.
unsigned baud_to_speed(std::uint32_t baud);

class SerialPort {
 public:
  SerialPort() = default;
  ~SerialPort();
  SerialPort(const SerialPort&) = delete;
  SerialPort& operator=(const SerialPort&) = delete;

  /// Opens `path` and configures it. Start-up only: not real-time safe.
  SerialOpenResult open(const std::string& path, const SerialConfig& config = {});
  void close();
  bool is_open() const { return fd_ >= 0; }
  int fd() const { return fd_; }
  int last_errno() const { return last_errno_; }

  /// Reads what is available (at most buffer.size() bytes), waiting up to `timeout` (0: just
  /// look) for the first byte. Real-time safe.
  SerialReadResult read(std::span<std::uint8_t> buffer, std::chrono::nanoseconds timeout);

 private:
  int fd_ = -1;
  int last_errno_ = 0;
};

}  // namespace zerog::rtio
