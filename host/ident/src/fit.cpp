// fit() (fit.hpp): the start values, the blocks and the whitening, the solver passes (the normal
// engine's streamed normal equations or a Ceres problem, residual_blocks.hpp's blocks either way),
// the summary; the covariance after them is fit_covariance.cpp's (fit_internal.hpp).
#include "zerog/ident/fit.hpp"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <sstream>
#include <utility>

#include "fit_internal.hpp"
#include "normal_equations.hpp"
#include "parallel.hpp"
#include "residual_blocks.hpp"
#include "zerog/ident/block_stats.hpp"
#include "zerog/ident/eiv.hpp"

namespace zerog::ident {

using fitting::estimate_covariance;
using fitting::FitBlocks;
using fitting::make_block_cost;
using fitting::make_blocks;
using fitting::mean_user_design;
using fitting::NormalBlocks;
using fitting::Solved;
using fitting::Unknowns;
using fitting::use;

namespace {

using model::Effect;

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

}  // namespace zerog::ident
