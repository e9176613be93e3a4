#pragma once
// Counts the global allocation functions (operator new in all its forms) in a test binary that
// links tests/common/alloc_count.cpp (CMake target zerog_test_alloc), so tests can prove the
// real-time paths do not allocate. Direct malloc calls are not counted.
#include <cstddef>

namespace zerog::test {

/// Number of global operator new / new[] calls so far in this process (any thread).
std::size_t allocation_count();

}  // namespace zerog::test
