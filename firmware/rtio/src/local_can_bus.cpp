#include "zerog/rtio/local_can_bus.hpp"

#include <linux/can.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <unistd.h>

#include <cerrno>
#include <cstddef>
#include <cstring>
#include <ctime>

#include "linux_can_frame.hpp"
#include "wait.hpp"

namespace zerog::rtio {

namespace {

// The length of an AF_UNIX address with no name (an unbound sender, or autobind's request).
constexpr socklen_t kUnnamedLength = offsetof(sockaddr_un, sun_path);

}  // namespace

LocalCanBus::~LocalCanBus() { close(); }

void LocalCanBus::close() {
  if (fd_ >= 0) {
    if (role_ == Role::server && bound_) {
      // Only the socket file this bus bound: another server may have taken the path since.
      struct stat st {};
      if (::lstat(path_.sun_path, &st) == 0 && S_ISSOCK(st.st_mode) &&
          static_cast<std::uint64_t>(st.st_dev) == bound_device_ &&
          static_cast<std::uint64_t>(st.st_ino) == bound_inode_) {
        ::unlink(path_.sun_path);
      }
    }
    ::close(fd_);
  }
  fd_ = -1;
  role_ = Role::closed;
  bound_ = false;
  peer_length_ = 0;
}

CanOpenResult LocalCanBus::open_server(std::string_view path, const CanSocketConfig& config) {
  return open(Role::server, path, config);
}

CanOpenResult LocalCanBus::open_client(std::string_view path, const CanSocketConfig& config) {
  return open(Role::client, path, config);
}

CanOpenResult LocalCanBus::open(Role role, std::string_view path, const CanSocketConfig& config) {
  close();
  if (path.empty() || path.size() > kMaxPathBytes || path.find('\0') != std::string_view::npos ||
      config.filter_count > kMaxCanFilters) {
    return {CanOpenStatus::bad_argument, EINVAL, "arguments"};
  }
  path_ = sockaddr_un{};
  path_.sun_family = AF_UNIX;
  std::memcpy(path_.sun_path, path.data(), path.size());
  path_length_ = static_cast<socklen_t>(kUnnamedLength + path.size() + 1);

  auto fail = [this](CanOpenStatus status, const char* what) {
    const CanOpenResult result{status, errno, what};
    close();
    return result;
  };

  fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd_ < 0) return fail(CanOpenStatus::socket_failed, "socket(AF_UNIX, SOCK_DGRAM)");
  role_ = role;

  // The kernel's CAN_RAW_FILTER and CAN_RAW_ERR_FILTER, kept for read() (see CanSocket::open).
  filters_ = {};
  for (std::size_t i = 0; i < config.filter_count; ++i) {
    filters_[i].id = config.filters[i].id & ~CAN_ERR_FLAG;
    filters_[i].mask = config.filters[i].mask & ~CAN_ERR_FLAG;
  }
  filter_count_ = config.filter_count;
  error_mask_ = config.error_mask & CAN_ERR_MASK;

  const int on = 1;
  if (config.timestamps && ::setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) != 0) {
    return fail(CanOpenStatus::option_failed, "SO_TIMESTAMPNS");
  }
  receive_buffer_capped_ = false;
  if (config.receive_buffer_bytes > 0) {
    const int wanted = config.receive_buffer_bytes;
    if (::setsockopt(fd_, SOL_SOCKET, SO_RCVBUFFORCE, &wanted, sizeof wanted) != 0 &&
        ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &wanted, sizeof wanted) != 0) {
      return fail(CanOpenStatus::option_failed, "SO_RCVBUF");
    }
  }
  socklen_t length = sizeof receive_buffer_bytes_;
  ::getsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &receive_buffer_bytes_, &length);
  receive_buffer_capped_ =
      config.receive_buffer_bytes > 0 && receive_buffer_bytes_ / 2 < config.receive_buffer_bytes;

  if (role == Role::server) {
    if (::bind(fd_, reinterpret_cast<const sockaddr*>(&path_), path_length_) != 0) {
      return fail(CanOpenStatus::bind_failed, "bind");
    }
    struct stat st {};
    if (::lstat(path_.sun_path, &st) == 0) {
      bound_device_ = static_cast<std::uint64_t>(st.st_dev);
      bound_inode_ = static_cast<std::uint64_t>(st.st_ino);
      bound_ = true;
    }
  } else {
    // Autobind: an abstract address the server can answer (an unbound sender has none).
    sockaddr_un unnamed{};
    unnamed.sun_family = AF_UNIX;
    if (::bind(fd_, reinterpret_cast<const sockaddr*>(&unnamed), kUnnamedLength) != 0) {
      return fail(CanOpenStatus::bind_failed, "bind (autobind)");
    }
    if (::connect(fd_, reinterpret_cast<const sockaddr*>(&path_), path_length_) != 0) {
      return fail(CanOpenStatus::connect_failed, "connect");
    }
  }
  peer_length_ = 0;
  last_errno_ = 0;
  return {};
}

bool LocalCanBus::accepts(const proto::CanFrame& frame) const {
  if (frame.error()) return (frame.id & error_mask_) != 0;
  for (std::size_t i = 0; i < filter_count_; ++i) {
    if (filters_[i].matches(frame)) return true;
  }
  return false;
}

CanReadStatus LocalCanBus::read(CanRxFrame& out, std::chrono::nanoseconds timeout) {
  if (fd_ < 0) return CanReadStatus::not_open;
  const std::int64_t deadline = detail::monotonic_ns() + timeout.count();
  can_frame frame{};
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timespec))];
  sockaddr_un from{};
  iovec iov{&frame, sizeof frame};
  msghdr message{};
  while (true) {
    message.msg_name = &from;
    message.msg_namelen = sizeof from;
    message.msg_iov = &iov;
    message.msg_iovlen = 1;
    message.msg_control = control;
    message.msg_controllen = sizeof control;
    message.msg_flags = 0;
    // MSG_TRUNC: the datagram's real length, so a longer one is told from a frame.
    const ssize_t n = ::recvmsg(fd_, &message, MSG_DONTWAIT | MSG_TRUNC);
    if (n >= 0) {
      if (role_ == Role::server && message.msg_namelen > kUnnamedLength &&
          message.msg_namelen <= sizeof from) {
        peer_ = from;
        peer_length_ = message.msg_namelen;
      }
      out.timestamp_ns = 0;
      if ((message.msg_flags & MSG_CTRUNC) != 0) ++counters_.control_truncated;
      for (cmsghdr* c = CMSG_FIRSTHDR(&message); c != nullptr; c = CMSG_NXTHDR(&message, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_TIMESTAMPNS) {
          timespec ts{};
          std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
          out.timestamp_ns = static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
        }
      }
      if (!detail::from_can_frame(frame, static_cast<std::size_t>(n), out.frame)) {
        ++counters_.bad_length;
        return CanReadStatus::bad_length;
      }
      if (!accepts(out.frame)) {
        ++counters_.filtered;  // dropped, as the kernel's filters would: read on
        continue;
      }
      if (out.frame.error()) {
        count_error_frame(out.frame, counters_);
        return CanReadStatus::error_frame;
      }
      ++counters_.frames_received;
      return CanReadStatus::frame;
    }
    const detail::AfterEmptyRead next = detail::wait_after_empty_read(fd_, errno, deadline);
    if (next == detail::AfterEmptyRead::timeout) return CanReadStatus::timeout;
    if (next == detail::AfterEmptyRead::error) {
      last_errno_ = errno;
      ++counters_.io_errors;
      return CanReadStatus::io_error;
    }
  }
}

CanWriteStatus LocalCanBus::write(const proto::CanFrame& frame) {
  if (fd_ < 0) return CanWriteStatus::not_open;
  if (frame.len > proto::kCanMaxDataLength) return CanWriteStatus::bad_frame;
  if (role_ == Role::server && peer_length_ == 0) {
    last_errno_ = ENOTCONN;  // nobody has sent anything yet: no one to answer
    ++counters_.tx_errors;
    return CanWriteStatus::io_error;
  }
  const can_frame raw = detail::to_can_frame(frame);
  bool reconnected = false;
  while (true) {
    const ssize_t n = role_ == Role::server
                          ? ::sendto(fd_, &raw, sizeof raw, MSG_NOSIGNAL,
                                     reinterpret_cast<const sockaddr*>(&peer_), peer_length_)
                          : ::send(fd_, &raw, sizeof raw, MSG_NOSIGNAL);
    if (n == static_cast<ssize_t>(sizeof raw)) {
      ++counters_.frames_sent;
      return CanWriteStatus::ok;
    }
    if (n < 0 && errno == EINTR) continue;
    last_errno_ = n < 0 ? errno : EIO;
    if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS)) {
      ++counters_.tx_would_block;
      return CanWriteStatus::would_block;
    }
    const bool peer_gone = n < 0 && (errno == ECONNREFUSED || errno == ENOTCONN);
    if (peer_gone && role_ == Role::server) {
      peer_length_ = 0;  // that client is gone; the next one announces itself with a request
    } else if (peer_gone && !reconnected) {
      // The server went away (the kernel dropped our connection): a restarted one is at path_.
      reconnected = true;
      if (::connect(fd_, reinterpret_cast<const sockaddr*>(&path_), path_length_) == 0) continue;
      last_errno_ = errno;
    }
    ++counters_.tx_errors;
    return CanWriteStatus::io_error;
  }
}

}  // namespace zerog::rtio
