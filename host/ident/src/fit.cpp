#include "zerog/ident/fit.hpp"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <utility>

#include "normal_equations.hpp"
#include "parallel.hpp"
#include "screening.hpp"
#include "zerog/ident/block_stats.hpp"
#include "zerog/ident/eiv.hpp"
#include "zerog/io/effect_file.hpp"

namespace zerog::ident {
namespace {

using model::Effect;

// One residual block per block of `count` consecutive samples: whitened mean(measured) −
// mean(predicted), six values. Averaging both sides the same way is exact for the nonlinear
// model and cuts the noise of differentiated gyro signals (see proto/effects.md).
//
// Derivatives by automatic differentiation in two stages, through the model's own two stages
// (model::payload_wrench, model::sensor_output): the nonlinear payload stage with a Jet of
// kCoreDim derivatives, then the sensor stage with a Jet over its own parameters plus the six
// payload-wrench components, and the chain rule between them: one pass over the model code
// instead of re-running all of it for every chunk of parameters.
// The sensor-stage Jet is as wide as the model needs (payload wrench 6, cable 36, crosstalk 36,
// bias, drift, temperature 6 each: at most 96), chosen from a few instantiations.
// Engine "samples" (the reference) does exactly that, with stage 1 on every sample. Engine
// "block_stats" evaluates stage 1's block mean once per block from the block's sufficient
// statistics (model::payload_wrench_mean, block_stats.hpp) and takes stage 2's derivatives from
// model::sensor_output_jacobian (stage 2 is affine in each parameter) instead of the wide Jet.
// Engine "normal" evaluates every block as block_stats does, through one BlockCost
// (evaluate_site), and solves the streamed normal equations itself (normal_equations.hpp); the
// rank check, covariance and BIC below then come from its final normal matrix.
constexpr int kCoreDim = 16;  // gravity 4, base_tilt 2, rotational_inertia 6, tau 1, rotation 3
using CoreJet = ceres::Jet<double, kCoreDim>;
// The IMU time offset's derivative alone. The block means depend on tau only, so the normal engine
// evaluates stage 1 with CoreJet parameters on the means' values (plain doubles) and once more
// with TauJets for tau's column: Jet arithmetic is slot by slot, so both give exactly the numbers
// of the one CoreJet evaluation on CoreJet means, for a fraction of its multiplications.
using TauJet = ceres::Jet<double, 1>;

// What stage 1 needs at one parameter point that does not depend on the block: the IMU mount
// (model::imu_mount) and the stage-1 parameters as Jets. The normal engine computes it once per
// point (NormalBlocks::set_point) instead of once per block.
struct PointStage1 {
  model::ImuMount<double> mount;        // for residual-only evaluations
  model::ImuMount<CoreJet> mount_core;  // with the stage-1 parameters' derivatives
  model::ImuMount<TauJet> mount_tau;    // mount_core's values; tau's derivative (zero: not in it)
  std::array<CoreJet, kCoreDim> core;   // stage-1 parameters, unit derivative in their own slot
  std::array<TauJet, kCoreDim> tau;     // their values, tau's with its unit derivative
};

// Which block a BlockCost evaluates: block `block` of the statistics (if any) is the samples
// [first, first + count), `user_design` its user terms' mean design.
struct BlockSite {
  std::size_t block, first, count;
  const double* user_design;
};

// A residual block whose evaluation can also be asked for another block of the same problem
// (the normal engine evaluates every block through one object, normal_equations.hpp).
class BlockCostBase : public ceres::CostFunction {
 public:
  // `point`: stage1_at(parameters), or null to compute it here.
  // `row_stride`: the distance between rows of each jacobians[b] (0: the block's size, Ceres'
  // layout), so the normal engine can have the blocks written straight into its 6 × n row.
  virtual bool evaluate_site(const BlockSite& site, double const* const* parameters,
                             double* residuals, double** jacobians, const PointStage1* point,
                             int row_stride) const = 0;
  // What stage 1 needs at `parameters` whatever the block (for evaluate_site's `point`).
  virtual PointStage1 stage1_at(double const* const* parameters) const = 0;
};

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

// The normal engine's view of the fit (normal_equations.hpp): every block evaluated through one
// BlockCost with the block statistics (the block_stats engine's evaluation), the free parameters
// packed in the order of the Ceres path's parameter blocks (the effects of `order` that are not
// frozen, then the user terms).
class NormalBlocks final : public normal::BlockEvaluator {
 public:
  NormalBlocks(const Dataset& data, const BlockStats& stats, const model::ModelParams& start,
               const std::vector<Effect>& order, const std::vector<bool>& frozen,
               std::array<double, 6> inv_sigma, const std::vector<double>& user_design)
      : data_(data),
        stats_(stats),
        order_(order),
        point_(start),
        num_user_(start.user.num_terms),
        user_design_(user_design),
        cost_(make_block_cost(&data, &stats, 0, 0, 0, start.effects, order, inv_sigma,
                              user_design.data(), num_user_)) {
    for (std::size_t b = 0; b < order.size(); ++b) {
      blocks_.push_back(point_.block(order[b]));
      if (!frozen[b]) free_.push_back({b, model::info(order[b]).num_params});
    }
    if (num_user_ > 0) {
      blocks_.push_back(point_.user.coeff.data());
      free_.push_back({order.size(), num_user_});
    }
    for (Free& f : free_) f.column = std::exchange(n_, n_ + f.size);
    stage1_ = cost_->stage1_at(blocks_.data());
  }

  std::size_t num_blocks() const override { return stats_.size(); }
  int num_params() const override { return n_; }
  /// A worker's walk: the rows of its blocks through a ResidentWindow (spill.hpp).
  std::unique_ptr<normal::BlockWalk> walk() const override {
    class Rows final : public normal::BlockWalk {
     public:
      Rows(const Dataset& data, const BlockStats& stats) : window_(data), stats_(stats) {}
      void at(std::size_t b) override {
        const auto [first, count] = stats_.block(b);
        window_.advance(first + count);
      }

     private:
      ResidentWindow window_;
      const BlockStats& stats_;
    };
    if (!data_.spilled()) return nullptr;
    return std::make_unique<Rows>(data_, stats_);
  }
  void set_point(const Eigen::VectorXd& x) override {
    for (const Free& f : free_)
      Eigen::Map<Eigen::VectorXd>(blocks_[f.block], f.size) = x.segment(f.column, f.size);
    stage1_ = cost_->stage1_at(blocks_.data());
  }
  Eigen::VectorXd point() const {
    Eigen::VectorXd x(n_);
    for (const Free& f : free_)
      x.segment(f.column, f.size) = Eigen::Map<const Eigen::VectorXd>(blocks_[f.block], f.size);
    return x;
  }
  /// The free parameters of `params` from the point.
  void store(model::ModelParams& params) const {
    for (const Free& f : free_) {
      double* to =
          f.block < order_.size() ? params.block(order_[f.block]) : params.user.coeff.data();
      std::copy_n(blocks_[f.block], f.size, to);
    }
  }

  bool evaluate(std::size_t b, double* residual, double* jacobian) const override {
    const auto [first, count] = stats_.block(b);
    const BlockSite site{b, first, count,
                         user_design_.data() + b * 6 * static_cast<std::size_t>(num_user_)};
    if (jacobian == nullptr)
      return cost_->evaluate_site(site, blocks_.data(), residual, nullptr, &stage1_, 0);
    // Each free block's 6 × size Jacobian straight into its columns of the 6 × n row (row-major;
    // the free blocks cover every column).
    std::array<double*, model::kEffectCount + 1> jacobians{};
    for (const Free& f : free_) jacobians[f.block] = jacobian + f.column;
    return cost_->evaluate_site(site, blocks_.data(), residual, jacobians.data(), &stage1_, n_);
  }

 private:
  struct Free {
    std::size_t block;  // parameter block (index into blocks_)
    int size;
    int column = 0;  // first column in the packed parameters
  };
  const Dataset& data_;
  const BlockStats& stats_;
  std::vector<Effect> order_;
  model::ModelParams point_;
  int num_user_;
  const std::vector<double>& user_design_;
  std::unique_ptr<BlockCostBase> cost_;
  PointStage1 stage1_;  // cost_->stage1_at the point (blocks_)
  std::vector<double*> blocks_;
  std::vector<Free> free_;
  int n_ = 0;
};

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

// Linear least squares for bias and gravity (F = F0 + m g_S, M = M0 + (m c) × g_S): start values.
// Per sample the rows are J = [[I, g, 0, 0], [0, 0, I, −[g]×]] (unknowns F0, m, M0, h = m c;
// rows F, M); JᵀJ and Jᵀ(F, M) are accumulated from their nonzero entries, each formed as the
// dense product forms it (zeros add nothing), so the sums are the dense ones: the dense 6 × 10
// product per sample cost as much as one model evaluation of the whole log (issue 16).
void linear_init(const Dataset& data, const FitOptions& o, model::ModelParams& p) {
  double n = 0.0, gg = 0.0, gF = 0.0;
  Eigen::Vector3d sg = Eigen::Vector3d::Zero(), sF = Eigen::Vector3d::Zero(),
                  sM = Eigen::Vector3d::Zero(), sgM = Eigen::Vector3d::Zero();
  Eigen::Vector3d diag = Eigen::Vector3d::Zero();  // Σ (g_y² + g_z², g_x² + g_z², g_x² + g_y²)
  Eigen::Vector3d off = Eigen::Vector3d::Zero();  // Σ (−g_x g_y, −g_x g_z, −g_y g_z)
  ResidentWindow window(data);
  for (std::size_t i = 0; i < data.size(); ++i) {
    window.advance(i);
    if (!use(o, i)) continue;
    const Eigen::Vector3d g =
        data.pose(i).R_base_sensor.transpose() * Eigen::Vector3d(0, 0, -model::kStandardGravity);
    const Wrench& w = data.measured[i];
    n += 1.0;
    sg += g;
    gg += g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
    sF += w.head<3>();
    gF += g[0] * w[0] + g[1] * w[1] + g[2] * w[2];
    sM += w.tail<3>();
    // Columns of −[g]×: (0, −g_z, g_y), (g_z, 0, −g_x), (−g_y, g_x, 0).
    diag[0] += g[2] * g[2] + g[1] * g[1];
    diag[1] += g[2] * g[2] + g[0] * g[0];
    diag[2] += g[1] * g[1] + g[0] * g[0];
    off[0] += g[1] * -g[0];
    off[1] += -g[2] * g[0];
    off[2] += g[2] * -g[1];
    sgM[0] += -g[2] * w[4] + g[1] * w[5];
    sgM[1] += g[2] * w[3] + -g[0] * w[5];
    sgM[2] += -g[1] * w[3] + g[0] * w[4];
  }
  Eigen::Matrix<double, 10, 10> A = Eigen::Matrix<double, 10, 10>::Zero();
  Eigen::Matrix<double, 10, 1> b;
  A.block<3, 3>(0, 0) = n * Eigen::Matrix3d::Identity();
  A.block<3, 1>(0, 3) = sg;
  A.block<1, 3>(3, 0) = sg.transpose();
  A(3, 3) = gg;
  A.block<3, 3>(4, 4) = n * Eigen::Matrix3d::Identity();
  A.block<3, 3>(4, 7) = -model::skew<double>(sg);
  A.block<3, 3>(7, 4) = A.block<3, 3>(4, 7).transpose();
  A.block<3, 3>(7, 7) << diag[0], off[0], off[1], off[0], diag[1], off[2], off[1], off[2], diag[2];
  b << sF, gF, sM, sgM;
  const Eigen::Matrix<double, 10, 1> x = A.ldlt().solve(b);
  double* bias = p.block(Effect::bias);
  for (int k = 0; k < 3; ++k) bias[k] = x[k];
  for (int k = 0; k < 3; ++k) bias[3 + k] = x[4 + k];
  double* grav = p.block(Effect::gravity);
  grav[0] = x[3];
  for (int k = 0; k < 3; ++k) grav[1 + k] = std::abs(x[3]) > 1e-9 ? x[7 + k] / x[3] : 0.0;
}

// What the passes leave for the summary and the covariance.
struct Solved {
  std::array<double, 6> sigma{};  // the last pass's whitening
  bool usable = false;
  bool no_convergence = false;  // stopped at max_iterations
  std::string message;
  Eigen::MatrixXd normal_JtJ;  // engine normal: JᵀJ of the free parameters at the solution
  std::array<double, 6> rms{};
  double ssr = 0.0;
  std::size_t n = 0;   // samples
  std::size_t nb = 0;  // block residuals
};

class ProgressCallback : public ceres::IterationCallback {
 public:
  explicit ProgressCallback(const std::function<void(const std::string&)>& f) : f_(f) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    std::ostringstream os;
    os << "  iteration " << s.iteration << "  cost " << s.cost << "  step " << s.step_norm;
    f_(os.str());
    return ceres::SOLVER_CONTINUE;
  }

 private:
  const std::function<void(const std::string&)>& f_;
};

// Block means of the residual (measured − predicted) with `params`, one per block. With the
// block statistics (engine block_stats) one model evaluation per block, exact as in BlockCost
// (stage 1's block mean from the statistics, stage 2 on the block means of its inputs, the user
// terms' mean design); without them, the mean of the per-sample residuals.
std::vector<Wrench> block_mean_residuals(const Dataset& data, const BlockStats* stats,
                                         const SampleBlocks& blocks,
                                         const model::ModelParams& params,
                                         const std::vector<double>& user_design) {
  std::vector<Wrench> out;
  out.reserve(blocks.size());
  const int num_user = params.user.num_terms;
  const auto p = model::pointers(params);
  ResidentWindow window(data);
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    const auto [first, count] = blocks[b];
    window.advance(first + count);
    if (stats == nullptr) {
      Wrench mean = Wrench::Zero();
      for (std::size_t i = first; i < first + count; ++i)
        mean += data.measured[i] - predict(params, data, i);
      out.push_back(mean / static_cast<double>(count));
      continue;
    }
    const BlockSensorMeans& means = stats->sensor_means(b);
    const Wrench w1 = stats->payload_mean<double>(params.effects, p, b);
    Wrench pred = model::sensor_output<double>(params.effects, p, means.inputs, w1);
    const double* design = user_design.data() + b * 6 * static_cast<std::size_t>(num_user);
    for (int j = 0; j < num_user; ++j)
      pred +=
          params.user.coeff[static_cast<std::size_t>(j)] * Eigen::Map<const Wrench>(design + 6 * j);
    out.push_back(means.measured - pred);
  }
  return out;
}

// Per-axis noise of block-mean residuals (`residuals`, one per block of `blocks`) from pairs of
// consecutive blocks that both lie in a dwell: var(mean_b+1 − mean_b) = 2 σ². Empty if there are
// fewer than 20 such pairs.
std::optional<std::array<double, 6>> static_noise_of_block_means(
    const Dataset& data, const SampleBlocks& blocks, const std::vector<Wrench>& residuals) {
  std::array<double, 6> ss{};
  std::size_t pairs = 0;
  bool prev_static = false;
  Wrench prev = Wrench::Zero();
  std::size_t prev_end = 0;
  ResidentWindow window(data);
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    const auto [first, count] = blocks[b];
    window.advance(first + count);
    bool is_static = true;
    for (std::size_t i = first; i < first + count; ++i) is_static = is_static && !data.moving[i];
    const Wrench& m = residuals[b];
    if (is_static && prev_static && prev_end == first) {
      const Wrench d = m - prev;
      for (int k = 0; k < 6; ++k) ss[k] += d[k] * d[k];
      ++pairs;
    }
    prev = m, prev_static = is_static, prev_end = first + count;
  }
  if (pairs < 20) return std::nullopt;
  std::array<double, 6> sigma{};
  for (int k = 0; k < 6; ++k)
    sigma[k] = std::max(std::sqrt(ss[k] / (2.0 * static_cast<double>(pairs))), k < 3 ? 1e-4 : 1e-5);
  return sigma;
}

// Identifiability from the column-scaled normal matrix C (unit diagonal). Its eigenvalues below
// 1e-9 of the largest span the null space (rank deficiency), the cut moved to the widest gap of
// the spectrum between 1e-12 and 1e-6 of the largest, so that an eigenvalue near 1e-9 does not
// flip with the summation order of C. Each null direction names the parameters with entries of
// at least 0.3 of its largest. The directions are taken from the null space's projector P, not
// from the eigensolver's basis (arbitrary in a null space of several dimensions): pivot on the
// parameter P leaves most undetermined, u = P e_q / √P_qq, then P −= u uᵀ; the result depends on
// the null space only. The covariance (of the scaled parameters): the pseudo-inverse of C on the
// identifiable directions.
struct RankCheck {
  std::vector<std::vector<int>> null_directions;  // parameters named, ascending; sorted
  Eigen::MatrixXd cov_scaled;
};

RankCheck rank_check(const Eigen::MatrixXd& C) {
  constexpr double kLow = 1e-12, kHigh = 1e-6;  // band of the cut, relative to the largest
  const int p = static_cast<int>(C.rows());
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(C);
  const Eigen::VectorXd& l = eig.eigenvalues();  // ascending
  const double lmax = l.maxCoeff();
  const auto clamped = [&](int k) {
    if (k < 0) return kLow;
    if (k >= p) return kHigh;
    return std::clamp(l[k] / lmax, kLow, kHigh);
  };
  int null_dim = lmax > 0.0 ? 0 : p;  // the cut below eigenvalue null_dim: the widest gap
  double widest = -1.0;
  for (int k = 0; k <= p && lmax > 0.0; ++k) {
    const double gap = std::log(clamped(k)) - std::log(clamped(k - 1));
    if (gap > widest) widest = gap, null_dim = k;
  }
  RankCheck out;
  Eigen::MatrixXd P =
      eig.eigenvectors().leftCols(null_dim) * eig.eigenvectors().leftCols(null_dim).transpose();
  for (int k = 0; k < null_dim; ++k) {
    Eigen::Index q = 0;
    const double pqq = P.diagonal().maxCoeff(&q);
    const Eigen::VectorXd u = P.col(q) / std::sqrt(std::max(pqq, 1e-300));
    const double umax = u.cwiseAbs().maxCoeff();
    std::vector<int> group;
    for (int j = 0; j < p; ++j)
      if (std::abs(u[j]) >= 0.3 * umax) group.push_back(j);
    out.null_directions.push_back(std::move(group));
    P -= u * u.transpose();
  }
  std::sort(out.null_directions.begin(), out.null_directions.end());
  out.cov_scaled = Eigen::MatrixXd::Zero(p, p);
  for (int k = null_dim; k < p; ++k)
    out.cov_scaled += eig.eigenvectors().col(k) * eig.eigenvectors().col(k).transpose() / l[k];
  return out;
}

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

// Σ_c g_c g_cᵀ · C / (C − 1): the scores Jᵀr of the blocks summed over clusters of `cluster_s`
// of log time (by each block's first row; a table's rows, without time, are each a cluster) at
// the evaluator's point. `clusters` gets C.
Eigen::MatrixXd cluster_meat(const NormalBlocks& nb, const Dataset& data,
                             const SampleBlocks& blocks, double cluster_s, int* clusters) {
  const int p = nb.num_params();
  Eigen::MatrixXd meat = Eigen::MatrixXd::Zero(p, p);
  Eigen::VectorXd g = Eigen::VectorXd::Zero(p);
  Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::RowMajor> J(6, p);
  Eigen::Matrix<double, 6, 1> res;
  const auto walk = nb.walk();
  long current = -1;
  int count = 0;
  const bool by_time = !data.columns.static_rows && cluster_s > 0.0;
  for (std::size_t b = 0; b < nb.num_blocks(); ++b) {
    if (walk) walk->at(b);
    const std::size_t first = blocks[b].first;
    const long id =
        by_time ? static_cast<long>(std::floor((data.t_s[first] - data.t_s.front()) / cluster_s))
                : static_cast<long>(b);
    if (id != current) {
      if (current >= 0) meat.selfadjointView<Eigen::Lower>().rankUpdate(g);
      g.setZero();
      current = id;
      ++count;
    }
    if (!nb.evaluate(b, res.data(), J.data())) continue;
    g.noalias() += J.transpose() * res;
  }
  if (current >= 0) meat.selfadjointView<Eigen::Lower>().rankUpdate(g);
  meat = meat.selfadjointView<Eigen::Lower>();
  *clusters = count;
  if (count > 1) meat *= static_cast<double>(count) / static_cast<double>(count - 1);
  return meat;
}

// ---- fit's phases, in the order fit() runs them ----

bool is_frozen(const FitOptions& o, Effect e) { return o.frozen.has(e) && o.effects.has(e); }

// The model checked against the log before anything is computed.
void check_model(const Dataset& data, const FitOptions& o) {
  check_signals(o.effects, data);
  check_signals(o.user, data);
  if (o.effects.size() == 0 && o.user.empty())
    throw std::runtime_error("empty model: give at least one effect");
}

// The point the solve starts from: the initial model's values (neutral for the effects it did
// not have, its coefficients when it has the same user terms), bias and gravity by linear least
// squares unless it has both.
model::ModelParams start_params(const Dataset& data, const FitOptions& o) {
  model::ModelParams params;
  params.effects = o.effects;
  if (o.initial) {
    params.values = o.initial->values;
    // Effects the initial model did not have start from neutral values.
    for (Effect e : model::kAllEffects) {
      if (!o.initial->effects.has(e)) params.values[model::index(e)].fill(0.0);
    }
  }
  params.user = o.user;
  if (o.initial && o.initial->user.num_terms == o.user.num_terms) {
    bool same = true;
    for (int j = 0; j < o.user.num_terms; ++j)
      same = same && o.initial->user.terms[static_cast<std::size_t>(j)] ==
                         o.user.terms[static_cast<std::size_t>(j)];
    if (same) params.user.coeff = o.initial->user.coeff;
  }
  for (Effect e : model::kAllEffects) {
    if (is_frozen(o, e) && (o.initial == nullptr || !o.initial->effects.has(e)))
      throw std::runtime_error(std::string("frozen effect '") + model::info(e).name +
                               "' needs its values from the initial model");
  }
  const bool init_linear = o.initial == nullptr || !o.initial->effects.has(Effect::bias) ||
                           !o.initial->effects.has(Effect::gravity);
  if (init_linear) {
    linear_init(data, o, params);
    for (Effect e : {Effect::bias, Effect::gravity})  // frozen values stay as given
      if (is_frozen(o, e)) params.values[model::index(e)] = o.initial->values[model::index(e)];
  }
  return params;
}

// The unknowns: the model's effects with parameters in the order of model::kAllEffects (the
// parameter blocks of both engines), which of them stay frozen, and how many parameters are free.
struct Unknowns {
  std::vector<Effect> order;
  std::vector<bool> frozen;  // per effect of `order`
  int num_user = 0;          // user terms, free, after the effects
  int num_free = 0;
};

Unknowns unknowns_of(const FitOptions& o, int num_user) {
  Unknowns u;
  u.num_user = num_user;
  for (Effect e : model::kAllEffects) {
    if (o.effects.has(e) && model::info(e).num_params > 0) {
      u.order.push_back(e);
      u.frozen.push_back(is_frozen(o, e));
      if (!u.frozen.back()) u.num_free += model::info(e).num_params;
    }
  }
  u.num_free += num_user;
  if (u.num_free == 0 && (!u.order.empty() || num_user > 0))
    throw std::runtime_error("every effect of the model is frozen: nothing to fit");
  return u;
}

// What every pass evaluates: the blocks of samples, the engine, and what the engine computes once
// from the log (the block statistics, the user terms' mean design).
struct FitBlocks {
  int block_samples = 1;
  SampleBlocks blocks;
  bool normal_engine = false;       // else a Ceres problem
  std::optional<BlockStats> stats;  // engines normal and block_stats
  std::vector<double> user_design;  // mean_user_design
  const BlockStats* stats_or_null() const { return stats ? &*stats : nullptr; }
};

FitBlocks fit_blocks(const Dataset& data, const FitOptions& o, const model::UserEffects& user,
                     std::string& engine) {
  FitBlocks fb;
  if (o.block_samples < 1) throw std::runtime_error("block_samples must be at least 1");
  // Static rows (no time) are independent poses: each row is a block of its own.
  fb.block_samples = data.columns.static_rows ? 1 : std::max(1, o.block_samples);
  fb.blocks = make_blocks(data, o, fb.block_samples);
  if (o.engine != "normal" && o.engine != "block_stats" && o.engine != "samples")
    throw std::runtime_error("unknown fit engine '" + o.engine +
                             "' (normal, block_stats, samples)");
  // The normal engine solves least squares only: a robust loss goes to block_stats' Ceres path.
  fb.normal_engine = o.engine == "normal" && o.loss == "none";
  if (o.engine == "normal" && !fb.normal_engine) engine = "block_stats";
  if (o.engine != "samples") fb.stats.emplace(data, fb.blocks, o.effects, o.threads);
  fb.user_design = mean_user_design(data, user, fb.blocks);
  return fb;
}

// Whitening: per-axis noise of the block residuals. Estimated before solving from the scatter of
// consecutive block means inside dwells (there the residual of any model is a constant plus
// noise), so one solve suffices; without dwells, a second pass reweights.
struct Whitening {
  std::array<double, 6> sigma{};
  int passes = 1;
};

Whitening initial_whitening(const Dataset& data, const FitOptions& o, const FitBlocks& fb,
                            const model::ModelParams& start) {
  Whitening w;
  w.sigma = o.sigma.value_or(std::array<double, 6>{1, 1, 1, 0.1, 0.1, 0.1});
  if (o.sigma) return w;
  // Consecutive static rows are different poses, not one dwell: no noise estimate from them.
  const auto est =
      data.columns.static_rows
          ? std::nullopt
          : static_noise_of_block_means(
                data, fb.blocks,
                block_mean_residuals(data, fb.stats_or_null(), fb.blocks, start, fb.user_design));
  if (est) {
    w.sigma = *est;
  } else {
    w.passes = 2;
  }
  return w;
}

// One pass of the solve: which of how many, and its whitening.
struct Pass {
  int index = 0;
  int count = 1;
  std::array<double, 6> inv_sigma{};
};

std::string pass_progress(const Pass& pass, std::size_t blocks, int block_samples, int num_params) {
  return "fit pass " + std::to_string(pass.index + 1) + "/" + std::to_string(pass.count) + ": " +
         std::to_string(blocks) + " blocks of " + std::to_string(block_samples) + " samples, " +
         std::to_string(num_params) + " parameters";
}

// One pass of the normal engine: Levenberg–Marquardt on the streamed normal equations
// (normal_equations.hpp) from r.params, which it updates.
void solve_normal_pass(const Dataset& data, const FitOptions& o, const FitBlocks& fb,
                       const Unknowns& u, const Pass& pass, FitResult& r, Solved& solved) {
  NormalBlocks blocks(data, *fb.stats, r.params, u.order, u.frozen, pass.inv_sigma, fb.user_design);
  if (blocks.num_blocks() == 0) throw std::runtime_error("no samples to fit");
  normal::SolveOptions so;
  so.max_iterations = o.max_iterations;
  so.threads = o.threads;
  so.function_tolerance = 1e-10;  // as the Ceres path
  so.parameter_tolerance = 1e-10;
  so.progress = o.progress;
  if (o.progress) {
    o.progress(pass_progress(pass, blocks.num_blocks(), fb.block_samples, r.num_params) +
               " (normal equations)");
  }
  Eigen::VectorXd x = blocks.point();
  normal::SolveSummary summary = normal::solve(blocks, x, so);
  blocks.set_point(x);
  blocks.store(r.params);
  r.iterations += summary.iterations;
  solved.usable = summary.usable;
  solved.no_convergence = summary.usable && !summary.converged;
  solved.message = summary.message;
  solved.normal_JtJ = std::move(summary.at_solution.JtJ);
}

// The Ceres path's objects: the robust loss (null: least squares), which the problem does not
// own and so outlives it, and the last pass's problem, which the covariance evaluates again.
struct CeresPath {
  std::unique_ptr<ceres::LossFunction> loss;
  std::unique_ptr<ceres::Problem> problem;
};

std::unique_ptr<ceres::LossFunction> make_loss(const FitOptions& o) {
  if (o.loss == "huber") return std::make_unique<ceres::HuberLoss>(o.loss_scale);
  if (o.loss == "cauchy") return std::make_unique<ceres::CauchyLoss>(o.loss_scale);
  if (o.loss != "none")
    throw std::runtime_error("unknown loss '" + o.loss + "' (none, huber, cauchy)");
  return nullptr;
}

// One pass of the Ceres path (engines block_stats and samples): a new problem from r.params,
// which it updates.
void solve_ceres_pass(const Dataset& data, const FitOptions& o, const FitBlocks& fb,
                      const Unknowns& u, const Pass& pass, CeresPath& ceres_path, FitResult& r,
                      Solved& solved) {
  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres_path.problem = std::make_unique<ceres::Problem>(problem_options);
  ceres::Problem& problem = *ceres_path.problem;
  std::vector<double*> blocks;
  for (Effect e : u.order) blocks.push_back(r.params.block(e));
  if (u.num_user > 0) blocks.push_back(r.params.user.coeff.data());
  for (std::size_t b = 0; b < fb.blocks.size(); ++b) {
    const auto [first, count] = fb.blocks[b];
    problem.AddResidualBlock(
        make_block_cost(&data, fb.stats_or_null(), b, first, count, o.effects, u.order,
                        pass.inv_sigma,
                        &fb.user_design[b * 6 * static_cast<std::size_t>(u.num_user)], u.num_user),
        ceres_path.loss.get(), blocks);
  }
  if (problem.NumResidualBlocks() == 0) throw std::runtime_error("no samples to fit");
  for (std::size_t k = 0; k < u.order.size(); ++k)
    if (u.frozen[k]) problem.SetParameterBlockConstant(r.params.block(u.order[k]));
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  so.num_threads = o.threads;
  so.max_num_iterations = o.max_iterations;
  so.function_tolerance = 1e-10;
  so.parameter_tolerance = 1e-10;
  so.logging_type = ceres::SILENT;
  std::unique_ptr<ProgressCallback> cb;
  if (o.progress) {
    o.progress(pass_progress(pass, static_cast<std::size_t>(problem.NumResidualBlocks()),
                             fb.block_samples, r.num_params));
    cb = std::make_unique<ProgressCallback>(o.progress);
    so.callbacks.push_back(cb.get());
  }
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  if (std::getenv("ZEROG_CERES_REPORT")) std::fprintf(stderr, "%s\n", summary.FullReport().c_str());
  r.iterations += static_cast<int>(summary.iterations.size());
  solved.usable = summary.IsSolutionUsable();
  solved.no_convergence = summary.termination_type == ceres::NO_CONVERGENCE;
  solved.message = summary.message;
}

// The whitening of the next pass: the RMS of the block-mean residuals the fit sees (from the
// block statistics when the engine has them), floored.
std::array<double, 6> reweighted_sigma(const Dataset& data, const FitBlocks& fb,
                                       const model::ModelParams& params) {
  std::array<double, 6> ss_block{};
  const double nb = static_cast<double>(fb.blocks.size());
  for (const Wrench& mean :
       block_mean_residuals(data, fb.stats_or_null(), fb.blocks, params, fb.user_design))
    for (int k = 0; k < 6; ++k) ss_block[k] += mean[k] * mean[k];
  std::array<double, 6> sigma{};
  for (int k = 0; k < 6; ++k) sigma[k] = std::max(std::sqrt(ss_block[k] / nb), k < 3 ? 1e-4 : 1e-5);
  return sigma;
}

// After the last pass: sums of squares of the per-sample residuals (their RMS is what compare
// reports) and of the block means (their whitened sum gives the BIC), in one pass over the samples.
struct ResidualSums {
  std::array<double, 6> ss{};        // per sample
  std::array<double, 6> ss_block{};  // per block mean
  std::size_t n = 0;                 // samples
};

// The residuals of a round of blocks are formed on the fit's threads (each sample's on its own),
// then summed in sample order: the sums of one thread, for any thread count. Alone on one thread
// this pass took as long as the model evaluation of the whole log (issue 16).
ResidualSums residual_sums(const Dataset& data, const FitOptions& o, const SampleBlocks& blocks,
                           const model::ModelParams& params) {
  ResidualSums s;
  ResidentWindow window(data);
  constexpr std::size_t kRoundBlocks = 2048, kTaskBlocks = 256;
  std::vector<std::size_t> at(kRoundBlocks + 1);  // a block's first residual in `e`
  std::vector<Wrench> e;
  for (std::size_t b0 = 0; b0 < blocks.size(); b0 += kRoundBlocks) {
    const std::size_t b1 = std::min(blocks.size(), b0 + kRoundBlocks);
    for (std::size_t b = b0; b < b1; ++b) at[b - b0 + 1] = at[b - b0] + blocks[b].second;
    e.resize(at[b1 - b0]);
    parallel::for_each(
        (b1 - b0 + kTaskBlocks - 1) / kTaskBlocks, o.threads, [&](std::size_t task, int) {
          const std::size_t t0 = b0 + task * kTaskBlocks;
          for (std::size_t b = t0; b < std::min(b1, t0 + kTaskBlocks); ++b) {
            const auto [first, count] = blocks[b];
            for (std::size_t i = 0; i < count; ++i)
              e[at[b - b0] + i] = data.measured[first + i] - predict(params, data, first + i);
          }
        });
    for (std::size_t b = b0; b < b1; ++b) {
      const auto [first, count] = blocks[b];
      Wrench mean = Wrench::Zero();
      for (std::size_t i = 0; i < count; ++i) {
        const Wrench& ei = e[at[b - b0] + i];
        for (int k = 0; k < 6; ++k) s.ss[k] += ei[k] * ei[k];
        mean += ei;
        ++s.n;
      }
      mean /= static_cast<double>(count);
      for (int k = 0; k < 6; ++k) s.ss_block[k] += mean[k] * mean[k];
    }
    window.advance(blocks[b1 - 1].first + blocks[b1 - 1].second);
  }
  return s;
}

// The passes: each solves from where the last one ended, with the whitening the last one's
// residuals give; the last one's residuals are the fit's.
Solved solve_passes(const Dataset& data, const FitOptions& o, const FitBlocks& fb,
                    const Unknowns& u, const Whitening& whitening, CeresPath& ceres_path,
                    FitResult& r) {
  Solved solved;
  solved.sigma = whitening.sigma;
  for (int index = 0; index < whitening.passes; ++index) {
    Pass pass{index, whitening.passes, {}};
    for (int k = 0; k < 6; ++k) pass.inv_sigma[k] = 1.0 / solved.sigma[k];
    if (fb.normal_engine) {
      solve_normal_pass(data, o, fb, u, pass, r, solved);
    } else {
      solve_ceres_pass(data, o, fb, u, pass, ceres_path, r, solved);
    }
    solved.nb = fb.blocks.size();
    if (index + 1 < whitening.passes) {
      solved.sigma = reweighted_sigma(data, fb, r.params);
      continue;
    }
    const ResidualSums s = residual_sums(data, o, fb.blocks, r.params);
    solved.n = s.n;
    solved.ssr = 0.0;
    for (int k = 0; k < 6; ++k) {
      solved.rms[k] = std::sqrt(s.ss[k] / static_cast<double>(s.n));
      solved.ssr += s.ss_block[k] / (solved.sigma[k] * solved.sigma[k]);
    }
  }
  return solved;
}

// The fit's figures from the solve: whitening, residuals, BIC, a warning when it did not converge.
void summarize(const Solved& solved, FitResult& r) {
  r.sigma = solved.sigma;
  r.residual_rms = solved.rms;
  r.samples = solved.n;
  r.usable = solved.usable;
  r.termination = solved.message;
  const double n_res = 6.0 * static_cast<double>(solved.nb);
  r.bic = n_res * std::log(solved.ssr / n_res) + r.num_params * std::log(n_res);
  if (solved.no_convergence) {
    r.warnings.push_back({"not_converged", "the solver stopped after " +
                                               std::to_string(r.iterations) +
                                               " iterations without converging"});
  }
}

// The free parameters in the order of the normal matrix's columns. Frozen blocks are not
// estimated and have no covariance.
struct FreeParams {
  std::vector<double*> blocks;  // the library effects', then the user terms' (one block)
  // Column q: (effect, index), or (no effect, term) for a user term.
  std::vector<std::pair<std::optional<Effect>, int>> names;
};

FreeParams free_params(const Unknowns& u, model::ModelParams& params) {
  FreeParams fp;
  for (std::size_t k = 0; k < u.order.size(); ++k) {
    if (u.frozen[k]) continue;
    const Effect e = u.order[k];
    fp.blocks.push_back(params.block(e));
    for (int i = 0; i < model::info(e).num_params; ++i) fp.names.emplace_back(e, i);
  }
  if (u.num_user > 0) fp.blocks.push_back(params.user.coeff.data());
  for (int j = 0; j < u.num_user; ++j) fp.names.emplace_back(std::nullopt, j);
  return fp;
}

std::string column_label(const FreeParams& fp, const model::UserEffects& user, int q) {
  const auto& [effect, i] = fp.names[static_cast<std::size_t>(q)];
  return effect ? param_label(*effect, i) : io::term_label(user, i);
}

// JᵀJ of the free parameters at the solution: the normal engine's own, or from Ceres' Jacobian.
Eigen::MatrixXd free_normal_matrix(const FitBlocks& fb, const Solved& solved, const FreeParams& fp,
                                   ceres::Problem* problem) {
  if (fb.normal_engine) return solved.normal_JtJ;  // the normal equations at the solution
  ceres::Problem::EvaluateOptions eval_options;
  eval_options.parameter_blocks = fp.blocks;
  ceres::CRSMatrix J;
  double cost = 0.0;
  problem->Evaluate(eval_options, &cost, nullptr, nullptr, &J);
  const int p = J.num_cols;
  Eigen::MatrixXd JtJ = Eigen::MatrixXd::Zero(p, p);
  Eigen::VectorXd row(p);
  for (int i = 0; i < J.num_rows; ++i) {
    row.setZero();
    for (int k = J.rows[i]; k < J.rows[i + 1]; ++k) row[J.cols[k]] = J.values[k];
    JtJ.selfadjointView<Eigen::Lower>().rankUpdate(row);
  }
  JtJ = JtJ.selfadjointView<Eigen::Lower>();
  return JtJ;
}

// A warning per direction the data cannot identify; the parameters they name are deficient.
std::vector<bool> warn_rank_deficient(const RankCheck& rank, int p, const FreeParams& fp,
                                      const model::UserEffects& user, FitResult& r) {
  std::vector<bool> deficient(p, false);
  for (const std::vector<int>& group : rank.null_directions) {
    std::string who;
    for (int q : group) {
      deficient[static_cast<std::size_t>(q)] = true;
      who += (who.empty() ? "" : ", ") + column_label(fp, user, q);
    }
    const std::size_t count = group.size();
    r.warnings.push_back(
        {"rank_deficient",
         count == 1 ? "the data cannot identify " + who +
                          ": it does not change the prediction on this log (rank deficiency)"
                    : "the data cannot identify " + who +
                          " separately: only a combination of them changes the prediction "
                          "(rank deficiency)"});
  }
  return deficient;
}

// Ceres' own covariance (SPARSE_QR) in place of `cov`, where Ceres computes one; it cross-checks
// ours.
void ceres_covariance(const FitOptions& o, const FreeParams& fp, ceres::Problem* problem,
                      Eigen::MatrixXd& cov) {
  ceres::Covariance::Options co;
  co.num_threads = o.threads;
  ceres::Covariance covariance(co);
  std::vector<std::pair<const double*, const double*>> pairs;
  for (const double* a : fp.blocks)
    for (const double* b : fp.blocks) pairs.emplace_back(a, b);
  std::vector<const double*> ptrs(fp.blocks.begin(), fp.blocks.end());
  if (covariance.Compute(pairs, problem)) {
    Eigen::MatrixXd ceres_cov(cov.rows(), cov.cols());
    covariance.GetCovarianceMatrix(ptrs, ceres_cov.data());
    cov = ceres_cov.transpose();  // column-major view of the row-major result
  }
}

// The cluster-robust covariance (a sandwich): (JᵀJ)⁻¹ (Σ_c g_c g_cᵀ) (JᵀJ)⁻¹ with g_c the score Jᵀr
// of cluster c's blocks, `cov` the model-based one before it is scaled by s². Sets r.std_kind and
// r.clusters; empty when the figures stay model-based.
std::optional<Eigen::MatrixXd> robust_covariance(const Dataset& data, const FitOptions& o,
                                                 const FitBlocks& fb, const Unknowns& u,
                                                 const Eigen::MatrixXd& cov, FitResult& r) {
  if (o.std_kind != "white" && o.std_kind != "robust")
    throw std::runtime_error("unknown std kind '" + o.std_kind + "' (robust, white)");
  r.std_kind = o.loss == "none" ? o.std_kind : "white";
  // A robust loss has its own score (ψ(r) Jᵀ, not Jᵀr): the model-based figures stand.
  if (o.std_kind != "robust" || o.loss != "none") return std::nullopt;
  std::optional<BlockStats> own;
  const BlockStats& st = fb.stats ? *fb.stats : own.emplace(data, fb.blocks, o.effects, o.threads);
  std::array<double, 6> inv_sigma;
  for (int k = 0; k < 6; ++k) inv_sigma[k] = 1.0 / r.sigma[k];
  NormalBlocks nb(data, st, r.params, u.order, u.frozen, inv_sigma, fb.user_design);
  if (nb.num_params() != cov.rows()) return std::nullopt;
  const Eigen::MatrixXd meat = cluster_meat(nb, data, fb.blocks, o.cluster_s, &r.clusters);
  if (r.clusters > 1) return cov * meat * cov;
  return std::nullopt;
}

// The standard deviations, model-based (`white`) and the larger of it and the robust one; NaN
// where the parameter is not identified or frozen.
void store_stds(const Eigen::MatrixXd& cov, const std::optional<Eigen::MatrixXd>& robust,
                const std::vector<bool>& deficient, const FreeParams& fp, int num_user,
                FitResult& r) {
  ParamArray stds{}, white{};
  for (auto& a : stds) a.fill(std::numeric_limits<double>::quiet_NaN());
  for (auto& a : white) a.fill(std::numeric_limits<double>::quiet_NaN());
  r.user_std.assign(static_cast<std::size_t>(num_user), std::numeric_limits<double>::quiet_NaN());
  r.user_std_white = r.user_std;
  for (int q = 0; q < static_cast<int>(cov.rows()); ++q) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double w = deficient[q] ? nan : std::sqrt(std::max(cov(q, q), 0.0));
    const double sd =
        deficient[q] || !robust ? w : std::sqrt(std::max({cov(q, q), (*robust)(q, q), 0.0}));
    const auto& [effect, i] = fp.names[static_cast<std::size_t>(q)];
    if (effect) {
      stds[model::index(*effect)][i] = sd;
      white[model::index(*effect)][i] = w;
    } else {
      r.user_std[static_cast<std::size_t>(i)] = sd;
      r.user_std_white[static_cast<std::size_t>(i)] = w;
    }
  }
  r.std = stds;
  r.std_white = white;
}

void warn_correlated(const Eigen::MatrixXd& cov, const std::vector<bool>& deficient,
                     const FreeParams& fp, FitResult& r) {
  const int p = static_cast<int>(cov.rows());
  for (int a = 0; a < p; ++a) {
    for (int b = a + 1; b < p; ++b) {
      if (deficient[a] || deficient[b]) continue;
      const double rho = cov(a, b) / std::sqrt(cov(a, a) * cov(b, b));
      if (std::abs(rho) > 0.99) {
        std::ostringstream os;
        os.precision(4);
        os << column_label(fp, r.params.user, a) << " and " << column_label(fp, r.params.user, b)
           << " are strongly correlated (rho = " << rho
           << "): the data barely tells them apart; their standard deviations are large";
        r.warnings.push_back({"correlated", os.str()});
      }
    }
  }
}

// Identifiability and uncertainty from the column-scaled JᵀJ of the free parameters (rank,
// correlations): warnings, standard deviations.
void estimate_covariance(const Dataset& data, const FitOptions& o, const FitBlocks& fb,
                         const Unknowns& u, const Solved& solved, ceres::Problem* problem,
                         FitResult& r) {
  const FreeParams fp = free_params(u, r.params);
  const Eigen::MatrixXd JtJ = free_normal_matrix(fb, solved, fp, problem);
  const Eigen::VectorXd d = JtJ.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXd C = d.asDiagonal() * JtJ * d.asDiagonal();
  const RankCheck rank = rank_check(C);
  const std::vector<bool> deficient =
      warn_rank_deficient(rank, static_cast<int>(JtJ.rows()), fp, r.params.user, r);
  Eigen::MatrixXd cov = d.asDiagonal() * rank.cov_scaled * d.asDiagonal();
  // Ceres' covariance needs full rank; the normal engine has no Ceres problem and keeps the
  // inverse of its normal matrix above.
  bool any_deficient = false;
  for (bool b : deficient) any_deficient = any_deficient || b;
  if (!any_deficient && !fb.normal_engine) ceres_covariance(o, fp, problem, cov);
  const std::optional<Eigen::MatrixXd> robust = robust_covariance(data, o, fb, u, cov, r);
  const double n_res = 6.0 * static_cast<double>(solved.nb);
  const double s2 = solved.ssr / std::max(1.0, n_res - r.num_params);
  cov *= s2;
  store_stds(cov, robust, deficient, fp, u.num_user, r);
  warn_correlated(cov, deficient, fp, r);
}

}  // namespace

std::string param_label(Effect e, int i) {
  const auto& ei = model::info(e);
  return std::string(ei.name) + "." + ei.params[i].name + " [" + ei.params[i].unit + "]";
}

// Problem, solve, summary, as Ceres has them: the phases above in order.
FitResult fit(const Dataset& data, const FitOptions& o) {
  const auto start = std::chrono::steady_clock::now();
  check_model(data, o);
  FitResult r;
  r.engine = o.engine;
  r.params = start_params(data, o);
  const Unknowns u = unknowns_of(o, r.params.user.num_terms);
  r.num_params = u.num_free;
  // Errors in variables (eiv.hpp): decided (and a bad mode refused) before the solve.
  r.errors_in_variables.mode = o.errors_in_variables;
  const bool eiv = errors_in_variables_applies(o, data, &r.errors_in_variables.reason);
  const FitBlocks fb = fit_blocks(data, o, r.params.user, r.engine);
  const Whitening whitening = initial_whitening(data, o, fb, r.params);
  CeresPath ceres_path;
  ceres_path.loss = make_loss(o);
  const Solved solved = solve_passes(data, o, fb, u, whitening, ceres_path, r);
  summarize(solved, r);
  if (o.covariance && r.usable && r.num_params > 0)
    estimate_covariance(data, o, fb, u, solved, ceres_path.problem.get(), r);
  if (eiv && r.usable) correct_errors_in_variables(data, o, fb.blocks, r);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return r;
}

// ---- screening.hpp: the training problem of a model at a point, for diagnose's screening ----

struct screening::TrainingProblem::Impl {
  Impl(const Dataset& data, const FitOptions& o, const model::ModelParams& point)
      : blocks(make_blocks(data, o, data.columns.static_rows ? 1 : std::max(1, o.block_samples))),
        stats(data, blocks, o.effects),
        user_design(mean_user_design(data, point.user, blocks)) {
    if (!o.sigma) throw std::runtime_error("screening needs the whitening (FitOptions::sigma)");
    if (blocks.empty()) throw std::runtime_error("no samples to fit");
    std::array<double, 6> inv_sigma;
    for (int k = 0; k < 6; ++k) inv_sigma[k] = 1.0 / (*o.sigma)[k];
    std::vector<bool> frozen;
    for (Effect e : model::kAllEffects) {
      if (!o.effects.has(e) || model::info(e).num_params == 0) continue;
      order.push_back(e);
      frozen.push_back(o.frozen.has(e));
    }
    column.fill(-1);
    int next = 0;
    for (std::size_t b = 0; b < order.size(); ++b) {
      if (frozen[b]) continue;
      column[static_cast<std::size_t>(model::index(order[b]))] = next;
      next += model::info(order[b]).num_params;
    }
    user_column = point.user.num_terms > 0 ? next : -1;
    evaluator =
        std::make_unique<NormalBlocks>(data, stats, point, order, frozen, inv_sigma, user_design);
    x0 = evaluator->point();
  }
  SampleBlocks blocks;
  BlockStats stats;
  std::vector<double> user_design;
  std::vector<Effect> order;
  std::array<int, model::kEffectCount> column{};
  int user_column = -1;
  std::unique_ptr<NormalBlocks> evaluator;
  Eigen::VectorXd x0;
};

screening::TrainingProblem::TrainingProblem(const Dataset& data, const FitOptions& options,
                                            const model::ModelParams& point)
    : impl_(std::make_unique<Impl>(data, options, point)) {}
screening::TrainingProblem::~TrainingProblem() = default;

int screening::TrainingProblem::num_params() const { return impl_->evaluator->num_params(); }
std::size_t screening::TrainingProblem::num_blocks() const { return impl_->blocks.size(); }
int screening::TrainingProblem::column(Effect e) const {
  return impl_->column[static_cast<std::size_t>(model::index(e))];
}
int screening::TrainingProblem::user_column() const { return impl_->user_column; }

bool screening::TrainingProblem::accumulate(int threads, normal::NormalEquations& out) const {
  return normal::accumulate(*impl_->evaluator, threads, out);
}

bool screening::TrainingProblem::evaluate(std::size_t b, double* residual, double* jacobian) const {
  return impl_->evaluator->evaluate(b, residual, jacobian);
}

double screening::TrainingProblem::ssr_at(const Eigen::VectorXd& step, int threads) const {
  NormalBlocks& f = *impl_->evaluator;
  f.set_point(impl_->x0 + step);
  // Residuals only (one model evaluation per block), the blocks' on `threads` threads (each its
  // own, each worker walking a spilled log's rows with its own BlockWalk), then summed in block
  // order: the same sum for any thread count.
  const std::size_t nb = f.num_blocks();
  constexpr std::size_t kBlocksPerTask = normal::kChunkBlocks;
  const std::size_t tasks = (nb + kBlocksPerTask - 1) / kBlocksPerTask;
  std::vector<double> r(6 * nb);
  std::vector<std::uint8_t> ok(tasks, 1);
  std::vector<std::unique_ptr<normal::BlockWalk>> walks(
      static_cast<std::size_t>(parallel::workers(tasks, threads)));
  for (auto& w : walks) w = f.walk();
  parallel::for_each(tasks, threads, [&](std::size_t task, int worker) {
    normal::BlockWalk* walk = walks[static_cast<std::size_t>(worker)].get();
    const std::size_t b1 = std::min(nb, (task + 1) * kBlocksPerTask);
    for (std::size_t b = task * kBlocksPerTask; b < b1 && ok[task]; ++b) {
      if (walk) walk->at(b);
      ok[task] = f.evaluate(b, r.data() + 6 * b, nullptr) ? 1 : 0;
    }
  });
  f.set_point(impl_->x0);
  double ssr = 0.0;
  for (double v : r) ssr += v * v;
  const bool all_ok = std::all_of(ok.begin(), ok.end(), [](std::uint8_t k) { return k != 0; });
  return all_ok && std::isfinite(ssr) ? ssr : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace zerog::ident
