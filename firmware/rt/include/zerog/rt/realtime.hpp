#pragma once
// Real-time set-up, explicit and loud (docs/STYLE.md habit 7, as ros2_control_node does it): lock
// the memory, run the cycle and sensor threads under SCHED_FIFO, pin the cycle thread, pre-fault
// the stacks. When the system does not permit it (EPERM in a container, no rtprio or memlock limit)
// the caller gets a one-line warning saying what failed and how to grant it, and carries on.
// Start-up only: not real-time safe.
#include <pthread.h>

#include <cstddef>
#include <functional>
#include <memory>
#include <string>

#include "zerog/status.hpp"

namespace zerog::rt {

/// mlockall(MCL_CURRENT | MCL_FUTURE). ok(), or system_error concerning "realtime.lock_memory"
/// (the [realtime] key that asks for it), saying what failed and how to grant it (the caller
/// warns and carries on).
Status lock_memory();

/// Stack of the threads Thread starts (MCL_FUTURE locks it whole).
inline constexpr std::size_t kThreadStackBytes = 2 * 1024 * 1024;
/// Stack touched by prefault_stack.
inline constexpr std::size_t kPrefaultStackBytes = 256 * 1024;
/// Touches kPrefaultStackBytes of the calling thread's stack so the cycle never page-faults on
/// it (with the memory locked, the pages then stay).
void prefault_stack();

/// How a thread's real-time settings went (errno values; 0 = done or not asked for).
struct ThreadSetup {
  int sched_error = 0;     ///< pthread_setschedparam(SCHED_FIFO)
  int affinity_error = 0;  ///< pthread_setaffinity_np
};

/// SCHED_FIFO at `priority` refused with `error` for `threads` (names): system_error concerning
/// "realtime.priority", saying what failed and how to grant it. A warning: the caller carries on.
Status sched_warning(const std::string& threads, int priority, int error);
/// Pinning `thread` to `cpu` refused with `error`: system_error concerning "realtime.cpu". A
/// warning: the caller carries on.
Status affinity_warning(const std::string& thread, int cpu, int error);

/// A thread with a fixed stack size (so MCL_FUTURE locks 2 MiB per thread, not the 8 MiB
/// default), a name (visible in top -H) and optional SCHED_FIFO priority and CPU affinity.
class Thread {
 public:
  Thread() = default;
  ~Thread();  ///< joins
  Thread(const Thread&) = delete;
  Thread& operator=(const Thread&) = delete;

  /// Starts `body`: ok(), already_started, or system_error when the thread could not be created.
  /// Then sets the scheduling: SCHED_FIFO at `priority` (0: SCHED_OTHER, nothing to do) and pins
  /// to `cpu` (-1: any); a failure there is not fatal and is reported in `setup`.
  Status start(const std::string& name, std::function<void()> body, int priority, int cpu,
               ThreadSetup& setup, std::size_t stack_bytes = kThreadStackBytes);
  void join();
  bool running() const { return started_; }

 private:
  pthread_t thread_{};
  bool started_ = false;
  std::unique_ptr<std::function<void()>> body_;
};

}  // namespace zerog::rt
