#include "normal_equations.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace zerog::ident::normal {
namespace {

struct Partial {
  Eigen::MatrixXd JtJ;  // lower triangle
  Eigen::VectorXd Jtr;
  double cost = 0.0;
  bool ok = true;
};

// Chunk c's partial sums (blocks [c K, min((c + 1) K, nb))); `J`, `r`: the worker's scratch.
void chunk_sums(const BlockEvaluator& f, std::size_t c, bool with_jacobian,
                Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>& J,
                Eigen::VectorXd& r, BlockWalk* walk, Partial& out) {
  const std::size_t nb = f.num_blocks();
  const std::size_t b0 = c * kChunkBlocks, b1 = std::min(nb, b0 + kChunkBlocks);
  const Eigen::Index n = f.num_params();
  const auto rows = static_cast<Eigen::Index>(6 * (b1 - b0));
  for (std::size_t b = b0; b < b1; ++b) {
    const auto row = static_cast<Eigen::Index>(6 * (b - b0));
    if (walk != nullptr) walk->at(b);
    out.ok = f.evaluate(b, r.data() + row, with_jacobian ? J.data() + row * n : nullptr) && out.ok;
  }
  out.cost = 0.5 * r.head(rows).squaredNorm();
  if (!with_jacobian) return;
  // Most parameters act on one axis of the wrench (bias, cross-talk, cable, drift, ...): the
  // rows of axis a (a, a + 6, ...) are dense only on their own columns. Per axis, those columns
  // gathered and one dense rank update on them (exact: the others are exact zeros), scattered
  // into JᵀJ; a few times fewer operations than the dense 6·count × n update.
  out.JtJ.setZero(n, n);
  out.Jtr.setZero(n);
  const auto count = static_cast<Eigen::Index>(b1 - b0);
  using Strided = Eigen::Map<Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>,
                             0, Eigen::OuterStride<>>;
  using StridedVector = Eigen::Map<Eigen::VectorXd, 0, Eigen::InnerStride<6>>;
  // Each axis' nonzero columns, from one pass over the rows in memory order (a scan column by
  // column would stride 6 n doubles per element and miss the cache on most of them).
  using Mask = Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  Mask nonzero = Mask::Zero(6, n);
  for (Eigen::Index i = 0; i < rows; ++i)
    nonzero.row(i % 6) = nonzero.row(i % 6) || (J.row(i).array() != 0.0);
  std::vector<Eigen::Index> columns;
  // The gathered columns: column-major (a row-major copy changes the order of the rank update's
  // sums, and the full-list fit then moves by 1e-9), each 8 doubles longer than count: with
  // count = 512 they would be 4 KiB apart and the stores of one row, gathered in J's memory
  // order below, would all hit the same cache set.
  const Eigen::Index leading = count + 8;
  Eigen::VectorXd gathered_storage;
  Eigen::MatrixXd update;
  for (int axis = 0; axis < 6; ++axis) {
    const Strided rows_of_axis(J.data() + axis * n, count, n, Eigen::OuterStride<>(6 * n));
    const StridedVector r_of_axis(r.data() + axis, count);
    columns.clear();
    for (Eigen::Index j = 0; j < n; ++j)
      if (nonzero(axis, j)) columns.push_back(j);
    const auto m = static_cast<Eigen::Index>(columns.size());
    gathered_storage.resize(leading * m);
    Eigen::Map<Eigen::MatrixXd, 0, Eigen::OuterStride<>> gathered(gathered_storage.data(), count, m,
                                                                  Eigen::OuterStride<>(leading));
    for (Eigen::Index i = 0; i < count; ++i)
      for (Eigen::Index k = 0; k < m; ++k) gathered(i, k) = rows_of_axis(i, columns[k]);
    update.setZero(m, m);
    update.selfadjointView<Eigen::Lower>().rankUpdate(gathered.transpose());
    const Eigen::VectorXd g = gathered.transpose() * r_of_axis;
    for (Eigen::Index k = 0; k < m; ++k) {
      out.Jtr[columns[k]] += g[k];
      for (Eigen::Index l = k; l < m; ++l) out.JtJ(columns[l], columns[k]) += update(l, k);
    }
  }
}

// All chunks on `threads` threads, summed in chunk order.
bool pass(const BlockEvaluator& f, int threads, bool with_jacobian, NormalEquations& out) {
  const std::size_t nb = f.num_blocks();
  const Eigen::Index n = f.num_params();
  const std::size_t chunks = (nb + kChunkBlocks - 1) / kChunkBlocks;
  std::vector<Partial> parts(chunks);
  std::atomic<std::size_t> next{0};
  const auto work = [&] {
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> J(
        with_jacobian ? static_cast<Eigen::Index>(6 * kChunkBlocks) : 0, n);
    Eigen::VectorXd r(static_cast<Eigen::Index>(6 * kChunkBlocks));
    const std::unique_ptr<BlockWalk> walk = f.walk();
    for (std::size_t c = next++; c < chunks; c = next++)
      chunk_sums(f, c, with_jacobian, J, r, walk.get(), parts[c]);
  };
  const int extra = std::clamp(threads, 1, static_cast<int>(std::max<std::size_t>(chunks, 1))) - 1;
  std::vector<std::thread> pool;
  pool.reserve(static_cast<std::size_t>(extra));
  for (int t = 0; t < extra; ++t) pool.emplace_back(work);
  work();
  for (std::thread& t : pool) t.join();
  out.cost = 0.0;
  if (with_jacobian) {
    out.JtJ.setZero(n, n);
    out.Jtr.setZero(n);
  }
  bool ok = true;
  for (const Partial& p : parts) {  // chunk order: the same sums for any thread count
    ok = ok && p.ok;
    out.cost += p.cost;
    if (!with_jacobian) continue;
    out.JtJ.triangularView<Eigen::Lower>() += p.JtJ;
    out.Jtr += p.Jtr;
  }
  if (with_jacobian) out.JtJ = out.JtJ.selfadjointView<Eigen::Lower>();
  return ok && std::isfinite(out.cost);
}

}  // namespace

bool accumulate(const BlockEvaluator& f, int threads, NormalEquations& out) {
  return pass(f, threads, true, out);
}

SolveSummary solve(BlockEvaluator& f, Eigen::VectorXd& x, const SolveOptions& o) {
  // Ceres' defaults for the trust region (solver.h) and the LM strategy
  // (levenberg_marquardt_strategy.cc), as fit.cpp's Ceres path runs them.
  constexpr double kInitialRadius = 1e4, kMaxRadius = 1e16, kMinRadius = 1e-32;
  constexpr double kMinDiagonal = 1e-6, kMaxDiagonal = 1e32, kMinRelativeDecrease = 1e-3;
  constexpr int kMaxInvalidSteps = 5;
  SolveSummary s;
  NormalEquations& cur = s.at_solution;
  f.set_point(x);
  if (!pass(f, o.threads, true, cur)) {
    s.message = "the residuals or their derivatives are not finite at the start values";
    return s;
  }
  s.iterations = 1;
  const auto finish = [&](bool converged, const std::string& why) {
    s.converged = converged;
    s.usable = true;
    s.message = why;
    return s;
  };
  if (cur.Jtr.lpNorm<Eigen::Infinity>() <= o.gradient_tolerance)
    return finish(true, "Gradient tolerance reached");
  // Jacobi scaling of the columns, fixed at the first iteration (as Ceres).
  const Eigen::VectorXd scale = (1.0 + cur.JtJ.diagonal().array().sqrt()).inverse().matrix();
  double radius = kInitialRadius, decrease_factor = 2.0;
  bool reuse_diagonal = false;
  int invalid_steps = 0;
  Eigen::VectorXd diagonal;
  NormalEquations candidate;
  for (int iteration = 1;; ++iteration) {
    if (iteration > o.max_iterations) return finish(false, "Maximum number of iterations reached");
    if (radius < kMinRadius) return finish(true, "Minimum trust region radius reached");
    ++s.iterations;
    // Step in the scaled variables: (S H S + D²) y = S g, step = −S y, D² = diag / radius.
    const Eigen::MatrixXd H = scale.asDiagonal() * cur.JtJ * scale.asDiagonal();
    const Eigen::VectorXd g = scale.cwiseProduct(cur.Jtr);
    if (!reuse_diagonal) diagonal = H.diagonal().cwiseMax(kMinDiagonal).cwiseMin(kMaxDiagonal);
    Eigen::MatrixXd lhs = H;
    lhs.diagonal() += diagonal / radius;
    const Eigen::LLT<Eigen::MatrixXd> llt(lhs);
    Eigen::VectorXd step;
    double model_decrease = 0.0;
    bool valid = llt.info() == Eigen::Success;
    if (valid) {
      step = -llt.solve(g);
      model_decrease = -(step.dot(g) + 0.5 * step.dot(H * step));
      valid = step.allFinite() && model_decrease > 0.0;
    }
    if (!valid) {
      if (++invalid_steps > kMaxInvalidSteps) {
        s.usable = false;
        s.message = "the linear solver failed repeatedly (invalid steps)";
        return s;
      }
      radius /= decrease_factor;
      decrease_factor *= 2.0;
      reuse_diagonal = true;
      continue;
    }
    invalid_steps = 0;
    const Eigen::VectorXd delta = scale.cwiseProduct(step);
    const Eigen::VectorXd x_candidate = x + delta;
    // The candidate's cost first (a cheaper pass: no derivatives), as Ceres does.
    f.set_point(x_candidate);
    const bool evaluated = pass(f, o.threads, false, candidate);
    const double candidate_cost =
        evaluated ? candidate.cost : std::numeric_limits<double>::infinity();
    if (o.progress) {
      std::ostringstream os;
      os << "  iteration " << s.iterations - 1 << "  cost " << candidate_cost << "  step "
         << delta.norm();
      o.progress(os.str());
    }
    if (delta.norm() <= o.parameter_tolerance * (x.norm() + o.parameter_tolerance))
      return finish(true, "Parameter tolerance reached");
    const double cost_change = cur.cost - candidate_cost;
    if (std::abs(cost_change) <= o.function_tolerance * cur.cost)
      return finish(true, "Function tolerance reached");
    const double relative_decrease = cost_change / model_decrease;
    if (relative_decrease > kMinRelativeDecrease) {
      NormalEquations next;
      if (!pass(f, o.threads, true, next)) {
        s.usable = false;
        s.message = "the derivatives are not finite at an accepted step";
        return s;
      }
      x = x_candidate;
      cur = std::move(next);
      const double t = 2.0 * relative_decrease - 1.0;
      radius = std::min(kMaxRadius, radius / std::max(1.0 / 3.0, 1.0 - t * t * t));
      decrease_factor = 2.0;
      reuse_diagonal = false;
      if (cur.Jtr.lpNorm<Eigen::Infinity>() <= o.gradient_tolerance)
        return finish(true, "Gradient tolerance reached");
    } else {
      radius /= decrease_factor;
      decrease_factor *= 2.0;
      reuse_diagonal = true;
    }
  }
}

}  // namespace zerog::ident::normal
