#pragma once
// The one monotonic clock of the firmware's threads (device I/O, the runtime, telemetry).
#include <time.h>

#include <cstdint>

namespace zerog::handover {

/// CLOCK_MONOTONIC in ns. Real-time safe (vDSO, no allocation).
inline std::int64_t monotonic_ns() noexcept {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace zerog::handover
