#include "zerog/ident/block_stats.hpp"

#include <algorithm>
#include <memory>

#include "parallel.hpp"

namespace zerog::ident {

BlockSensorMeans block_sensor_means(const Dataset& data, std::size_t first, std::size_t count) {
  const double inv_n = 1.0 / static_cast<double>(count);
  BlockSensorMeans m;
  m.inputs.temperature_C = 0.0;
  for (std::size_t i = first; i < first + count; ++i) {
    const model::SensorInputs in = model::sensor_inputs(data.pose(i));
    m.inputs.t_rel_s += in.t_rel_s * inv_n;
    m.inputs.temperature_C += in.temperature_C * inv_n;
    for (int k = 0; k < 6; ++k) m.inputs.cable_features[k] += in.cable_features[k] * inv_n;
    m.measured += data.measured[i] * inv_n;
  }
  return m;
}

namespace {

// xx yy zz xy xz yz of v vᵀ.
Eigen::Matrix<double, 6, 1> upper(const Eigen::Vector3d& v) {
  Eigen::Matrix<double, 6, 1> u;
  u << v.x() * v.x(), v.y() * v.y(), v.z() * v.z(), v.x() * v.y(), v.x() * v.z(), v.y() * v.z();
  return u;
}

}  // namespace

BlockStats::BlockStats(const Dataset& data, SampleBlocks blocks, const model::EffectSet& effects,
                       int threads)
    : data_(&data), blocks_(std::move(blocks)) {
  // Both passes on `threads` threads (parallel.hpp) with the numbers of one: every block's means
  // are its own, and the running sums restart at every segment, so a segment's are too.
  sensor_.resize(blocks_.size());
  R_mean_.resize(blocks_.size());
  std::size_t longest = 1;
  for (const auto& [first, count] : blocks_) longest = std::max(longest, count);
  constexpr std::size_t kTaskBlocks = 512;
  const std::size_t block_tasks = (blocks_.size() + kTaskBlocks - 1) / kTaskBlocks;
  {
    // A worker's rows are released behind it by its own window (spill.hpp).
    std::vector<std::unique_ptr<ResidentWindow>> windows(
        static_cast<std::size_t>(parallel::workers(block_tasks, threads)));
    for (auto& w : windows) w = std::make_unique<ResidentWindow>(data);
    parallel::for_each(block_tasks, threads, [&](std::size_t task, int worker) {
      for (std::size_t b = task * kTaskBlocks;
           b < std::min(blocks_.size(), (task + 1) * kTaskBlocks); ++b) {
        const auto [first, count] = blocks_[b];
        windows[static_cast<std::size_t>(worker)]->advance(first + count);
        sensor_[b] = block_sensor_means(data, first, count);
        Eigen::Matrix3d R = Eigen::Matrix3d::Zero();
        const double inv_n = 1.0 / static_cast<double>(count);
        for (std::size_t i = first; i < first + count; ++i) R += data.pose(i).R_base_sensor * inv_n;
        R_mean_[b] = R;
      }
    });
  }
  // payload_wrench reads the IMU only for the inertia effects (Dataset::imu_at: none without IMU).
  imu_ = data.columns.any_imu() && (effects.has(model::Effect::linear_inertia) ||
                                    effects.has(model::Effect::rotational_inertia));
  if (!imu_) return;
  segment_ = std::max<std::size_t>(4096, longest + 1);
  const std::size_t n = data.size();
  partial_.assign((n / kCheckpointRows + 1) * kChannels, 0.0);
  total_.assign((n / segment_ + 1) * kChannels, 0.0);
  const std::size_t segments = (n + segment_ - 1) / segment_;
  std::vector<std::unique_ptr<ResidentWindow>> windows(
      static_cast<std::size_t>(parallel::workers(segments, threads)));
  for (auto& w : windows) w = std::make_unique<ResidentWindow>(data);
  parallel::for_each(segments, threads, [&](std::size_t s, int worker) {
    ResidentWindow& window = *windows[static_cast<std::size_t>(worker)];
    Channels sum = Channels::Zero();
    for (std::size_t j = s * segment_; j < std::min(n, (s + 1) * segment_); ++j) {
      window.advance(j + 1);
      sum += row_channels(j);
      const std::size_t next = j + 1;
      if (next % segment_ == 0 || next == n) {
        Eigen::Map<Channels> total(&total_[(j / segment_) * kChannels]);
        total = sum;
      }
      if (next % segment_ == 0) sum.setZero();
      if (next % kCheckpointRows == 0) {
        Eigen::Map<Channels> partial(&partial_[(next / kCheckpointRows) * kChannels]);
        partial = sum;
      }
    }
  });
}

BlockStats::Channels BlockStats::row_channels(std::size_t j) const {
  const std::size_t n = data_->size();
  const double* row = &data_->imu[j * 9];
  const Eigen::Map<const Eigen::Vector3d> w(row + 3);
  Channels c;
  for (int k = 0; k < 3; ++k) c[k] = row[k], c[3 + k] = row[6 + k];
  const Eigen::Vector3d d =
      j + 1 < n ? Eigen::Vector3d(Eigen::Map<const Eigen::Vector3d>(row + 9 + 3) - w)
                : Eigen::Vector3d::Zero();
  c.segment<6>(6) = upper(w);
  c.segment<6>(12) = upper(d);
  return c;
}

BlockStats::Channels BlockStats::partial_sum(std::size_t j) const {
  const std::size_t segment_start = (j / segment_) * segment_;
  std::size_t from = (j / kCheckpointRows) * kCheckpointRows;
  Channels sum = Channels::Zero();
  if (from > segment_start) {
    sum = Eigen::Map<const Channels>(&partial_[(from / kCheckpointRows) * kChannels]);
  } else {
    from = segment_start;
  }
  for (std::size_t r = from; r < j; ++r) sum += row_channels(r);
  return sum;
}

BlockStats::Channels BlockStats::window_sum(std::size_t a, std::size_t e) const {
  const std::size_t sa = a / segment_, se = e / segment_;
  const Channels pa = partial_sum(a), pe = partial_sum(e);
  if (sa == se) return pe - pa;
  return (Eigen::Map<const Channels>(&total_[sa * kChannels]) - pa) + pe;
}

}  // namespace zerog::ident
