#pragma once
// A fixed-size log-linear histogram of durations in nanoseconds (HdrHistogram's idea): exact
// below 128 ns, then 64 buckets per power of two, so a quantile is within 1/64 (1.6 %) of the
// true value. add() is real-time safe (no allocation, no locks, a few integer operations); read
// it from the thread that adds, or after that thread has been joined.
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>

namespace zerog::rt {

class LatencyHistogram {
 public:
  static constexpr int kSubBits = 6;                      // 64 buckets per octave
  static constexpr std::size_t kBuckets = 128 + 58 * 64;  // up to 2^64 ns

  void add(std::int64_t ns) noexcept {
    const std::uint64_t v = ns > 0 ? static_cast<std::uint64_t>(ns) : 0;
    ++counts_[bucket(v)];
    ++count_;
    if (v > max_) max_ = v;
  }

  std::uint64_t count() const { return count_; }
  std::uint64_t max() const { return max_; }
  /// The q-quantile (0 ≤ q ≤ 1) as the lower edge of its bucket (the exact maximum for q = 1);
  /// 0 when empty.
  std::uint64_t quantile(double q) const {
    if (count_ == 0) return 0;
    if (q >= 1.0) return max_;
    const auto rank = static_cast<std::uint64_t>(q * static_cast<double>(count_ - 1));
    std::uint64_t seen = 0;
    for (std::size_t b = 0; b < kBuckets; ++b) {
      seen += counts_[b];
      if (seen > rank) return lower_edge(b);
    }
    return max_;
  }

  static std::size_t bucket(std::uint64_t v) {
    if (v < 128) return static_cast<std::size_t>(v);
    const int shift =
        static_cast<int>(std::bit_width(v)) - (kSubBits + 1);  // v >> shift in [64, 127]
    return 128 + static_cast<std::size_t>(shift - 1) * 64 +
           static_cast<std::size_t>((v >> shift) - 64);
  }
  static std::uint64_t lower_edge(std::size_t b) {
    if (b < 128) return b;
    const std::size_t shift = (b - 128) / 64 + 1;
    return (64 + (b - 128) % 64) << shift;
  }

 private:
  std::array<std::uint64_t, kBuckets> counts_{};
  std::uint64_t count_ = 0;
  std::uint64_t max_ = 0;
};

}  // namespace zerog::rt
