#pragma once
// Screening of candidate effects for diagnose (candidates.cpp, issue 16): the training problem of
// one model holding the baseline and every candidate, as the fit's normal engine sees it
// (normal_equations.hpp: the same blocks, whitening and block evaluation as fit(), one copy of
// the model), and the Gauss–Newton step of the baseline plus one candidate from its normal
// equations (a bordered system, solved through the Schur complement on the candidate's columns).
// Host only: allocates.
#include <Eigen/Core>
#include <memory>
#include <vector>

#include "normal_equations.hpp"
#include "zerog/ident/fit.hpp"

namespace zerog::ident::screening {

/// The least-squares problem fit() solves for `options` (effects, user terms, mask, frozen
/// effects, block_samples; `options.sigma` must be set: the whitening is not re-estimated),
/// at the point `point` (its values and user coefficients; effects as in `options`).
class TrainingProblem {
 public:
  TrainingProblem(const Dataset& data, const FitOptions& options, const model::ModelParams& point);
  ~TrainingProblem();
  TrainingProblem(const TrainingProblem&) = delete;
  TrainingProblem& operator=(const TrainingProblem&) = delete;

  int num_params() const;          ///< free parameters n (the normal engine's packing)
  std::size_t num_blocks() const;  ///< block residuals (6 each)
  /// First column of effect e's parameters, −1 if the problem does not fit them (absent,
  /// frozen, or without parameters).
  int column(model::Effect e) const;
  /// First column of the user terms (they are the last columns), −1 without user terms.
  int user_column() const;
  /// The normal equations at the point (one streaming pass, normal::accumulate). False if an
  /// evaluation failed.
  bool accumulate(int threads, normal::NormalEquations& out) const;
  /// Block b's whitened residual (6) and its derivative with respect to the n free parameters
  /// (6 × n, row-major) at the point, as the fit evaluates them. False if the evaluation failed.
  bool evaluate(std::size_t b, double* residual, double* jacobian) const;
  /// Σ_b |r_b|² (whitened block residuals, what the BIC counts) at the point moved by `step`
  /// (n columns); NaN if an evaluation failed. The point itself is not changed. The blocks are
  /// evaluated on `threads` threads and summed in block order (the same sum for any count).
  double ssr_at(const Eigen::VectorXd& step, int threads = 1) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The Gauss–Newton step x of ½|r + J x|² restricted to the base columns and one set of
/// candidate columns: H_SS x_S = −g_S with S = base ∪ candidate. The base block is factored once;
/// each candidate is a bordered system solved through its Schur complement
/// S_c = H_cc − H_cb H_bb⁺ H_bc (Golub & Van Loan, Matrix Computations, 4th ed., §3.2.11).
/// Rank deficiency as the fit's rank check treats it: on the Jacobi-scaled matrix (unit
/// diagonal), eigen-directions below kRankCut of the largest carry no step (a pseudo-inverse).
class BorderedSolver {
 public:
  static constexpr double kRankCut = 1e-9;  ///< fit.cpp rank_check's nominal cut
  /// `H` (n × n) and `g` (n) are held by reference: they must outlive the solver.
  /// `drop_coupling` is a test-only mutant: it ignores H_bc (the candidate alone, base held),
  /// which the screening tests must detect.
  BorderedSolver(const Eigen::MatrixXd& H, const Eigen::VectorXd& g, std::vector<int> base,
                 bool drop_coupling = false);
  /// The step over all n columns (zero outside base ∪ `candidate`).
  Eigen::VectorXd step(const std::vector<int>& candidate) const;

 private:
  const Eigen::MatrixXd& H_;
  const Eigen::VectorXd& g_;
  std::vector<int> base_;
  bool drop_coupling_;
  Eigen::VectorXd d_base_;     // Jacobi scaling of the base columns
  Eigen::MatrixXd pinv_base_;  // (D H_bb D)⁺
};

/// The same step by one pseudo-inverse of the whole scaled sub-block H_SS (the reference of the
/// bordered solve in tests).
Eigen::VectorXd direct_step(const Eigen::MatrixXd& H, const Eigen::VectorXd& g,
                            const std::vector<int>& columns);

}  // namespace zerog::ident::screening
