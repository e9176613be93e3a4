#include "wait.hpp"

#include <poll.h>
#include <time.h>

#include <cerrno>

namespace zerog::rtio::detail {

int wait_fd(int fd, short events, std::int64_t timeout_ns) {
  const std::int64_t deadline = monotonic_ns() + (timeout_ns > 0 ? timeout_ns : 0);
  while (true) {
    std::int64_t left = deadline - monotonic_ns();
    if (left < 0) left = 0;
    const timespec timeout{static_cast<time_t>(left / 1'000'000'000),
                           static_cast<long>(left % 1'000'000'000)};
    pollfd pfd{fd, events, 0};
    const int n = ::ppoll(&pfd, 1, &timeout, nullptr);
    if (n > 0) return pfd.revents;
    if (n == 0) return 0;
    if (errno != EINTR) return -1;
  }
}

AfterEmptyRead wait_after_empty_read(int fd, int read_errno, std::int64_t deadline_ns) {
  if (read_errno == EINTR) return AfterEmptyRead::retry;
  if (read_errno != EAGAIN && read_errno != EWOULDBLOCK) {
    errno = read_errno;
    return AfterEmptyRead::error;
  }
  const std::int64_t left = deadline_ns - monotonic_ns();
  if (left <= 0) return AfterEmptyRead::timeout;
  const int revents = wait_fd(fd, POLLIN, left);
  if (revents < 0) return AfterEmptyRead::error;
  // Readable (or an error the next read reports): go round once more.
  return revents == 0 ? AfterEmptyRead::timeout : AfterEmptyRead::retry;
}

}  // namespace zerog::rtio::detail
