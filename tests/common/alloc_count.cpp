// The allocation guard's hooks (alloc_count.hpp says what is counted, and how in each build).
#include "alloc_count.hpp"

#include <malloc.h>
#include <unistd.h>

#include <Eigen/Core>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>

#ifndef EIGEN_RUNTIME_NO_MALLOC
#error "zerog_test_alloc is compiled with EIGEN_RUNTIME_NO_MALLOC (tests/CMakeLists.txt)"
#endif

// Which hooks this build can have: the sanitizer runtime's (it owns malloc and operator new), or
// a replacement of glibc's malloc family in the test executable.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
#define ZEROG_ALLOC_HOOKS_SANITIZER 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(memory_sanitizer)
#define ZEROG_ALLOC_HOOKS_SANITIZER 1
#endif
#endif
#if !defined(ZEROG_ALLOC_HOOKS_SANITIZER) && defined(__GLIBC__)
#define ZEROG_ALLOC_HOOKS_GLIBC 1
#include <execinfo.h>
#endif

#if defined(ZEROG_ALLOC_HOOKS_SANITIZER)
// The sanitizer runtime's interface (sanitizer/allocator_interface.h, which GCC 12 does not ship).
extern "C" {
int __sanitizer_install_malloc_and_free_hooks(void (*malloc_hook)(const volatile void*,
                                                                  std::size_t),
                                              void (*free_hook)(const volatile void*));
void __sanitizer_print_stack_trace();
}
#endif

namespace {

// The calling thread's running totals. Trivial and constant-initialised, in the static TLS
// block: reading it from inside malloc neither allocates nor recurses.
struct ThreadCounts {
  std::size_t allocations;
  std::size_t frees;
  const char* first_call;   // first entry point since the innermost guard started
  const char* abort_scope;  // the innermost abort-mode guard's name, or nullptr
  bool reporting;           // inside report_and_abort: count nothing more
};
constinit thread_local ThreadCounts t_counts __attribute__((tls_model("initial-exec"))){};

std::atomic<bool> g_counting{true};  // false only in the guard's mutant test

void write_stderr(const char* text) {
  std::size_t left = std::strlen(text);
  while (left > 0) {
    const ssize_t n = ::write(STDERR_FILENO, text, left);
    if (n <= 0) return;
    text += n;
    left -= static_cast<std::size_t>(n);
  }
}

void print_stack() {
#if defined(ZEROG_ALLOC_HOOKS_GLIBC)
  void* frames[48];
  const int n = ::backtrace(frames, 48);
  ::backtrace_symbols_fd(frames, n, STDERR_FILENO);  // writes, does not allocate
#elif defined(ZEROG_ALLOC_HOOKS_SANITIZER)
  __sanitizer_print_stack_trace();
#endif
}

[[noreturn]] void report_and_abort(ThreadCounts& t, const char* call, std::size_t size) {
  t.reporting = true;
  char line[512];
  if (size > 0) {
    std::snprintf(line, sizeof line,
                  "AllocGuard: %s of %zu bytes inside the scope '%s', which must not allocate "
                  "(abort mode); stack:\n",
                  call, size, t.abort_scope);
  } else {
    std::snprintf(line, sizeof line,
                  "AllocGuard: %s inside the scope '%s', which must not allocate or free "
                  "(abort mode); stack:\n",
                  call, t.abort_scope);
  }
  write_stderr(line);
  print_stack();
  std::abort();
}

void observe(bool allocation, const char* call, std::size_t size) noexcept {
  if (!g_counting.load(std::memory_order_relaxed)) return;
  ThreadCounts& t = t_counts;
  if (t.reporting) return;
  if (allocation) {
    ++t.allocations;
  } else {
    ++t.frees;
  }
  if (t.first_call == nullptr) t.first_call = call;
  if (t.abort_scope != nullptr) report_and_abort(t, call, size);
}

#if defined(ZEROG_ALLOC_HOOKS_SANITIZER)
void on_sanitizer_malloc(const volatile void*, std::size_t size) {
  observe(true, "allocation", size == 0 ? 1 : size);
}
void on_sanitizer_free(const volatile void* p) {
  if (p != nullptr) observe(false, "free", 0);
}
// Installed during static initialisation; what is allocated before is not counted.
const bool g_sanitizer_hooks_installed =
    __sanitizer_install_malloc_and_free_hooks(on_sanitizer_malloc, on_sanitizer_free) != 0;
#endif

// Called through volatile pointers so that the compiler cannot drop the malloc/free pair.
void* (*volatile g_probe_malloc)(std::size_t) = std::malloc;
void (*volatile g_probe_free)(void*) = std::free;

// Once per process: does a malloc/free pair on this thread show in the counts?
bool hooks_seen() {
  static const bool seen = [] {
#if defined(ZEROG_ALLOC_HOOKS_SANITIZER)
    if (!g_sanitizer_hooks_installed) return false;
#endif
    const std::size_t allocations = t_counts.allocations;
    const std::size_t frees = t_counts.frees;
    g_probe_free(g_probe_malloc(32));
    return t_counts.allocations > allocations && t_counts.frees > frees;
  }();
  return seen;
}

void require_hooks() {
  if (hooks_seen()) return;
  write_stderr(
      "AllocGuard: the allocator is not hooked in this build (no glibc malloc replacement and no "
      "sanitizer allocation hooks), so a guard would see nothing; refusing to run rather than "
      "pass (tests/common/alloc_count.hpp)\n");
  std::abort();
}

// backtrace() loads libgcc_s on its first call, which allocates: do it outside the scope.
void warm_stack_trace() {
#if defined(ZEROG_ALLOC_HOOKS_GLIBC)
  static const bool warm = [] {
    void* frame[2];
    return ::backtrace(frame, 2) >= 0;
  }();
  (void)warm;
#endif
}

}  // namespace

namespace zerog::test {

std::size_t allocation_count() { return t_counts.allocations; }
std::size_t free_count() { return t_counts.frees; }
bool allocation_hooks_active() { return hooks_seen(); }

AllocGuard::AllocGuard(const char* scope_name, Mode mode) : name_(scope_name), mode_(mode) {
  require_hooks();
  if (mode_ == Mode::abort) warm_stack_trace();
  eigen_malloc_allowed_before_ = Eigen::internal::is_malloc_allowed();
  Eigen::internal::set_is_malloc_allowed(false);
  ThreadCounts& t = t_counts;
  outer_first_call_ = t.first_call;
  outer_abort_scope_ = t.abort_scope;
  t.first_call = nullptr;
  allocations_at_start_ = t.allocations;
  frees_at_start_ = t.frees;
  if (mode_ == Mode::abort) t.abort_scope = name_;
}

AllocGuard::~AllocGuard() { stop(); }

void AllocGuard::stop() {
  if (!running_) return;
  ThreadCounts& t = t_counts;
  allocations_at_stop_ = t.allocations;
  frees_at_stop_ = t.frees;
  first_call_ = t.first_call;
  t.abort_scope = outer_abort_scope_;
  if (outer_first_call_ != nullptr) t.first_call = outer_first_call_;
  Eigen::internal::set_is_malloc_allowed(eigen_malloc_allowed_before_);
  running_ = false;
}

std::size_t AllocGuard::allocations() const {
  return (running_ ? t_counts.allocations : allocations_at_stop_) - allocations_at_start_;
}

std::size_t AllocGuard::frees() const {
  return (running_ ? t_counts.frees : frees_at_stop_) - frees_at_start_;
}

const char* AllocGuard::first_call() const {
  const char* call = running_ ? t_counts.first_call : first_call_;
  return call == nullptr ? "" : call;
}

namespace detail {
bool set_hooks_counting_for_test(bool counting) {
  require_hooks();  // the per-process check runs with the hooks counting
  return g_counting.exchange(counting);
}
}  // namespace detail

}  // namespace zerog::test

#if defined(ZEROG_ALLOC_HOOKS_GLIBC)
// glibc's allocator under its own names, for the replacements below ("Replacing malloc" in the
// glibc manual: malloc, free, calloc, realloc must be replaced together; the aligned forms too,
// so that they are counted).
extern "C" {
void* __libc_malloc(std::size_t) noexcept;
void* __libc_calloc(std::size_t, std::size_t) noexcept;
void* __libc_realloc(void*, std::size_t) noexcept;
void __libc_free(void*) noexcept;
void* __libc_memalign(std::size_t, std::size_t) noexcept;
void* __libc_valloc(std::size_t) noexcept;
void* __libc_pvalloc(std::size_t) noexcept;
}

namespace {
bool is_power_of_two(std::size_t n) { return n != 0 && (n & (n - 1)) == 0; }
}  // namespace

extern "C" {
void* malloc(std::size_t size) noexcept {
  observe(true, "malloc", size);
  return __libc_malloc(size);
}
void* calloc(std::size_t count, std::size_t size) noexcept {
  observe(true, "calloc", count * size);
  return __libc_calloc(count, size);
}
void* realloc(void* p, std::size_t size) noexcept {
  observe(true, "realloc", size);
  return __libc_realloc(p, size);
}
void* reallocarray(void* p, std::size_t count, std::size_t size) noexcept {
  std::size_t bytes = 0;
  if (__builtin_mul_overflow(count, size, &bytes)) {
    errno = ENOMEM;
    return nullptr;
  }
  observe(true, "reallocarray", bytes);
  return __libc_realloc(p, bytes);
}
void free(void* p) noexcept {
  if (p != nullptr) observe(false, "free", 0);
  __libc_free(p);
}
void* memalign(std::size_t alignment, std::size_t size) noexcept {
  observe(true, "memalign", size);
  return __libc_memalign(alignment, size);
}
void* aligned_alloc(std::size_t alignment, std::size_t size) noexcept {
  observe(true, "aligned_alloc", size);
  if (!is_power_of_two(alignment)) {
    errno = EINVAL;
    return nullptr;
  }
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) noexcept {
  observe(true, "posix_memalign", size);
  if (!is_power_of_two(alignment) || alignment % sizeof(void*) != 0) return EINVAL;
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
void* valloc(std::size_t size) noexcept {
  observe(true, "valloc", size);
  return __libc_valloc(size);
}
void* pvalloc(std::size_t size) noexcept {
  observe(true, "pvalloc", size);
  return __libc_pvalloc(size);
}
}  // extern "C"

// operator new/delete in all their forms, counted once each (they call glibc's allocator
// directly, not the counted malloc above).
// GCC pairs the inlined __libc_free() below with the `new` expressions that reach it and warns
// (-Wmismatched-new-delete); the pairing is right, since these replacements own both sides.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
namespace {
void* counted_new(std::size_t size, const char* call) noexcept {
  observe(true, call, size == 0 ? 1 : size);
  return __libc_malloc(size == 0 ? 1 : size);
}
void* counted_new_aligned(std::size_t size, std::align_val_t alignment, const char* call) noexcept {
  observe(true, call, size == 0 ? 1 : size);
  return __libc_memalign(static_cast<std::size_t>(alignment), size == 0 ? 1 : size);
}
void counted_delete(void* p, const char* call) noexcept {
  if (p != nullptr) observe(false, call, 0);
  __libc_free(p);
}
}  // namespace

void* operator new(std::size_t size) {
  if (void* p = counted_new(size, "operator new")) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) {
  if (void* p = counted_new(size, "operator new[]")) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t size, const std::nothrow_t&) noexcept {
  return counted_new(size, "operator new (nothrow)");
}
void* operator new[](std::size_t size, const std::nothrow_t&) noexcept {
  return counted_new(size, "operator new[] (nothrow)");
}
void* operator new(std::size_t size, std::align_val_t alignment) {
  if (void* p = counted_new_aligned(size, alignment, "operator new (aligned)")) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size, std::align_val_t alignment) {
  if (void* p = counted_new_aligned(size, alignment, "operator new[] (aligned)")) return p;
  throw std::bad_alloc();
}
void* operator new(std::size_t size, std::align_val_t alignment, const std::nothrow_t&) noexcept {
  return counted_new_aligned(size, alignment, "operator new (aligned, nothrow)");
}
void* operator new[](std::size_t size, std::align_val_t alignment, const std::nothrow_t&) noexcept {
  return counted_new_aligned(size, alignment, "operator new[] (aligned, nothrow)");
}
void operator delete(void* p) noexcept { counted_delete(p, "operator delete"); }
void operator delete[](void* p) noexcept { counted_delete(p, "operator delete[]"); }
void operator delete(void* p, std::size_t) noexcept { counted_delete(p, "operator delete"); }
void operator delete[](void* p, std::size_t) noexcept { counted_delete(p, "operator delete[]"); }
void operator delete(void* p, const std::nothrow_t&) noexcept {
  counted_delete(p, "operator delete");
}
void operator delete[](void* p, const std::nothrow_t&) noexcept {
  counted_delete(p, "operator delete[]");
}
void operator delete(void* p, std::align_val_t) noexcept { counted_delete(p, "operator delete"); }
void operator delete[](void* p, std::align_val_t) noexcept {
  counted_delete(p, "operator delete[]");
}
void operator delete(void* p, std::size_t, std::align_val_t) noexcept {
  counted_delete(p, "operator delete");
}
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept {
  counted_delete(p, "operator delete[]");
}
void operator delete(void* p, std::align_val_t, const std::nothrow_t&) noexcept {
  counted_delete(p, "operator delete");
}
void operator delete[](void* p, std::align_val_t, const std::nothrow_t&) noexcept {
  counted_delete(p, "operator delete[]");
}
#pragma GCC diagnostic pop
#endif  // ZEROG_ALLOC_HOOKS_GLIBC
