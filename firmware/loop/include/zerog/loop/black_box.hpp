#pragma once
// A pre-allocated ring of the most recent cycles (libfranka's habit): on a fault, the last
// second before it is frozen and dumped outside the cycle. Real-time safe: `push` copies one
// fixed-size record (or `next` + `commit` fill the slot in place), `freeze` only marks the ring;
// no allocation, no locks.
#include <array>
#include <cstddef>
#include <cstdint>

namespace zerog::loop {

template <typename Record, std::size_t N>
class BlackBox {
 public:
  /// Appends the record of one cycle, overwriting the oldest. No-op while frozen.
  void push(const Record& r) {
    if (frozen_) return;
    ring_[count_ % N] = r;
    ++count_;
  }
  /// The slot the next record goes to (the oldest record once full), to fill it in place and
  /// then `commit()` it: the cycle writes its record there, with no copy. Not while frozen.
  Record& next() { return ring_[count_ % N]; }
  /// The slot from `next()` becomes the newest record. Requires !frozen().
  void commit() { ++count_; }
  /// The newest record, to complete it after the cycle (e.g. its measured compute time), frozen
  /// or not. Requires size() > 0.
  Record& newest() { return ring_[(count_ - 1) % N]; }
  /// Keeps the current content (the cycles before a fault) until `release()`.
  void freeze() { frozen_ = true; }
  void release() { frozen_ = false; }
  bool frozen() const { return frozen_; }

  std::size_t size() const { return count_ < N ? count_ : N; }
  /// Record i, oldest first (0 ≤ i < size()).
  const Record& at(std::size_t i) const { return ring_[((count_ < N ? 0 : count_ % N) + i) % N]; }
  std::uint64_t total_pushed() const { return count_; }
  static constexpr std::size_t capacity() { return N; }

 private:
  std::array<Record, N> ring_{};
  std::uint64_t count_ = 0;
  bool frozen_ = false;
};

}  // namespace zerog::loop
