#pragma once
// Block sufficient statistics for the fit: the fit compares block means of the measured and the
// predicted wrench (fit.hpp, FitOptions::block_samples), and within a block the parameters are
// constant, so the block mean of stage 1 (model::payload_wrench) follows exactly from a few block
// means of the signals (model::payload_wrench_mean), and stage 2 from the block means of its
// inputs. One model evaluation per block instead of one per sample.
//
// With an IMU time offset tau the IMU is read at the fractional row i + s, s = tau / dt, by
// linear interpolation (model::interpolate_uniform): x(i + s) = x[i + K] + φ Δ[i + K] with
// K = floor(s), φ = s − K the same for every sample of a block and Δ[j] = x[j + 1] − x[j]. Over
// the block's shifted rows j = a … e − 1 (a = first + K, e = a + count):
//   mean x(· + s)           = mean x[j] + φ (x[e] − x[a]) / count,
//   mean x(· + s) x(· + s)ᵀ = mean x[j] x[j]ᵀ + φ ((x[e] x[e]ᵀ − x[a] x[a]ᵀ) / count − D) + φ² D,
// D = mean Δ[j] Δ[j]ᵀ (the sums telescope: x Δᵀ + Δ xᵀ = x[j+1] x[j+1]ᵀ − x[j] x[j]ᵀ − Δ Δᵀ).
// This is (1 − φ)² S(K,K) + φ (1 − φ) (S(K,K+1) + S(K,K+1)ᵀ) + φ² S(K+1,K+1), S(k,l) the mean of
// x[j+k] x[j+l]ᵀ, rearranged so that what carries tau's derivative comes from differences of
// rows, not of sums. The means over rows are read in O(1) from running sums over the log; φ
// carries tau's derivative (a Jet in the fit). Where the window reaches an end of the log
// (interpolate_uniform clamps there) the block is evaluated sample by sample instead.
// Host only: allocates at construction.
#include <Eigen/Core>
#include <cmath>
#include <cstddef>
#include <type_traits>
#include <utility>
#include <vector>

#include "zerog/ident/dataset.hpp"
#include "zerog/model/predict.hpp"

namespace zerog::ident {

/// Blocks of consecutive samples: (first, count).
using SampleBlocks = std::vector<std::pair<std::size_t, std::size_t>>;

/// Block means of the stage-2 inputs (model::SensorInputs) and of the measured wrench over
/// samples [first, first + count).
struct BlockSensorMeans {
  model::SensorInputs inputs;
  Wrench measured = Wrench::Zero();
};
BlockSensorMeans block_sensor_means(const Dataset& data, std::size_t first, std::size_t count);

/// The mean of model::payload_wrench over samples [first, first + count), evaluated sample by
/// sample (IMU read at t + tau when the model has imu_time_offset): the reference of
/// BlockStats::payload_mean and its fallback at the ends of the log.
template <typename T>
model::Wrench<T> payload_mean_by_samples(const Dataset& data, const model::EffectSet& effects,
                                         const model::ParamPointers<T>& p, std::size_t first,
                                         std::size_t count) {
  const T* tau = effects.has(model::Effect::imu_time_offset)
                     ? p[model::index(model::Effect::imu_time_offset)]
                     : nullptr;
  const double inv_n = 1.0 / static_cast<double>(count);
  model::Wrench<T> w = model::Wrench<T>::Zero();
  for (std::size_t i = first; i < first + count; ++i) {
    w += model::payload_wrench<T>(effects, p, data.pose(i), data.imu_at<T>(i, tau), data.rig) *
         T(inv_n);
  }
  return w;
}

/// The statistics of `blocks` of `data` for the model `effects`. Keeps a pointer to `data`.
class BlockStats {
 public:
  /// Formed on `threads` threads, the same for any count.
  BlockStats(const Dataset& data, SampleBlocks blocks, const model::EffectSet& effects,
             int threads = 1);

  std::size_t size() const { return blocks_.size(); }
  const std::pair<std::size_t, std::size_t>& block(std::size_t b) const { return blocks_[b]; }
  const BlockSensorMeans& sensor_means(std::size_t b) const { return sensor_[b]; }

  /// Block means of the stage-1 signals of block b, the IMU read at t + tau (tau may be null).
  /// False where the shifted window reaches an end of the log (then `out` is not complete).
  template <typename T>
  bool payload_means(std::size_t b, const T* tau, model::PayloadMeans<T>& out) const {
    const auto [first, count] = blocks_[b];
    out.R_base_sensor = R_mean_[b];
    out.specific_force_imu.setZero();
    out.angular_accel_imu.setZero();
    out.rate_outer_imu.setZero();
    if (!imu_) return true;
    const double inv_n = 1.0 / static_cast<double>(count);
    if (tau == nullptr) {
      const Channels a = window_sum(first, first + count) * inv_n;
      out.specific_force_imu = a.template segment<3>(0).template cast<T>();
      out.angular_accel_imu = a.template segment<3>(3).template cast<T>();
      out.rate_outer_imu = symmetric(a.template segment<6>(6)).template cast<T>();
      return true;
    }
    const T shift = *tau / T(data_->dt_s);
    double shift_value = 0.0;
    if constexpr (std::is_same_v<T, double>) {
      shift_value = shift;
    } else {
      shift_value = shift.a;
    }
    const double k = std::floor(shift_value);
    // Every sample's interpolation interval [i + K, i + K + 1] inside the log: no clamping.
    const double lo = static_cast<double>(first) + k;
    const double hi = static_cast<double>(first + count) + k;  // last row + K + 1
    if (!(lo >= 0.0) || !(hi <= static_cast<double>(data_->size()) - 1.0)) return false;
    const auto a = static_cast<std::size_t>(lo);
    const std::size_t e = a + count;
    const T phi = shift - T(k);
    const Channels mean = window_sum(a, e) * inv_n;
    const double* xa = &data_->imu[a * 9];
    const double* xe = &data_->imu[e * 9];
    Eigen::Vector3d slope_f, slope_wd;  // (x[e] − x[a]) / count
    for (int c = 0; c < 3; ++c) {
      slope_f[c] = (xe[c] - xa[c]) * inv_n;
      slope_wd[c] = (xe[6 + c] - xa[6 + c]) * inv_n;
    }
    const Eigen::Map<const Eigen::Vector3d> wa(xa + 3), we(xe + 3);
    const Eigen::Matrix3d D = symmetric(mean.template segment<6>(12));
    const Eigen::Matrix3d slope_ww = (we * we.transpose() - wa * wa.transpose()) * inv_n - D;
    out.specific_force_imu =
        mean.template segment<3>(0).template cast<T>() + slope_f.template cast<T>() * phi;
    out.angular_accel_imu =
        mean.template segment<3>(3).template cast<T>() + slope_wd.template cast<T>() * phi;
    out.rate_outer_imu = symmetric(mean.template segment<6>(6)).template cast<T>() +
                         slope_ww.template cast<T>() * phi + D.template cast<T>() * (phi * phi);
    return true;
  }

  /// The mean of model::payload_wrench over block b (as payload_mean_by_samples, to rounding).
  template <typename T>
  model::Wrench<T> payload_mean(const model::EffectSet& effects, const model::ParamPointers<T>& p,
                                std::size_t b) const {
    const T* tau = effects.has(model::Effect::imu_time_offset)
                       ? p[model::index(model::Effect::imu_time_offset)]
                       : nullptr;
    model::PayloadMeans<T> means;
    if (!payload_means<T>(b, tau, means))
      return payload_mean_by_samples<T>(*data_, effects, p, blocks_[b].first, blocks_[b].second);
    return model::payload_wrench_mean<T>(effects, p, means, data_->rig);
  }

 private:
  // Per row j: specific force (3), angular acceleration (3), ω ωᵀ of ω = ω[j] and of
  // ω = ω[j + 1] − ω[j] (6 each, xx yy zz xy xz yz; the difference is zero on the last row).
  static constexpr int kChannels = 18;
  using Channels = Eigen::Matrix<double, kChannels, 1>;

  /// The symmetric matrix of (xx yy zz xy xz yz).
  static Eigen::Matrix3d symmetric(const Eigen::Matrix<double, 6, 1>& c) {
    Eigen::Matrix3d m;
    m << c[0], c[3], c[4], c[3], c[1], c[5], c[4], c[5], c[2];
    return m;
  }
  /// Sum of the channels over rows [a, e), e − a ≤ segment_.
  Channels window_sum(std::size_t a, std::size_t e) const;
  /// The channels of row j.
  Channels row_channels(std::size_t j) const;
  /// The running sum of row j (rows [segment start of j, j)): the checkpoint at or before j plus
  /// the rows after it, added in the order the constructor added them (so the same number).
  Channels partial_sum(std::size_t j) const;

  const Dataset* data_;
  SampleBlocks blocks_;
  std::vector<BlockSensorMeans> sensor_;
  std::vector<Eigen::Matrix3d> R_mean_;
  bool imu_ = false;
  // Running sums restarted every segment_ rows (so a window sum never subtracts two sums of the
  // whole log: its rounding stays that of a segment): the running sum of row j is the sum of rows
  // [segment start of j, j), j = 0..n; it is kept every kCheckpointRows rows only (partial_ row m
  // = that of row m kCheckpointRows: 18 doubles per 8 rows instead of per row) and completed
  // from the rows on demand (partial_sum); total_ row s = sum of the rows of segment s.
  static constexpr std::size_t kCheckpointRows = 8;
  std::size_t segment_ = 4096;
  std::vector<double> partial_;
  std::vector<double> total_;
};

}  // namespace zerog::ident
