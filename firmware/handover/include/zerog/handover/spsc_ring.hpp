#pragma once
// Single-producer single-consumer ring for handing records from a device thread to the cycle
// (realtime_tools' lock-free queue habit). Fixed capacity (a power of two), no allocation, no
// locks: the producer owns the write index, the consumer the read index, and each publishes its
// index with a release store that the other side reads with acquire.
//
// When the ring is full the producer's record is dropped (the oldest data stay queued) and the
// drop is counted: pushed() + dropped() == attempts, popped() <= pushed().
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <type_traits>

namespace zerog::handover {

/// Size of a cache line, to keep the producer's and the consumer's indices apart.
inline constexpr std::size_t kCacheLineBytes = 64;

template <typename T, std::size_t Capacity>
class SpscRing {
  static_assert(Capacity >= 2 && (Capacity & (Capacity - 1)) == 0,
                "SpscRing capacity must be a power of two");
  static_assert(std::is_nothrow_copy_assignable_v<T> && std::is_nothrow_default_constructible_v<T>,
                "SpscRing holds plain value types");

 public:
  static constexpr std::size_t capacity() { return Capacity; }

  /// Producer side. Copies `value` in; false (and counted in dropped()) when the ring is full.
  /// Real-time safe, wait-free.
  bool try_push(const T& value) noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_cache_ == Capacity) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      if (head - tail_cache_ == Capacity) {
        dropped_.fetch_add(1, std::memory_order_relaxed);
        return false;
      }
    }
    slots_[head & kMask] = value;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }

  /// Consumer side. Copies the oldest record out; false when the ring is empty. Real-time safe,
  /// wait-free.
  bool try_pop(T& out) noexcept {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail == head_cache_) {
      head_cache_ = head_.load(std::memory_order_acquire);
      if (tail == head_cache_) return false;
    }
    out = slots_[tail & kMask];
    tail_.store(tail + 1, std::memory_order_release);
    return true;
  }

  /// Records accepted by try_push so far (any thread; a snapshot).
  std::uint64_t pushed() const noexcept { return head_.load(std::memory_order_acquire); }
  /// Records taken by try_pop so far (any thread; a snapshot).
  std::uint64_t popped() const noexcept { return tail_.load(std::memory_order_acquire); }
  /// Records refused because the ring was full (any thread; a snapshot).
  std::uint64_t dropped() const noexcept { return dropped_.load(std::memory_order_relaxed); }
  /// Records queued now (exact only when both sides are idle).
  std::size_t size_approx() const noexcept { return static_cast<std::size_t>(pushed() - popped()); }

 private:
  static constexpr std::size_t kMask = Capacity - 1;

  alignas(kCacheLineBytes) std::atomic<std::size_t> head_{0};  // next slot to write (producer)
  std::size_t tail_cache_ = 0;                                 // producer's view of tail_
  std::atomic<std::uint64_t> dropped_{0};                      // written by the producer
  alignas(kCacheLineBytes) std::atomic<std::size_t> tail_{0};  // next slot to read (consumer)
  std::size_t head_cache_ = 0;                                 // consumer's view of head_
  alignas(kCacheLineBytes) std::array<T, Capacity> slots_{};
};

}  // namespace zerog::handover
