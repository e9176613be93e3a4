#pragma once
// Allocation guard at the allocator for the tests that prove real-time paths do not allocate (as
// Drake's LimitMalloc; CMake target zerog_test_alloc, tests/common/alloc_count.cpp).
//
// What is seen, per thread (the cycle runs on one thread; DDS, gtest or emulator threads do not
// pollute the count):
// - allocations: malloc, calloc, realloc, reallocarray, aligned_alloc, memalign, posix_memalign,
//   valloc, pvalloc, and operator new / new[] in every form (plain, nothrow, aligned) — which
//   covers std::vector, std::string, std::function and Eigen's dynamic matrices (Eigen allocates
//   through malloc);
// - frees: free and operator delete / delete[] of a non-null pointer, whether the memory was
//   allocated inside the scope or before it (freeing is an allocator call too: it takes the
//   arena lock and may give memory back to the kernel). free(nullptr) does nothing and is not
//   counted.
//
// How, by build:
// - glibc, no sanitizer (presets ci, release): this object replaces malloc & co in the test
//   executable and forwards them to glibc's own allocator (__libc_malloc, ...), which every
//   shared library then calls too; it replaces operator new/delete as well.
// - AddressSanitizer or ThreadSanitizer (presets asan, tsan): the sanitizer runtime owns malloc
//   and operator new, so nothing is replaced; the counts come from the sanitizer's allocation
//   hooks (__sanitizer_install_malloc_and_free_hooks), which run on the allocating thread for
//   every allocation and free, operator new included. The guard works the same there; only the
//   abort message names "allocation" instead of the entry point, with the sanitizer's stack.
//   One gap, measured (alloc_guard_test): GCC 12's ThreadSanitizer runs no hook for the C aligned
//   forms (aligned_alloc, posix_memalign, memalign, valloc); the glibc and ASan builds see them.
// - Anything else: AllocGuard refuses to start (abort with a message that says the allocator is
//   not hooked), rather than pass without seeing anything. Each process checks once, at the
//   first guard, that a malloc/free pair is seen.
//
// The test binaries that link zerog_test_alloc are compiled with EIGEN_RUNTIME_NO_MALLOC, and a
// guard sets Eigen::internal::set_is_malloc_allowed(false) for its scope (a process-wide flag,
// restored at the end): in a build with assertions, Eigen asserts at the allocating expression.
// The presets build with NDEBUG, where Eigen's check compiles to nothing; there the allocator
// hooks are what catch an Eigen allocation (alloc_guard_test proves they do).
#include <cstddef>

namespace zerog::test {

/// Allocations (as counted above) made by the calling thread since the hooks were installed.
std::size_t allocation_count();

/// Frees (as counted above) made by the calling thread since the hooks were installed.
std::size_t free_count();

/// True when this build sees allocations (glibc replacement or sanitizer hooks).
bool allocation_hooks_active();

/// A scope in which the calling thread's allocations and frees are counted; in abort mode the
/// first one aborts the process with the scope's name, the entry point, the size and a stack.
/// Guards nest (counts are differences of the thread's running totals). Not real-time safe to
/// construct (it checks the hooks once per process), real-time safe to hold.
class AllocGuard {
 public:
  enum class Mode { count, abort };

  explicit AllocGuard(const char* scope_name, Mode mode = Mode::count);
  ~AllocGuard();
  AllocGuard(const AllocGuard&) = delete;
  AllocGuard& operator=(const AllocGuard&) = delete;

  /// Ends the scope early; the counts stay readable and stop changing.
  void stop();

  /// Allocations and frees on this thread since the guard started (until stop()).
  std::size_t allocations() const;
  std::size_t frees() const;

  /// The allocator entry point of the first allocation or free in the scope, or "" when none
  /// ("malloc", "operator new", "free", ...; "allocation"/"free" under a sanitizer).
  const char* first_call() const;

 private:
  const char* name_;
  Mode mode_;
  bool running_ = true;
  bool eigen_malloc_allowed_before_ = true;
  std::size_t allocations_at_start_;
  std::size_t frees_at_start_;
  std::size_t allocations_at_stop_ = 0;
  std::size_t frees_at_stop_ = 0;
  const char* first_call_ = nullptr;  // after stop()
  const char* outer_first_call_;      // the enclosing guard's, restored at stop()
  const char* outer_abort_scope_;
};

namespace detail {
/// For the guard's own mutant test only: with false the hooks stop counting (the allocator
/// still works), so a guard misses everything. Returns the previous value.
bool set_hooks_counting_for_test(bool counting);
}  // namespace detail

}  // namespace zerog::test
