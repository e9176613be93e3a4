#pragma once
// Counts global operator new calls in proto_test (the replacement lives in rsi_test.cpp), so the
// tests can prove the real-time paths do not allocate.
#include <cstddef>

namespace zerog::proto::test {

/// Number of global operator new calls so far in this process.
std::size_t allocation_count();

}  // namespace zerog::proto::test
