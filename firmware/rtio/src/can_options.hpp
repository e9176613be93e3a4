#pragma once
// The socket options CanSocket and LocalCanBus set alike (proto/rtio.md). Private to zerog::rtio;
// called from open(), not from the cycle.
#include <sys/socket.h>

#include "zerog/rtio/can_socket.hpp"

namespace zerog::rtio::detail {

/// On `fd`: SO_TIMESTAMPNS when config.timestamps, and the receive buffer config asks for, as
/// candump -r does it: SO_RCVBUFFORCE first (needs CAP_NET_ADMIN, ignores rmem_max), else
/// SO_RCVBUF, which rmem_max caps (the kernel doubles the value for its bookkeeping). `granted`:
/// what the kernel gave. Returns the option that failed (errno tells why), or nullptr.
inline const char* set_receive_options(int fd, const CanSocketConfig& config,
                                       CanReceiveBuffer& granted) {
  const int on = 1;
  if (config.timestamps && ::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) != 0) {
    return "SO_TIMESTAMPNS";
  }
  granted = CanReceiveBuffer{};
  const int wanted = config.receive_buffer_bytes;
  if (wanted > 0 && ::setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &wanted, sizeof wanted) != 0 &&
      ::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &wanted, sizeof wanted) != 0) {
    return "SO_RCVBUF";
  }
  socklen_t length = sizeof granted.bytes;
  ::getsockopt(fd, SOL_SOCKET, SO_RCVBUF, &granted.bytes, &length);
  granted.capped = wanted > 0 && granted.bytes / 2 < wanted;
  return nullptr;
}

}  // namespace zerog::rtio::detail
