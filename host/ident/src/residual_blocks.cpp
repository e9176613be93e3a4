// fit()'s residual blocks (residual_blocks.hpp): BlockCost, the one residual block of every
// engine, instantiated by make_block_cost for the model's sensor stage; the blocks of a log and
// the user terms' mean design per block.
#include "residual_blocks.hpp"

#include <Eigen/Dense>
#include <optional>

namespace zerog::ident::fitting {
namespace {

using model::Effect;

template <int kSensorDim>
class BlockCost : public BlockCostBase {
  using SensorJet = ceres::Jet<double, kSensorDim>;

 public:
  // `user_design`: the block mean of the user terms' design (6 × num_user, column-major), the
  // last parameter block (user terms are linear and add after the library effects).
  // `stats`: block `block` of these statistics is the block [first, first + count) (null: the
  // samples engine).
  BlockCost(const Dataset* data, const BlockStats* stats, std::size_t block, std::size_t first,
            std::size_t count, model::EffectSet effects, std::vector<Effect> order,
            std::array<double, 6> inv_sigma, const double* user_design, int num_user)
      : data_(data),
        stats_(stats),
        block_(block),
        first_(first),
        count_(count),
        effects_(effects),
        order_(std::move(order)),
        inv_sigma_(inv_sigma),
        user_design_(user_design),
        num_user_(num_user) {
    set_num_residuals(6);
    int core = 0, sensor = 6;
    for (Effect e : order_) {
      const int n = model::info(e).num_params;
      mutable_parameter_block_sizes()->push_back(n);
      int& next = model::is_payload_effect(e) ? core : sensor;
      offset_[model::index(e)] = next;
      next += n;
    }
    if (num_user_ > 0) mutable_parameter_block_sizes()->push_back(num_user_);
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    return evaluate_site({block_, first_, count_, user_design_}, parameters, residuals, jacobians,
                         nullptr, 0);
  }

  PointStage1 stage1_at(double const* const* parameters) const override {
    model::ParamPointers<double> p{};
    for (std::size_t b = 0; b < order_.size(); ++b) p[model::index(order_[b])] = parameters[b];
    PointStage1 point;
    core_jets(parameters, point.core);
    point.mount = model::imu_mount<double>(effects_, p, data_->rig);
    point.mount_core = model::imu_mount<CoreJet>(effects_, core_pointers(point.core), data_->rig);
    const auto values = [](const auto& x) {
      return x.unaryExpr([](const CoreJet& j) { return TauJet(j.a); });
    };
    point.mount_tau.R_nominal_true = values(point.mount_core.R_nominal_true);
    point.mount_tau.R_sensor_imu = values(point.mount_core.R_sensor_imu);
    point.mount_tau.p_sensor_imu = values(point.mount_core.p_sensor_imu);
    for (int i = 0; i < kCoreDim; ++i) point.tau[i] = TauJet(point.core[i].a);
    if (effects_.has(Effect::imu_time_offset)) {
      const int slot = offset_[model::index(Effect::imu_time_offset)];
      point.tau[slot] = TauJet(point.core[slot].a, 0);
    }
    return point;
  }

  bool evaluate_site(const BlockSite& site, double const* const* parameters, double* residuals,
                     double** jacobians, const PointStage1* point, int row_stride) const override {
    // Stage 1's block mean; stage 2 once, on the block means of its inputs (exact: stage 2 is
    // affine in them).
    const BlockSensorMeans computed =
        stats_ ? BlockSensorMeans{} : block_sensor_means(*data_, site.first, site.count);
    const BlockSensorMeans& means = stats_ ? stats_->sensor_means(site.block) : computed;
    const model::SensorInputs& mean_in = means.inputs;
    const ident::Wrench& meas = means.measured;
    model::ParamPointers<double> p{};
    for (std::size_t b = 0; b < order_.size(); ++b) p[model::index(order_[b])] = parameters[b];
    ident::Wrench pred;
    if (jacobians == nullptr) {  // only residuals wanted: plain doubles
      model::PayloadMeans<double> stage1_means;
      const ident::Wrench w1 =
          point != nullptr && stats_ != nullptr &&
                  stats_->payload_means<double>(site.block, tau(p), stage1_means)
              ? model::payload_wrench_mean<double, double>(effects_, p, point->mount, stage1_means)
              : payload_mean<double>(site, p);
      pred = model::sensor_output<double>(effects_, p, mean_in, w1);
      add_user(site, parameters, pred);
      for (int r = 0; r < 6; ++r) residuals[r] = (meas[r] - pred[r]) * inv_sigma_[r];
      return true;
    }
    // The point's stage-1 Jets, or built here (only then: a Jet is zeroed on construction).
    std::optional<std::array<CoreJet, kCoreDim>> core_here;
    if (point == nullptr) core_jets(parameters, core_here.emplace());
    const model::ParamPointers<CoreJet> pc = core_pointers(point ? point->core : *core_here);
    model::Wrench<CoreJet> w1;
    if (point == nullptr || !payload_mean_at_point(site, p, pc, *point, w1))
      w1 = payload_mean<CoreJet>(site, pc);
    Eigen::Matrix<double, 6, kSensorDim> d_sensor;
    if (stats_) {
      // Stage 2 with its hand-derived derivatives (model::sensor_output_jacobian).
      ident::Wrench w1d;
      for (int k = 0; k < 6; ++k) w1d[k] = w1[k].a;
      pred = model::sensor_output<double>(effects_, p, mean_in, w1d);
      model::sensor_output_jacobian<kSensorDim>(effects_, p, mean_in, w1d, offset_, d_sensor);
    } else {
      // Stage 2 by autodiff over its parameters and the six payload-wrench components.
      std::array<SensorJet, kSensorDim> sensor;
      model::ParamPointers<SensorJet> ps{};
      for (std::size_t b = 0; b < order_.size(); ++b) {
        const Effect e = order_[b];
        if (model::is_payload_effect(e)) continue;
        const int idx = model::index(e), off = offset_[idx];
        for (int i = 0; i < model::info(e).num_params; ++i)
          sensor[off + i] = SensorJet(parameters[b][i], off + i);
        ps[idx] = &sensor[off];
      }
      model::Wrench<SensorJet> w1s;
      for (int k = 0; k < 6; ++k) w1s[k] = SensorJet(w1[k].a, k);
      const model::Wrench<SensorJet> out =
          model::sensor_output<SensorJet>(effects_, ps, mean_in, w1s);
      for (int r = 0; r < 6; ++r) {
        pred[r] = out[r].a;
        d_sensor.row(r) = out[r].v.transpose();
      }
    }
    // Chain rule: d out / d core = sum_k d out / d w1_k * d w1_k / d core.
    Eigen::Matrix<double, 6, kCoreDim> d_core = Eigen::Matrix<double, 6, kCoreDim>::Zero();
    for (int r = 0; r < 6; ++r)
      for (int k = 0; k < 6; ++k) d_core.row(r) += d_sensor(r, k) * w1[k].v.transpose();
    add_user(site, parameters, pred);
    for (int r = 0; r < 6; ++r) residuals[r] = (meas[r] - pred[r]) * inv_sigma_[r];
    if (num_user_ > 0 && jacobians[order_.size()] != nullptr) {
      double* J = jacobians[order_.size()];
      const int stride = row_stride > 0 ? row_stride : num_user_;
      for (int r = 0; r < 6; ++r)
        for (int j = 0; j < num_user_; ++j)
          J[r * stride + j] = -inv_sigma_[r] * site.user_design[6 * j + r];
    }
    for (std::size_t b = 0; b < order_.size(); ++b) {
      if (jacobians[b] == nullptr) continue;
      const Effect e = order_[b];
      const int n = model::info(e).num_params, off = offset_[model::index(e)];
      const int stride = row_stride > 0 ? row_stride : n;
      const bool is_core = model::is_payload_effect(e);
      for (int r = 0; r < 6; ++r) {
        const double scale = -inv_sigma_[r];
        for (int i = 0; i < n; ++i)
          jacobians[b][r * stride + i] =
              scale * (is_core ? d_core(r, off + i) : d_sensor(r, off + i));
      }
    }
    return true;
  }

 private:
  // Stage-1 parameters as Jets with a unit derivative in their own slot (storage for the active
  // blocks only: a Jet is zeroed on construction).
  void core_jets(double const* const* parameters, std::array<CoreJet, kCoreDim>& core) const {
    for (std::size_t b = 0; b < order_.size(); ++b) {
      const Effect e = order_[b];
      if (!model::is_payload_effect(e)) continue;
      const int off = offset_[model::index(e)];
      for (int i = 0; i < model::info(e).num_params; ++i)
        core[off + i] = CoreJet(parameters[b][i], off + i);
    }
  }

  // The stage-1 effects' blocks of `core` (laid out as core_jets does).
  template <typename J>
  model::ParamPointers<J> core_pointers(const std::array<J, kCoreDim>& core) const {
    model::ParamPointers<J> pc{};
    for (Effect e : order_)
      if (model::is_payload_effect(e)) pc[model::index(e)] = &core[offset_[model::index(e)]];
    return pc;
  }

  const double* tau(const model::ParamPointers<double>& p) const {
    return effects_.has(Effect::imu_time_offset) ? p[model::index(Effect::imu_time_offset)]
                                                 : nullptr;
  }

  // Stage 1's block mean from the statistics with the mount of the point (as payload_mean, the
  // same numbers): the CoreJet evaluation on the means' values, tau's column from a TauJet one.
  // False where the statistics do not cover the block (payload_mean's fallback then).
  bool payload_mean_at_point(const BlockSite& site, const model::ParamPointers<double>& p,
                             const model::ParamPointers<CoreJet>& pc, const PointStage1& point,
                             model::Wrench<CoreJet>& w1) const {
    if (stats_ == nullptr) return false;
    const double* tau_s = tau(p);
    if (tau_s == nullptr) {
      model::PayloadMeans<double> means;
      if (!stats_->payload_means<double>(site.block, nullptr, means)) return false;
      w1 = model::payload_wrench_mean<CoreJet, double>(effects_, pc, point.mount_core, means);
      return true;
    }
    const TauJet tau_jet(*tau_s, 0);
    model::PayloadMeans<TauJet> means_tau;
    if (!stats_->payload_means<TauJet>(site.block, &tau_jet, means_tau)) return false;
    const auto values = [](const auto& x) {
      return x.unaryExpr([](const TauJet& j) { return j.a; }).eval();
    };
    model::PayloadMeans<double> means;
    means.R_base_sensor = means_tau.R_base_sensor;
    means.specific_force_imu = values(means_tau.specific_force_imu);
    means.angular_accel_imu = values(means_tau.angular_accel_imu);
    means.rate_outer_imu = values(means_tau.rate_outer_imu);
    w1 = model::payload_wrench_mean<CoreJet, double>(effects_, pc, point.mount_core, means);
    // tau's column: the parameters' values, tau with its unit derivative.
    const int slot = offset_[model::index(Effect::imu_time_offset)];
    const model::Wrench<TauJet> wt = model::payload_wrench_mean<TauJet, TauJet>(
        effects_, core_pointers(point.tau), point.mount_tau, means_tau);
    for (int k = 0; k < 6; ++k) w1[k].v[slot] = wt[k].v[0];
    return true;
  }

  template <typename T>
  model::Wrench<T> payload_mean(const BlockSite& site, const model::ParamPointers<T>& p) const {
    if (stats_) return stats_->payload_mean<T>(effects_, p, site.block);
    return payload_mean_by_samples<T>(*data_, effects_, p, site.first, site.count);
  }

  void add_user(const BlockSite& site, double const* const* parameters, ident::Wrench& pred) const {
    if (num_user_ == 0) return;
    const double* c = parameters[order_.size()];
    for (int j = 0; j < num_user_; ++j)
      pred += c[j] * Eigen::Map<const ident::Wrench>(site.user_design + 6 * j);
  }

  const Dataset* data_;
  const BlockStats* stats_;
  std::size_t block_;
  std::size_t first_, count_;
  model::EffectSet effects_;
  std::vector<Effect> order_;
  std::array<double, 6> inv_sigma_;
  std::array<int, model::kEffectCount> offset_{};
  const double* user_design_;
  int num_user_;
};

}  // namespace

/// The narrowest BlockCost whose sensor-stage Jet holds the model's sensor-stage parameters.
BlockCostBase* make_block_cost(const Dataset* data, const BlockStats* stats, std::size_t block,
                               std::size_t first, std::size_t count, model::EffectSet effects,
                               const std::vector<Effect>& order, std::array<double, 6> inv_sigma,
                               const double* user_design, int num_user) {
  int sensor_dim = 6;
  for (Effect e : order)
    if (!model::is_payload_effect(e)) sensor_dim += model::info(e).num_params;
  const auto make = [&]<int kDim>() -> BlockCostBase* {
    return new BlockCost<kDim>(data, stats, block, first, count, effects, order, inv_sigma,
                               user_design, num_user);
  };
  if (sensor_dim <= 12) return make.template operator()<12>();
  if (sensor_dim <= 24) return make.template operator()<24>();
  if (sensor_dim <= 48) return make.template operator()<48>();
  return make.template operator()<96>();
}

// Blocks of `m` consecutive used samples, never spanning a gap in the mask (so held-out data
// never leaks into training); a run's leftover tail shorter than m is not used.
SampleBlocks make_blocks(const Dataset& data, const FitOptions& o, int m) {
  SampleBlocks blocks;
  std::size_t run_start = 0;
  bool in_run = false;
  auto close = [&](std::size_t end) {
    for (std::size_t b = run_start; b + m <= end; b += m) blocks.emplace_back(b, m);
  };
  for (std::size_t i = 0; i < data.size(); ++i) {
    const bool u = o.mask == nullptr || (*o.mask)[i] != 0;
    if (u && !in_run) run_start = i, in_run = true;
    if (!u && in_run) close(i), in_run = false;
  }
  if (in_run) close(data.size());
  return blocks;
}

bool use(const FitOptions& o, std::size_t i) { return o.mask == nullptr || (*o.mask)[i] != 0; }

// User terms are linear: each block's mean design (6 × num_user, column-major) is computed once.
std::vector<double> mean_user_design(const Dataset& data, const model::UserEffects& user,
                                     const SampleBlocks& blocks) {
  const int num_user = user.num_terms;
  std::vector<double> design(blocks.size() * 6 * static_cast<std::size_t>(num_user));
  if (num_user == 0) return design;
  std::array<double, 6 * model::kMaxUserTerms> row{};
  ResidentWindow window(data);
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    const auto [first, count] = blocks[b];
    window.advance(first + count);
    double* mean = &design[b * 6 * static_cast<std::size_t>(num_user)];
    for (std::size_t i = first; i < first + count; ++i) {
      model::user_design(user, data.dictionary(i), data.pose(i).R_base_sensor, row.data());
      for (int k = 0; k < 6 * num_user; ++k)
        mean[k] += row[static_cast<std::size_t>(k)] / static_cast<double>(count);
    }
  }
  return design;
}

}  // namespace zerog::ident::fitting
