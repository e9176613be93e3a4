#include "zerog/rtio/rsi_endpoint.hpp"

#include <arpa/inet.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <string_view>

#include "wait.hpp"

namespace zerog::rtio {

namespace rsi = proto::rsi;

RsiEndpoint::RsiEndpoint(const RsiEndpointConfig& config) : config_(config) {}

RsiEndpoint::~RsiEndpoint() { close(); }

void RsiEndpoint::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  have_peer_ = false;
}

RobotStartStatus RsiEndpoint::start() {
  close();
  in_addr bind_ip{};
  if (::inet_pton(AF_INET, config_.bind_address.c_str(), &bind_ip) != 1 ||
      ::inet_pton(AF_INET, config_.robot_address.c_str(), &robot_ip_) != 1) {
    return RobotStartStatus::bad_config;
  }
  if (config_.sensor_type.empty() || config_.sensor_type.size() > kMaxSensorTypeLength) {
    return RobotStartStatus::bad_config;
  }
  std::memcpy(sensor_type_.data(), config_.sensor_type.data(), config_.sensor_type.size());
  sensor_type_length_ = config_.sensor_type.size();
  // Let the formatter check the sensor type's characters once, here.
  char probe[kReplyBufferBytes];
  if (rsi::format_reply({}, 0, probe, {sensor_type_.data(), sensor_type_length_}).status !=
      rsi::FormatStatus::ok) {
    return RobotStartStatus::bad_config;
  }

  fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (fd_ < 0) return RobotStartStatus::socket_failed;
  if (config_.receive_buffer_bytes > 0 &&
      ::setsockopt(fd_, SOL_SOCKET, SO_RCVBUF, &config_.receive_buffer_bytes,
                   sizeof config_.receive_buffer_bytes) != 0) {
    last_errno_ = errno;
    close();
    return RobotStartStatus::socket_failed;
  }
  sockaddr_in local{};
  local.sin_family = AF_INET;
  local.sin_addr = bind_ip;
  local.sin_port = htons(config_.bind_port);
  if (::bind(fd_, reinterpret_cast<const sockaddr*>(&local), sizeof local) != 0) {
    last_errno_ = errno;
    close();
    return RobotStartStatus::bind_failed;
  }
  socklen_t length = sizeof local;
  ::getsockname(fd_, reinterpret_cast<sockaddr*>(&local), &length);
  local_port_ = ntohs(local.sin_port);
  return RobotStartStatus::ok;
}

std::size_t RsiEndpoint::discard_queued() {
  if (fd_ < 0) return 0;
  std::size_t n = 0;
  while (true) {
    const ssize_t r = ::recv(fd_, rx_.data(), rx_.size(), MSG_DONTWAIT | MSG_TRUNC);
    if (r >= 0) {
      ++n;
      continue;
    }
    if (errno == EINTR) continue;
    break;
  }
  counters_.discarded += n;
  return n;
}

RobotReceiveStatus RsiEndpoint::receive(rsi::RobotMessage& out) {
  if (fd_ < 0) return RobotReceiveStatus::not_started;
  const std::int64_t deadline = detail::monotonic_ns() + config_.receive_timeout.count();
  while (true) {
    sockaddr_in from{};
    socklen_t from_length = sizeof from;
    // MSG_TRUNC: the return value is the datagram's real length, so oversize is detected.
    const ssize_t n = ::recvfrom(fd_, rx_.data(), rx_.size(), MSG_DONTWAIT | MSG_TRUNC,
                                 reinterpret_cast<sockaddr*>(&from), &from_length);
    if (n >= 0) {
      ++counters_.datagrams;
      const bool from_robot =
          from.sin_family == AF_INET && from.sin_addr.s_addr == robot_ip_.s_addr &&
          (config_.robot_port == 0 || ntohs(from.sin_port) == config_.robot_port);
      if (!from_robot) {
        ++counters_.foreign;
        if (detail::monotonic_ns() >= deadline) {  // bounded under a flood of foreign datagrams
          ++counters_.timeouts;
          return RobotReceiveStatus::timeout;
        }
        continue;
      }
      if (static_cast<std::size_t>(n) > rx_.size()) {
        last_parse_ = {rsi::ParseStatus::too_long, rx_.size(), "datagram longer than 4096 bytes"};
      } else {
        last_parse_ = rsi::parse_robot_message(
            std::string_view(rx_.data(), static_cast<std::size_t>(n)), out);
      }
      if (!last_parse_.ok()) {
        ++counters_.malformed;
        ++counters_.malformed_by_status[static_cast<std::size_t>(last_parse_.status)];
        return RobotReceiveStatus::malformed;
      }
      peer_ = from;
      have_peer_ = true;
      ++counters_.messages;
      return RobotReceiveStatus::message;
    }
    if (errno == EINTR) continue;
    if (errno != EAGAIN && errno != EWOULDBLOCK) {
      last_errno_ = errno;
      ++counters_.io_errors;
      return RobotReceiveStatus::io_error;
    }
    const std::int64_t left = deadline - detail::monotonic_ns();
    const int revents = left > 0 ? detail::wait_fd(fd_, POLLIN, left) : 0;
    if (revents < 0) {
      last_errno_ = errno;
      ++counters_.io_errors;
      return RobotReceiveStatus::io_error;
    }
    if (revents == 0) {
      ++counters_.timeouts;
      return RobotReceiveStatus::timeout;
    }
  }
}

RobotReplyStatus RsiEndpoint::reply(const rsi::Correction& correction, std::uint64_t ipoc) {
  if (fd_ < 0) return RobotReplyStatus::not_started;
  if (!have_peer_) return RobotReplyStatus::no_peer;
  return send(rsi::format_reply(correction, ipoc, tx_, {sensor_type_.data(), sensor_type_length_}));
}

RobotReplyStatus RsiEndpoint::reply_axes(const std::array<double, 6>& akorr_deg,
                                         std::uint64_t ipoc) {
  if (fd_ < 0) return RobotReplyStatus::not_started;
  if (!have_peer_) return RobotReplyStatus::no_peer;
  return send(
      rsi::format_axis_reply(akorr_deg, ipoc, tx_, {sensor_type_.data(), sensor_type_length_}));
}

RobotReplyStatus RsiEndpoint::send(const rsi::FormatResult& formatted) {
  if (formatted.status != rsi::FormatStatus::ok) {
    ++counters_.bad_corrections;
    return RobotReplyStatus::bad_correction;
  }
  while (true) {
    const ssize_t n = ::sendto(fd_, tx_.data(), formatted.size, MSG_DONTWAIT,
                               reinterpret_cast<const sockaddr*>(&peer_), sizeof peer_);
    if (n >= 0) {
      ++counters_.replies;
      return RobotReplyStatus::ok;
    }
    if (errno == EINTR) continue;
    last_errno_ = errno;
    if (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS) {
      ++counters_.reply_would_block;
      return RobotReplyStatus::would_block;
    }
    ++counters_.reply_errors;
    return RobotReplyStatus::io_error;
  }
}

}  // namespace zerog::rtio
