#pragma once
// Monotonic time and a bounded wait on one file descriptor (private to zerog::rtio).
#include <cstdint>

#include "zerog/handover/clock.hpp"

namespace zerog::rtio::detail {

using handover::monotonic_ns;

/// Waits until `fd` has one of `events` or `timeout_ns` (≥ 0) has passed; retries EINTR with the
/// time left. Returns the poll revents (0: timeout), or −1 with errno set.
int wait_fd(int fd, short events, std::int64_t timeout_ns);

enum class AfterEmptyRead : std::uint8_t { retry, timeout, error };
/// After a non-blocking read of `fd` found nothing (`read_errno` its errno): EINTR or `fd`
/// readable before `deadline_ns` (monotonic) → retry; the deadline passed → timeout; any other
/// errno, or the wait failed → error (errno set).
AfterEmptyRead wait_after_empty_read(int fd, int read_errno, std::int64_t deadline_ns);

}  // namespace zerog::rtio::detail
