#pragma once
// fit()'s residual blocks (residual_blocks.cpp): a block of consecutive samples, whitened mean
// residual and its derivatives through the model's two stages (BlockCost, behind BlockCostBase),
// the normal engine's view of them (NormalBlocks, normal_equations.hpp), the blocks of a log and
// the user terms' mean design per block. fit.cpp solves with them, fit_covariance.cpp measures
// the uncertainty, training_problem.cpp hands them to diagnose's screening. Host only: allocates.
#include <ceres/ceres.h>

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cstddef>
#include <memory>
#include <utility>
#include <vector>

#include "normal_equations.hpp"
#include "zerog/ident/block_stats.hpp"
#include "zerog/ident/fit.hpp"

namespace zerog::ident::fitting {

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
// rank check, covariance and BIC (fit.cpp, fit_covariance.cpp) then come from its final normal
// matrix.
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

/// The narrowest BlockCost whose sensor-stage Jet holds the model's sensor-stage parameters.
BlockCostBase* make_block_cost(const Dataset* data, const BlockStats* stats, std::size_t block,
                               std::size_t first, std::size_t count, model::EffectSet effects,
                               const std::vector<model::Effect>& order,
                               std::array<double, 6> inv_sigma, const double* user_design,
                               int num_user);

// The normal engine's view of the fit (normal_equations.hpp): every block evaluated through one
// BlockCost with the block statistics (the block_stats engine's evaluation), the free parameters
// packed in the order of the Ceres path's parameter blocks (the effects of `order` that are not
// frozen, then the user terms).
class NormalBlocks final : public normal::BlockEvaluator {
 public:
  NormalBlocks(const Dataset& data, const BlockStats& stats, const model::ModelParams& start,
               const std::vector<model::Effect>& order, const std::vector<bool>& frozen,
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
  std::vector<model::Effect> order_;
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
SampleBlocks make_blocks(const Dataset& data, const FitOptions& o, int m);

// Whether sample i is used (in o.mask, or every sample without one).
bool use(const FitOptions& o, std::size_t i);

// User terms are linear: each block's mean design (6 × num_user, column-major) is computed once.
std::vector<double> mean_user_design(const Dataset& data, const model::UserEffects& user,
                                     const SampleBlocks& blocks);

}  // namespace zerog::ident::fitting
