// Counting replacement of the global allocation functions for the whole infer_test binary (the
// pattern of tests/unit/proto/rsi_test.cpp), so tests can prove the cycle does not allocate.
#include "alloc_count.hpp"

#include <atomic>
#include <cstdlib>
#include <new>

// GCC pairs the inlined free() below with the `new` expressions that reach it and warns
// (-Wmismatched-new-delete); the pairing is right, since these replacements own both sides.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
namespace {
std::atomic<std::size_t> g_allocations{0};
}
void* operator new(std::size_t size) {
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
#pragma GCC diagnostic pop

namespace zerog::infer::test {
std::size_t allocation_count() { return g_allocations.load(std::memory_order_relaxed); }
}  // namespace zerog::infer::test
