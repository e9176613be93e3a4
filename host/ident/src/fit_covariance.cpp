// fit()'s identifiability and uncertainty (fit_internal.hpp): the rank check of the
// column-scaled normal matrix, its warnings, the model-based covariance (ours, or Ceres' where it
// computes one), the cluster-robust sandwich and the standard deviations fit() reports.
#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <utility>

#include "fit_internal.hpp"
#include "residual_blocks.hpp"
#include "zerog/io/effect_file.hpp"

namespace zerog::ident::fitting {
namespace {

using model::Effect;

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

}  // namespace

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

}  // namespace zerog::ident::fitting
