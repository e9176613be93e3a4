// The allocation guard itself (alloc_count.hpp): every allocator entry point is seen, per
// thread, and abort mode names the scope; a guard without its hooks misses the push it catches.
#include <gtest/gtest.h>
#include <malloc.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <atomic>
#include <cstdlib>
#include <memory>
#include <new>
#include <thread>
#include <vector>

#include "alloc_count.hpp"

namespace zerog::test {
namespace {

#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kSanitizerHooks = true;  // the guard counts through the sanitizer's hooks
#else
constexpr bool kSanitizerHooks = false;
#endif
#if defined(__SANITIZE_THREAD__)
// GCC 12's ThreadSanitizer runs no allocation hook for the C aligned forms (aligned_alloc,
// posix_memalign, memalign, valloc); everything else, aligned operator new included, is seen.
constexpr bool kCAlignedFormsSeen = false;
#else
constexpr bool kCAlignedFormsSeen = true;
#endif

// Stores what was allocated, so that the compiler cannot drop an allocation it sees unused.
void* volatile g_sink = nullptr;
void* volatile g_other_sink = nullptr;
// A null the compiler cannot see (it turns realloc(nullptr, n) into malloc(n)).
void* volatile g_null = nullptr;

TEST(AllocGuard, TheHooksAreActiveInThisBuild) { EXPECT_TRUE(allocation_hooks_active()); }

TEST(AllocGuard, ArithmeticOnFixedSizeDataIsClean) {
  std::array<double, 16> a{};
  Eigen::Matrix3d m = Eigen::Matrix3d::Identity();
  AllocGuard guard("fixed-size arithmetic");
  for (int i = 0; i < 100; ++i) {
    a[static_cast<std::size_t>(i % 16)] += 0.5 * i;
    m = m * Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  }
  guard.stop();
  EXPECT_EQ(guard.allocations(), 0u);
  EXPECT_EQ(guard.frees(), 0u);
  EXPECT_STREQ(guard.first_call(), "");
  EXPECT_GT(a[3] + m(0, 0), -10.0);
}

TEST(AllocGuard, CatchesADeliberateVectorPush) {
  std::vector<int> trace;  // empty: the first push allocates
  AllocGuard guard("cycle-like scope");
  trace.push_back(1);
  guard.stop();
  EXPECT_EQ(guard.allocations(), 1u);
  EXPECT_EQ(guard.frees(), 0u);
  EXPECT_STREQ(guard.first_call(), kSanitizerHooks ? "allocation" : "operator new");
  EXPECT_EQ(trace.size(), 1u);
}

// The mutant: the same guard with its hooks not counting misses the push above, so the hooks
// (not the guard's bookkeeping) are what catch it.
TEST(AllocGuard, MutantWithoutItsHooksMissesTheVectorPush) {
  std::vector<int> trace;
  const bool counting = detail::set_hooks_counting_for_test(false);
  AllocGuard guard("mutant: hooks off");
  trace.push_back(1);
  guard.stop();
  detail::set_hooks_counting_for_test(counting);
  EXPECT_EQ(guard.allocations(), 0u);
  EXPECT_EQ(trace.size(), 1u);
}

struct CCall {
  const char* name;
  void* (*allocate)();
  bool aligned_form;
};

TEST(AllocGuard, CatchesEveryCAllocationEntryPoint) {
  const std::array<CCall, 8> calls{{
      {"malloc", [] { return std::malloc(24); }, false},
      {"calloc", [] { return std::calloc(3, 8); }, false},
      {"realloc", [] { return std::realloc(g_null, 24); }, false},
      {"reallocarray", [] { return ::reallocarray(g_null, 3, 8); }, false},
      {"aligned_alloc", [] { return std::aligned_alloc(64, 128); }, true},
      {"posix_memalign",
       [] {
         void* p = nullptr;
         return ::posix_memalign(&p, 64, 24) == 0 ? p : nullptr;
       },
       true},
      {"memalign", [] { return ::memalign(64, 24); }, true},
      {"valloc", [] { return ::valloc(24); }, true},
  }};
  for (const CCall& call : calls) {
    AllocGuard guard(call.name);
    g_sink = call.allocate();
    guard.stop();
    const bool seen = kCAlignedFormsSeen || !call.aligned_form;
    EXPECT_EQ(guard.allocations(), seen ? 1u : 0u) << call.name;
    EXPECT_EQ(guard.frees(), 0u) << call.name;
    if (!kSanitizerHooks) {
      EXPECT_STREQ(guard.first_call(), call.name);
    }
    ASSERT_NE(g_sink, nullptr) << call.name;
    std::free(g_sink);
  }
}

// Freeing is an allocator call too: memory allocated before the scope and freed inside it
// counts as a free (not as an allocation); free(nullptr) does nothing and is not counted.
TEST(AllocGuard, CountsFreesOfMemoryAllocatedBeforeTheScope) {
  void* before = std::malloc(40);
  auto owned = std::make_unique<std::array<double, 8>>();
  g_other_sink = owned.get();
  g_sink = before;
  AllocGuard guard("frees");
  std::free(g_sink);
  owned.reset();
  std::free(nullptr);
  guard.stop();
  EXPECT_EQ(guard.allocations(), 0u);
  EXPECT_EQ(guard.frees(), 2u);
  EXPECT_STREQ(guard.first_call(), "free");
}

struct alignas(64) Aligned {
  double value[8];
};

TEST(AllocGuard, CatchesEveryFormOfOperatorNew) {
  AllocGuard guard("operator new");
  int* one = new int(1);
  g_sink = one;
  int* many = new int[4];
  g_sink = many;
  int* quiet = new (std::nothrow) int(2);
  g_sink = quiet;
  Aligned* aligned = new Aligned{};
  g_sink = aligned;
  Aligned* aligned_many = new Aligned[2];
  g_sink = aligned_many;
  Aligned* aligned_quiet = new (std::nothrow) Aligned{};
  g_sink = aligned_quiet;
  guard.stop();
  EXPECT_EQ(guard.allocations(), 6u);
  EXPECT_EQ(guard.frees(), 0u);
  delete one;
  delete[] many;
  delete quiet;
  delete aligned;
  delete[] aligned_many;
  delete aligned_quiet;
}

TEST(AllocGuard, CatchesAnEigenDynamicAllocationAndSetsEigensFlag) {
  Eigen::VectorXd v;  // empty: the resize allocates
  {
    AllocGuard guard("Eigen dynamic");
    EXPECT_FALSE(Eigen::internal::is_malloc_allowed());
    // Let the allocation through Eigen's own check (which NDEBUG compiles out anyway): the
    // allocator hooks alone must see it.
    Eigen::internal::set_is_malloc_allowed(true);
    v.resize(64);
    guard.stop();
    EXPECT_EQ(guard.allocations(), 1u);
  }
  EXPECT_TRUE(Eigen::internal::is_malloc_allowed());  // restored at the end of the scope
  EXPECT_EQ(v.size(), 64);
}

TEST(AllocGuard, OtherThreadsDoNotCount) {
  std::atomic<int> allocated{0};
  std::atomic<bool> done{false};
  std::atomic<std::size_t> seen_by_worker{0};
  std::thread worker([&] {
    // Its own count, not a guard: a guard also sets Eigen's process-wide flag.
    const std::size_t start = allocation_count();
    while (!done.load()) {
      std::vector<double> v(16, 1.0);
      g_sink = v.data();
      allocated.fetch_add(1);
    }
    seen_by_worker = allocation_count() - start;
  });
  AllocGuard guard("main thread");
  const std::size_t before = allocation_count();
  while (allocated.load() < 1000) std::this_thread::yield();
  guard.stop();
  EXPECT_EQ(guard.allocations(), 0u);
  EXPECT_EQ(allocation_count(), before);
  done = true;
  worker.join();
  EXPECT_GE(seen_by_worker.load(), 1000u);
}

TEST(AllocGuard, GuardsNest) {
  std::vector<int> a, b;
  AllocGuard outer("outer");
  {
    AllocGuard inner("inner");
    a.push_back(1);
    inner.stop();
    EXPECT_EQ(inner.allocations(), 1u);
  }
  b.push_back(2);
  outer.stop();
  EXPECT_EQ(outer.allocations(), 2u);
  EXPECT_STRNE(outer.first_call(), "");
}

TEST(AllocGuardDeathTest, AbortModeNamesTheScopeAtTheFirstAllocation) {
  std::vector<int> trace;
  EXPECT_DEATH(
      {
        AllocGuard guard("deliberate push", AllocGuard::Mode::abort);
        trace.push_back(1);
      },
      "AllocGuard: .* inside the scope 'deliberate push', which must not allocate");
  EXPECT_DEATH(
      {
        AllocGuard guard("deliberate malloc", AllocGuard::Mode::abort);
        g_sink = std::malloc(8);
      },
      "inside the scope 'deliberate malloc'");
}

TEST(AllocGuardDeathTest, AbortModeStopsAtAFreeToo) {
  g_sink = std::malloc(8);
  EXPECT_DEATH(
      {
        AllocGuard guard("deliberate free", AllocGuard::Mode::abort);
        std::free(g_sink);
      },
      "free inside the scope 'deliberate free', which must not allocate or free");
  std::free(g_sink);
}

TEST(AllocGuard, AbortModeLetsACleanScopeThrough) {
  std::array<int, 4> a{};
  {
    AllocGuard guard("clean", AllocGuard::Mode::abort);
    for (int& x : a) x += 3;
  }
  EXPECT_EQ(a[2], 3);
}

}  // namespace
}  // namespace zerog::test
