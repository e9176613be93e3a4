#pragma once
// Work of diagnose's screening and discovery on several threads with results that do not depend
// on the thread count (issue 16), as the fit's normal engine does it (normal_equations.hpp): the
// work is cut into tasks fixed by the problem (never by the number of threads), each task writes
// only its own outputs, and where tasks add into one result they are folded in task order.
// Host only: starts threads.
#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace zerog::ident::parallel {

/// Workers for `tasks` tasks on at most `threads` threads (at least 1).
inline int workers(std::size_t tasks, int threads) {
  return static_cast<int>(std::clamp<std::size_t>(static_cast<std::size_t>(std::max(threads, 1)), 1,
                                                  std::max<std::size_t>(tasks, 1)));
}

/// Runs `task(i, worker)` for every i in [0, tasks) on `threads` threads (`worker` in
/// [0, workers(tasks, threads)): an index for per-thread scratch). Tasks are handed out in
/// increasing order; a task must not depend on another's outputs. If tasks throw, the remaining
/// ones are skipped and the exception of the first task (by index) that threw is rethrown here.
template <typename Task>
void for_each(std::size_t tasks, int threads, const Task& task) {
  const int n = workers(tasks, threads);
  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  std::mutex m;
  std::size_t first_failed = tasks;
  std::exception_ptr error;
  const auto work = [&](int worker) {
    for (std::size_t i = next++; i < tasks && !failed; i = next++) {
      try {
        task(i, worker);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(m);
        if (i < first_failed) first_failed = i, error = std::current_exception();
        failed = true;
      }
    }
  };
  std::vector<std::thread> pool;
  pool.reserve(static_cast<std::size_t>(n - 1));
  for (int w = 1; w < n; ++w) pool.emplace_back(work, w);
  work(0);
  for (std::thread& t : pool) t.join();
  if (error) std::rethrow_exception(error);
}

/// Runs `compute(i, worker, slot)` for every i in [0, tasks) on `threads` threads, and
/// `fold(i, slot)` for each in task order (i = 0, 1, …) whichever thread computed it: `compute`
/// leaves task i's result in result slot `slot` = i mod `window`, and `fold` adds it into the
/// total, so that the sum runs in the same order for any thread count (`worker` indexes
/// per-thread scratch, as for_each's). A task starts only once task i − window is folded (its
/// slot is free), so a slow thread holds the others back by at most `window` tasks; a finished
/// task is folded, with the ready ones after it, by the thread that completes the next one in
/// order. If a task throws, no later task is folded, and the exception of the first (by index)
/// is rethrown here.
template <typename Compute, typename Fold>
void ordered(std::size_t tasks, int threads, std::size_t window, const Compute& compute,
             const Fold& fold) {
  window = std::max<std::size_t>(window, 1);
  std::mutex m;
  std::condition_variable freed;
  std::size_t folded = 0;  // tasks folded (or skipped after an error): the next is `folded`
  std::vector<std::uint8_t> ready(window, 0);
  std::vector<std::exception_ptr> failed(window);
  std::exception_ptr error;
  for_each(tasks, threads, [&](std::size_t i, int worker) {
    const std::size_t slot = i % window;
    {
      std::unique_lock<std::mutex> lock(m);
      freed.wait(lock, [&] { return i < folded + window; });
    }
    std::exception_ptr computed;
    try {
      compute(i, worker, slot);
    } catch (...) {
      computed = std::current_exception();
    }
    {
      const std::lock_guard<std::mutex> lock(m);
      ready[slot] = 1;
      failed[slot] = computed;
      while (folded < tasks && ready[folded % window]) {
        const std::size_t s = folded % window;
        ready[s] = 0;
        if (!error) {
          try {
            if (failed[s]) std::rethrow_exception(failed[s]);
            fold(folded, s);
          } catch (...) {
            error = std::current_exception();
          }
        }
        failed[s] = nullptr;
        ++folded;
      }
    }
    freed.notify_all();
  });
  if (error) std::rethrow_exception(error);
}

}  // namespace zerog::ident::parallel
