#pragma once
// "Latest value" box for a sensor thread → cycle handover: a triple buffer. The writer fills its
// private back buffer and swaps it with the shared middle one (marking it fresh); the reader,
// when the middle is fresh, swaps it with its private front buffer. Both sides are wait-free,
// never copy under contention and never see a torn value (each buffer is owned by exactly one
// side between swaps). The reader keeps the last good value when nothing new has come
// (realtime_tools' "keep the last good value" habit); a value the writer replaces before the
// reader took it is counted as overwritten.
//
// Counts add up: published() == taken() + overwritten() + (a fresh value waiting ? 1 : 0).
#include <atomic>
#include <cstdint>
#include <type_traits>

#include "zerog/handover/spsc_ring.hpp"  // kCacheLineBytes

namespace zerog::handover {

enum class LatestRead : std::uint8_t {
  fresh,  ///< a value published since the last read
  stale,  ///< nothing new: the last value read is returned again
  empty,  ///< nothing has been published yet; `out` is untouched
};

template <typename T>
class LatestValue {
  static_assert(std::is_trivially_copyable_v<T>, "LatestValue holds fixed-size value types");

 public:
  /// Writer side (one thread). Real-time safe, wait-free.
  void publish(const T& value) noexcept {
    buffers_[back_].value = value;
    const std::uint8_t previous =
        middle_.exchange(static_cast<std::uint8_t>(back_ | kFresh), std::memory_order_acq_rel);
    if ((previous & kFresh) != 0) overwritten_.fetch_add(1, std::memory_order_relaxed);
    back_ = previous & kIndexMask;
    published_.fetch_add(1, std::memory_order_release);
  }

  /// Reader side (one thread). Writes the newest value to `out` (or the last one read again).
  /// Real-time safe, wait-free.
  LatestRead read(T& out) noexcept {
    if ((middle_.load(std::memory_order_relaxed) & kFresh) != 0) {
      // Only the reader clears kFresh, so the exchange below takes a fresh buffer.
      const std::uint8_t previous = middle_.exchange(front_, std::memory_order_acq_rel);
      front_ = previous & kIndexMask;
      have_value_ = true;
      taken_.fetch_add(1, std::memory_order_relaxed);
      out = buffers_[front_].value;
      return LatestRead::fresh;
    }
    if (!have_value_) return LatestRead::empty;
    out = buffers_[front_].value;
    return LatestRead::stale;
  }

  std::uint64_t published() const noexcept { return published_.load(std::memory_order_acquire); }
  /// Fresh values the reader took.
  std::uint64_t taken() const noexcept { return taken_.load(std::memory_order_relaxed); }
  /// Values replaced before the reader took them (dropped).
  std::uint64_t overwritten() const noexcept {
    return overwritten_.load(std::memory_order_relaxed);
  }

 private:
  static constexpr std::uint8_t kIndexMask = 0x3;
  static constexpr std::uint8_t kFresh = 0x4;

  struct alignas(kCacheLineBytes) Slot {
    T value{};
  };
  Slot buffers_[3];
  // Buffer indices: the writer owns back_, the reader front_, and middle_ is shared.
  alignas(kCacheLineBytes) std::atomic<std::uint8_t> middle_{1};
  alignas(kCacheLineBytes) std::uint8_t back_ = 0;
  std::atomic<std::uint64_t> published_{0};
  std::atomic<std::uint64_t> overwritten_{0};
  alignas(kCacheLineBytes) std::uint8_t front_ = 2;
  bool have_value_ = false;
  std::atomic<std::uint64_t> taken_{0};
};

}  // namespace zerog::handover
