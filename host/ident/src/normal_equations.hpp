#pragma once
// The fit's "normal" engine (fit.hpp, FitOptions::engine): Levenberg–Marquardt on the whitened
// normal equations JᵀJ, Jᵀr of the block residuals, accumulated in one streaming pass over the
// blocks per iteration. A block's residual (6) and Jacobian (6 × free parameters) come from the
// caller's BlockEvaluator (fit.cpp evaluates them exactly as the block_stats engine does); no
// block's Jacobian outlives its chunk, so memory does not grow with the number of blocks beyond
// one n × n partial sum per chunk.
//
// Determinism: the blocks are cut into fixed chunks (kChunkBlocks); each chunk's partial sums
// are computed independently (by whichever thread) and added in chunk order, so the result is
// bit-identical for any thread count.
//
// The iteration follows Ceres' trust-region Levenberg–Marquardt as fit.cpp configures it
// (DENSE_NORMAL_CHOLESKY, Jacobi column scaling fixed at the first iteration, radius 1e4,
// minimum relative decrease 1e-3, function / parameter tolerance from the options, gradient
// tolerance 1e-10), so that where the problem is nearly rank deficient both take the same path.
//
// Robust losses (huber, cauchy) are left to the Ceres path: fit.cpp delegates them to the Ceres
// path of the block_stats engine.
// Host only: allocates.
#include <Eigen/Core>
#include <cstddef>
#include <functional>
#include <memory>
#include <string>

namespace zerog::ident::normal {

/// Blocks per chunk of the streaming pass (the unit of work and of summation order).
inline constexpr std::size_t kChunkBlocks = 512;

/// A worker's walk over the blocks of one pass (blocks in increasing order): BlockEvaluator::walk.
class BlockWalk {
 public:
  virtual ~BlockWalk() = default;
  /// The worker is about to evaluate block b.
  virtual void at(std::size_t b) = 0;
};

/// The residuals of a least-squares problem, block by block.
class BlockEvaluator {
 public:
  virtual ~BlockEvaluator() = default;
  virtual std::size_t num_blocks() const = 0;
  virtual int num_params() const = 0;  ///< free parameters n
  /// Makes `x` (n free parameters) the point of the following evaluate calls. Not concurrent.
  virtual void set_point(const Eigen::VectorXd& x) = 0;
  /// Block b's whitened residual (6) and, if `jacobian` is not null, its derivative with respect
  /// to the free parameters (6 × n, row-major) at the point. Called concurrently from several
  /// threads (for different blocks); false if the evaluation failed.
  virtual bool evaluate(std::size_t b, double* residual, double* jacobian) const = 0;
  /// A walk for one worker of a pass, told each block before it is evaluated (the fit's releases
  /// the rows behind it: ident/spill.hpp); null (the default) for none.
  virtual std::unique_ptr<BlockWalk> walk() const { return nullptr; }
};

/// The normal equations of ½ Σ_b |r_b|² at one point.
struct NormalEquations {
  Eigen::MatrixXd JtJ;  ///< n × n, symmetric (both triangles filled)
  Eigen::VectorXd Jtr;  ///< n; the gradient of the cost
  double cost = 0.0;    ///< ½ Σ |r|²
};

/// One streaming pass over all blocks at the evaluator's current point, on `threads` threads
/// (deterministic, see above). False if an evaluation failed.
bool accumulate(const BlockEvaluator& f, int threads, NormalEquations& out);

struct SolveOptions {
  int max_iterations = 50;
  int threads = 2;
  double function_tolerance = 1e-10;
  double parameter_tolerance = 1e-10;
  double gradient_tolerance = 1e-10;
  std::function<void(const std::string&)> progress;  ///< one line per iteration (may be empty)
};

struct SolveSummary {
  bool usable = false;     ///< as Ceres' IsSolutionUsable: converged or out of iterations
  bool converged = false;  ///< a tolerance was met
  std::string message;
  int iterations = 0;           ///< as Ceres counts them (iteration 0 included)
  NormalEquations at_solution;  ///< at the returned point
};

/// Minimises ½ Σ_b |r_b(x)|², starting from `x` (updated in place).
SolveSummary solve(BlockEvaluator& f, Eigen::VectorXd& x, const SolveOptions& options);

}  // namespace zerog::ident::normal
