#include "zerog/rtio/serial_port.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <termios.h>
#include <unistd.h>

#include <cerrno>

#include "wait.hpp"

namespace zerog::rtio {

const char* serial_open_status_name(SerialOpenStatus status) {
  switch (status) {
    case SerialOpenStatus::ok:
      return "ok";
    case SerialOpenStatus::open_failed:
      return "open_failed";
    case SerialOpenStatus::not_a_tty:
      return "not_a_tty";
    case SerialOpenStatus::unsupported_baud:
      return "unsupported_baud";
    case SerialOpenStatus::configure_failed:
      return "configure_failed";
  }
  return "?";
}

unsigned baud_to_speed(std::uint32_t baud) {
  switch (baud) {
    case 1200:
      return B1200;
    case 2400:
      return B2400;
    case 4800:
      return B4800;
    case 9600:
      return B9600;
    case 19200:
      return B19200;
    case 38400:
      return B38400;
    case 57600:
      return B57600;
    case 115200:
      return B115200;
    case 230400:
      return B230400;
    case 460800:
      return B460800;
    case 500000:
      return B500000;
    case 576000:
      return B576000;
    case 921600:
      return B921600;
    case 1000000:
      return B1000000;
    case 1152000:
      return B1152000;
    case 1500000:
      return B1500000;
    case 2000000:
      return B2000000;
    case 2500000:
      return B2500000;
    case 3000000:
      return B3000000;
    case 3500000:
      return B3500000;
    case 4000000:
      return B4000000;
    default:
      return 0;
  }
}

SerialPort::~SerialPort() { close(); }

void SerialPort::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

SerialOpenResult SerialPort::open(const std::string& path, const SerialConfig& config) {
  close();
  const speed_t speed = baud_to_speed(config.baud);
  if (speed == 0) return {SerialOpenStatus::unsupported_baud, EINVAL};
  fd_ = ::open(path.c_str(), O_RDWR | O_NOCTTY | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) return {SerialOpenStatus::open_failed, errno};
  auto fail = [this](SerialOpenStatus status) {
    const SerialOpenResult result{status, errno};
    close();
    return result;
  };
  termios tio{};
  if (::tcgetattr(fd_, &tio) != 0) return fail(SerialOpenStatus::not_a_tty);
  ::cfmakeraw(&tio);  // no echo, no canonical mode, no translation, 8 bits, no parity
  tio.c_cflag |= CLOCAL | CREAD;
  tio.c_cflag &= ~static_cast<tcflag_t>(CSTOPB | CRTSCTS);
  tio.c_iflag &= ~static_cast<tcflag_t>(IXON | IXOFF | IXANY);
  // VMIN 1 with O_NONBLOCK: read() gives EAGAIN when empty (with VMIN 0 it would return 0,
  // indistinguishable from a hangup); ppoll() does the waiting.
  tio.c_cc[VMIN] = 1;
  tio.c_cc[VTIME] = 0;
  if (::cfsetispeed(&tio, speed) != 0 || ::cfsetospeed(&tio, speed) != 0) {
    return fail(SerialOpenStatus::unsupported_baud);
  }
  if (::tcsetattr(fd_, TCSANOW, &tio) != 0) return fail(SerialOpenStatus::configure_failed);
  if (config.exclusive && ::ioctl(fd_, TIOCEXCL) != 0) {
    return fail(SerialOpenStatus::configure_failed);
  }
  if (config.flush_on_open) ::tcflush(fd_, TCIFLUSH);
  return {};
}

SerialReadResult SerialPort::read(std::span<std::uint8_t> buffer,
                                  std::chrono::nanoseconds timeout) {
  if (fd_ < 0) return {SerialReadStatus::not_open, 0};
  const std::int64_t deadline = detail::monotonic_ns() + timeout.count();
  bool hung_up = false;  // poll said POLLHUP/POLLERR
  while (true) {
    const ssize_t n = ::read(fd_, buffer.data(), buffer.size());
    if (n > 0) return {SerialReadStatus::data, static_cast<std::size_t>(n)};
    if (n == 0) return {SerialReadStatus::hangup, 0};  // EOF on a tty: the other end hung up
    if (errno == EINTR) continue;
    if (errno == EIO) return {SerialReadStatus::hangup, 0};
    if (errno != EAGAIN && errno != EWOULDBLOCK) {
      last_errno_ = errno;
      return {SerialReadStatus::io_error, 0};
    }
    if (hung_up) return {SerialReadStatus::hangup, 0};  // no data left and the line is gone
    const std::int64_t left = deadline - detail::monotonic_ns();
    if (left <= 0) return {SerialReadStatus::timeout, 0};
    const int revents = detail::wait_fd(fd_, POLLIN, left);
    if (revents < 0) {
      last_errno_ = errno;
      return {SerialReadStatus::io_error, 0};
    }
    if (revents == 0) return {SerialReadStatus::timeout, 0};
    if ((revents & POLLNVAL) != 0) {
      last_errno_ = EBADF;
      return {SerialReadStatus::io_error, 0};
    }
    // POLLIN, POLLHUP or POLLERR: the next read() returns the data, EOF or the error.
    hung_up = (revents & (POLLHUP | POLLERR)) != 0;
  }
}

}  // namespace zerog::rtio
