#pragma once
// Counts global operator new calls (all forms) in rtio_test (the replacement lives in
// alloc_count.cpp), so tests can prove the per-sample paths do not allocate.
#include <cstddef>

namespace zerog::rtio::test {

/// Number of global operator new / new[] calls so far in this process (any thread).
std::size_t allocation_count();

}  // namespace zerog::rtio::test
