#pragma once
// A fixed-size log-linear histogram of durations in nanoseconds (HdrHistogram's idea): exact
// below 128 ns, then 64 buckets per power of two, so a quantile is within 1/64 (1.6 %) of the
// true value. add() is real-time safe (no allocation, no locks, a few integer operations); read
// it from the thread that adds, or after that thread has been joined.
#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstdlib>

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

/// The supervisor's timing figures (proto/modbus.md, input registers 24–29) from the arrival of
/// robot messages: the period since the previous one, and per second of messages the compute
/// time's 99th percentile and the largest |period − nominal|. Fixed size (the first 1024 compute
/// times of a second are ranked); real-time safe; one thread.
class SecondWindow {
 public:
  static constexpr std::int64_t kSecondNs = 1'000'000'000;

  struct Figures {
    bool has_period = false;  ///< a previous message exists:
    std::int64_t period_ns = 0;
    bool second_ended = false;        ///< this message completed a second:
    bool has_compute_p99 = false;     ///<   it had compute times,
    std::int64_t compute_p99_ns = 0;  ///<   their 99th percentile,
    std::int64_t jitter_max_ns = 0;   ///<   its largest |period − nominal|
  };

  /// A robot message arrived at `t_received_ns` (CLOCK_MONOTONIC, > 0). `compute_ns`: the
  /// previous cycle's compute time, counted when `has_compute`.
  Figures on_message(std::int64_t t_received_ns, std::int64_t nominal_period_ns,
                     std::int64_t compute_ns, bool has_compute) noexcept {
    Figures f;
    if (last_ns_ != 0) {
      f.has_period = true;
      f.period_ns = t_received_ns - last_ns_;
      jitter_ns_ = std::max(jitter_ns_, std::abs(f.period_ns - nominal_period_ns));
    }
    last_ns_ = t_received_ns;
    if (has_compute && n_ < compute_ns_.size()) compute_ns_[n_++] = compute_ns;
    if (second_start_ns_ == 0) second_start_ns_ = t_received_ns;
    if (t_received_ns - second_start_ns_ >= kSecondNs) {
      f.second_ended = true;
      if (n_ > 0) {
        const std::size_t rank = (n_ - 1) * 99 / 100;
        std::nth_element(compute_ns_.begin(),
                         compute_ns_.begin() + static_cast<std::ptrdiff_t>(rank),
                         compute_ns_.begin() + static_cast<std::ptrdiff_t>(n_));
        f.has_compute_p99 = true;
        f.compute_p99_ns = compute_ns_[rank];
      }
      f.jitter_max_ns = jitter_ns_;
      n_ = 0;
      jitter_ns_ = 0;
      second_start_ns_ = t_received_ns;
    }
    return f;
  }

 private:
  std::array<std::int64_t, 1024> compute_ns_{};  // this second's compute times
  std::size_t n_ = 0;
  std::int64_t second_start_ns_ = 0;
  std::int64_t jitter_ns_ = 0;  // largest |period − nominal| this second
  std::int64_t last_ns_ = 0;    // when the last robot message arrived
};

}  // namespace zerog::rt
