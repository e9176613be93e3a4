// Real-time set-up: either it is granted (checked through the kernel's own view) or the warning
// says what failed and how to grant it.
#include "zerog/rt/realtime.hpp"

#include <gtest/gtest.h>
#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>

#include <atomic>
#include <fstream>
#include <string>

namespace zerog::rt {
namespace {

TEST(Realtime, LockMemoryLocksOrSaysHowToGrantIt) {
  const Status locked = lock_memory();
  const std::string& warning = locked.message();
  if (locked.ok()) {
    std::ifstream status("/proc/self/status");
    std::string line;
    long locked_kb = -1;
    while (std::getline(status, line)) {
      if (line.rfind("VmLck:", 0) == 0) locked_kb = std::stol(line.substr(6));
    }
#if !defined(__SANITIZE_THREAD__) && !defined(__SANITIZE_ADDRESS__)
    EXPECT_GT(locked_kb, 0);  // the sanitizers make mlockall a no-op (their shadow memory)
#endif
    EXPECT_GE(locked_kb, 0);
    ::munlockall();
  } else {
    EXPECT_EQ(locked.code(), StatusCode::system_error);
    EXPECT_EQ(warning.rfind("mlockall(MCL_CURRENT|MCL_FUTURE) failed (", 0), 0u) << warning;
    EXPECT_NE(warning.find("LimitMEMLOCK=infinity"), std::string::npos) << warning;
    EXPECT_NE(warning.find("limits.conf"), std::string::npos) << warning;
  }
}

TEST(Realtime, ThreadRunsUnderSchedFifoOrReportsWhy) {
  Thread thread;
  std::atomic<bool> release{false};
  std::atomic<int> policy{-1};
  std::atomic<int> priority{-1};
  ThreadSetup setup;
  ASSERT_EQ(thread
                .start(
                    "test",
                    [&] {
                      prefault_stack();
                      while (!release.load()) sched_yield();
                      sched_param p{};
                      int pol = 0;
                      pthread_getschedparam(pthread_self(), &pol, &p);
                      policy = pol;
                      priority = p.sched_priority;
                    },
                    10, -1, setup)
                .text(),
            "");
  release = true;
  thread.join();
  if (setup.sched_error == 0) {
    EXPECT_EQ(policy.load(), SCHED_FIFO);
    EXPECT_EQ(priority.load(), 10);
  } else {
    EXPECT_EQ(policy.load(), SCHED_OTHER);
    const Status w = sched_warning("the test thread", 10, setup.sched_error);
    EXPECT_EQ(w.code(), StatusCode::system_error);
    EXPECT_EQ(w.setting(), "realtime.priority");
    EXPECT_NE(w.message().find("LimitRTPRIO"), std::string::npos) << w.text();
  }
  EXPECT_EQ(setup.affinity_error, 0);
}

}  // namespace
}  // namespace zerog::rt
