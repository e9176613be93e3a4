#pragma once
// The one monotonic clock of the firmware's threads (device I/O, the runtime, telemetry), and the
// conversion of the kernel's receive stamps to it (proto/rtio.md, "When a sample arrived").
#include <time.h>

#include <cstdint>

namespace zerog::handover {

/// CLOCK_MONOTONIC in ns. Real-time safe (vDSO, no allocation).
inline std::int64_t monotonic_ns() noexcept {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

/// A CLOCK_REALTIME time `realtime_ns` that lies shortly in the past (a socket's SO_TIMESTAMPNS
/// receive stamp, which the kernel gives only in CLOCK_REALTIME: socket(7)) on CLOCK_MONOTONIC:
/// shifted by the two clocks' offset read now. Exact unless the wall clock was stepped between
/// the stamp and now (NTP's slewing changes the offset by at most 500 ppm of that interval).
/// Real-time safe.
inline std::int64_t realtime_to_monotonic_ns(std::int64_t realtime_ns) noexcept {
  timespec real{};
  timespec mono{};
  ::clock_gettime(CLOCK_REALTIME, &real);
  ::clock_gettime(CLOCK_MONOTONIC, &mono);
  const std::int64_t offset =
      (static_cast<std::int64_t>(real.tv_sec) - mono.tv_sec) * 1'000'000'000 +
      (real.tv_nsec - mono.tv_nsec);
  return realtime_ns - offset;
}

}  // namespace zerog::handover
