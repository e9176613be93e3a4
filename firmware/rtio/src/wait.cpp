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

}  // namespace zerog::rtio::detail
