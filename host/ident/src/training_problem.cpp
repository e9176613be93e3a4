// screening.hpp's TrainingProblem: the training problem of a model at a point, as fit()'s
// normal engine sees it (the same blocks, whitening and block evaluation: residual_blocks.hpp),
// for diagnose's screening of candidate effects.
#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <stdexcept>
#include <vector>

#include "normal_equations.hpp"
#include "parallel.hpp"
#include "residual_blocks.hpp"
#include "screening.hpp"

namespace zerog::ident {

using fitting::make_blocks;
using fitting::mean_user_design;
using fitting::NormalBlocks;
using model::Effect;

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
