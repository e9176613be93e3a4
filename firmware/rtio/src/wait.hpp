#pragma once
// Monotonic time and a bounded wait on one file descriptor (private to zerog::rtio).
#include <cstdint>

#include "zerog/rtio/clock.hpp"

namespace zerog::rtio::detail {

using rtio::monotonic_ns;

/// Waits until `fd` has one of `events` or `timeout_ns` (≥ 0) has passed; retries EINTR with the
/// time left. Returns the poll revents (0: timeout), or −1 with errno set.
int wait_fd(int fd, short events, std::int64_t timeout_ns);

}  // namespace zerog::rtio::detail
