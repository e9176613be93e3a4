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

#include "can_options.hpp"
#include "can_read.hpp"
#include "linux_can_frame.hpp"

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

  if (const char* failed = detail::set_receive_options(fd_, config, receive_buffer_)) {
    return fail(CanOpenStatus::option_failed, failed);
  }

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
  // The sender's address (a server answers the last one that sent), SO_TIMESTAMPNS only, and the
  // acceptance filters in user space.
  struct Read {
    static constexpr std::size_t control_bytes() { return CMSG_SPACE(sizeof(timespec)); }
    // MSG_TRUNC: the datagram's real length, so a longer one is told from a frame.
    static constexpr int recv_flags() { return MSG_TRUNC; }
    LocalCanBus& self;
    sockaddr_un from{};
    void name(msghdr& message) {
      message.msg_name = &from;
      message.msg_namelen = sizeof from;
    }
    void received(const msghdr& message) {
      if (self.role_ == Role::server && message.msg_namelen > kUnnamedLength &&
          message.msg_namelen <= sizeof from) {
        self.peer_ = from;
        self.peer_length_ = message.msg_namelen;
      }
    }
    void ancillary(cmsghdr* /*c*/) const {}
    bool accepts(const proto::CanFrame& frame) const { return self.accepts(frame); }
  };
  Read bus{*this};
  return detail::read_can_frame(fd_, bus, out, timeout, counters_, last_errno_);
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
    const detail::WriteOutcome outcome = detail::classify_write(n, counters_, last_errno_);
    if (outcome == detail::WriteOutcome::sent) return CanWriteStatus::ok;
    if (outcome == detail::WriteOutcome::retry) continue;
    if (outcome == detail::WriteOutcome::would_block) return CanWriteStatus::would_block;
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
