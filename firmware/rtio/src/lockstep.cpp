#include "zerog/rtio/lockstep.hpp"

#include <fcntl.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string>

#include "wait.hpp"

namespace zerog::rtio {

const char* lockstep_status_name(LockstepStatus status) {
  switch (status) {
    case LockstepStatus::ok:
      return "ok";
    case LockstepStatus::timeout:
      return "timeout";
    case LockstepStatus::bad_message:
      return "bad_message";
    case LockstepStatus::io_error:
      return "io_error";
    case LockstepStatus::not_open:
      return "not_open";
  }
  return "?";
}

LockstepClient::~LockstepClient() {
  if (fd_ >= 0) ::close(fd_);
}

Status LockstepClient::open(std::string_view path) {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  sockaddr_un peer{};
  peer.sun_family = AF_UNIX;
  if (path.empty() || path.size() >= sizeof peer.sun_path) {
    return Status::invalid(
        "path", "is empty or longer than " + std::to_string(sizeof peer.sun_path - 1) + " bytes");
  }
  std::memcpy(peer.sun_path, path.data(), path.size());
  const int fd = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC | SOCK_NONBLOCK, 0);
  if (fd < 0) {
    last_errno_ = errno;
    return {StatusCode::system_error,
            std::string("socket(AF_UNIX, SOCK_DGRAM) failed: ") + std::strerror(last_errno_)};
  }
  sockaddr_un self{};
  self.sun_family = AF_UNIX;  // autobind: an abstract address the emulator answers to
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&self), sizeof(sa_family_t)) != 0 ||
      ::connect(fd, reinterpret_cast<const sockaddr*>(&peer), sizeof peer) != 0) {
    last_errno_ = errno;
    ::close(fd);
    return {StatusCode::system_error, std::string("no emulator listens there (connect failed: ") +
                                          std::strerror(last_errno_) + ")"};
  }
  fd_ = fd;
  return {};
}

LockstepStatus LockstepClient::send(const LockstepReply& reply) {
  if (fd_ < 0) return LockstepStatus::not_open;
  while (true) {
    const ssize_t n = ::send(fd_, &reply, sizeof reply, MSG_NOSIGNAL);
    if (n == static_cast<ssize_t>(sizeof reply)) return LockstepStatus::ok;
    if (n < 0 && errno == EINTR) continue;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
      // The emulator reads every reply before it goes on: a full queue drains at once.
      if (detail::wait_fd(fd_, POLLOUT, 100'000'000) > 0) continue;
    }
    last_errno_ = n < 0 ? errno : EMSGSIZE;
    return LockstepStatus::io_error;
  }
}

LockstepStatus LockstepClient::hello(std::chrono::nanoseconds receive_timeout, double ft_rate_hz,
                                     std::chrono::nanoseconds ft_sample_timeout) {
  LockstepReply r;
  r.ft_sample_timeout_ns = ft_sample_timeout.count();
  r.kind = LockstepKind::hello;
  r.receive_timeout_ns = receive_timeout.count();
  r.ft_rate_hz = ft_rate_hz;
  return send(r);
}

LockstepStatus LockstepClient::done(std::uint64_t seq, std::uint64_t replies_sent) {
  LockstepReply r;
  r.kind = LockstepKind::done;
  r.seq = seq;
  r.replies_sent = replies_sent;
  return send(r);
}

LockstepStatus LockstepClient::wait(LockstepEvent& out, std::chrono::nanoseconds guard) {
  if (fd_ < 0) return LockstepStatus::not_open;
  const std::int64_t deadline = detail::monotonic_ns() + guard.count();
  while (true) {
    const ssize_t n = ::recv(fd_, &out, sizeof out, MSG_TRUNC);
    if (n == static_cast<ssize_t>(sizeof out)) {
      if (out.magic != kLockstepMagic || out.kind < LockstepKind::datagram ||
          out.kind > LockstepKind::end) {
        ++bad_messages_;
        return LockstepStatus::bad_message;
      }
      return LockstepStatus::ok;
    }
    if (n >= 0) {
      ++bad_messages_;
      return LockstepStatus::bad_message;
    }
    const detail::AfterEmptyRead next = detail::wait_after_empty_read(fd_, errno, deadline);
    if (next == detail::AfterEmptyRead::timeout) return LockstepStatus::timeout;
    if (next == detail::AfterEmptyRead::error) {
      last_errno_ = errno;
      return LockstepStatus::io_error;
    }
  }
}

}  // namespace zerog::rtio
