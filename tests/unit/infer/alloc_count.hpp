#pragma once
// Counts global operator new calls in infer_test (the replacement lives in alloc_count.cpp).
#include <cstddef>

namespace zerog::infer::test {

/// Number of global operator new calls so far in this process.
std::size_t allocation_count();

}  // namespace zerog::infer::test
