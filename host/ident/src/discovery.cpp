// Discovery of a law in the signal dictionary (proto/user_effects.md, "Discovery"): when no
// library effect explains the residual, the terms basis × axis that it follows beyond what the
// model can absorb, chosen by orthogonal matching pursuit and validated on the held-out blocks.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <optional>

#include <Eigen/Dense>

#include "diagnose_internal.hpp"
#include "growing_fit.hpp"
#include "parallel.hpp"
#include "screening.hpp"
#include "zerog/io/effect_file.hpp"

namespace zerog::ident::diagnosis {
namespace {

using model::Effect;

// Blocks of `m` consecutive samples inside the mask (as the fit forms them).
std::vector<std::pair<std::size_t, std::size_t>> mask_blocks(const std::vector<std::uint8_t>& mask,
                                                             std::size_t m) {
  std::vector<std::pair<std::size_t, std::size_t>> out;
  std::size_t run = 0;
  for (std::size_t i = 0; i <= mask.size(); ++i) {
    if (i < mask.size() && mask[i]) {
      ++run;
      continue;
    }
    for (std::size_t b = i - run; b + m <= i; b += m) out.emplace_back(b, m);
    run = 0;
  }
  return out;
}

// One factor of a basis, tabulated over the samples.
struct FactorColumn {
  model::Factor factor;
  // Left uninitialised until dictionary_factors writes every sample: zeroing 74 columns of a
  // long log first cost a serial third of the tabulation (issue 16); written on the workers,
  // its pages are touched there.
  std::unique_ptr<double[]> v;
};

// The discovery dictionary's factors: every base signal the log has (its value), sin and cos of
// the joint angles, and tanh(x/eps) of the velocities (eps: 0.02 rad/s, 0.005 m/s).
std::vector<FactorColumn> dictionary_factors(const Dataset& data, int threads) {
  const std::size_t n = data.size();
  const unsigned have = available_sources(data);
  std::vector<FactorColumn> out;
  auto add = [&](model::Signal s, model::FactorOp op, double eps) {
    out.push_back({{s, op, eps}, std::make_unique_for_overwrite<double[]>(n)});
  };
  for (int k = 0; k < model::kSignalCount; ++k) {
    const auto s = static_cast<model::Signal>(k);
    const model::SignalInfo& si = model::signal_info(s);
    if (!(have >> static_cast<unsigned>(si.source) & 1u)) continue;
    if (si.angle) {
      add(s, model::FactorOp::sin, 0.0);
      add(s, model::FactorOp::cos, 0.0);
      continue;
    }
    add(s, model::FactorOp::value, 0.0);
    if (si.velocity)
      add(s, model::FactorOp::tanh, std::string_view(si.unit) == "m/s" ? 0.005 : 0.02);
  }
  // A batch of samples' signals at a time, then every factor's values on them (each sample on
  // its own: the same values on any thread). The batch's signals stay in cache while every
  // factor reads its own signal from them: a whole chunk's (8192 samples) did not, and each
  // factor's pass went to memory (issue 16).
  constexpr std::size_t kBatch = 256;
  for_each_sample_chunk(data, threads, [&](std::size_t i0, std::size_t i1) {
    std::vector<model::DictionarySignals> sig(std::min(kBatch, i1 - i0));
    for (std::size_t b0 = i0; b0 < i1; b0 += kBatch) {
      const std::size_t b1 = std::min(i1, b0 + kBatch);
      for (std::size_t i = b0; i < b1; ++i) sig[i - b0] = data.dictionary(i);
      for (FactorColumn& c : out) {
        model::Basis b;
        b.a = c.factor;
        for (std::size_t i = b0; i < b1; ++i) c.v[i] = model::basis_value(b, sig[i - b0]);
      }
    }
  });
  return out;
}

// The first rank() columns of Q of a column-pivoted QR (never the full square Q).
Eigen::MatrixXd thin_q(const Eigen::ColPivHouseholderQR<Eigen::MatrixXd>& qr, Eigen::Index rows) {
  return qr.householderQ() * Eigen::MatrixXd::Identity(rows, qr.rank());
}

// z such that P(|N(0,1)| > z) = p.
double normal_two_sided_quantile(double p) {
  double lo = 0.0, hi = 40.0;
  for (int it = 0; it < 200; ++it) {
    const double mid = 0.5 * (lo + hi);
    (std::erfc(mid / std::sqrt(2.0)) > p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

struct Column {
  model::Basis basis;
  int axis = 0;
  std::vector<double> train, held;  // whitened block means on `axis` (other axes are zero)
  double score = 0.0;
};

// Discovery's phases (discover_law below runs them in order), each from typed inputs to a typed
// output: the blocks and the residual, the model's tangent space, the rows every basis is
// projected on, every basis's projections, the shortlist per axis and its columns, the pursuit,
// the law's fit.

// Blocks of samples: (first sample, samples).
using Blocks = std::vector<std::pair<std::size_t, std::size_t>>;

// The blocks discovery works on and the baseline's residual on them.
struct DiscoveryBlocks {
  std::size_t m = 1;  // samples per block
  Blocks train, held;
  std::vector<double> r_train, r_held;  // whitened block-mean residuals, r[b * 6 + k]
};

// Whitened block-mean residuals of the baseline, per axis: r[b * 6 + k].
std::vector<double> residual_means(const Baseline& base, const Blocks& blocks) {
  const std::array<double, 6>& sigma = base.fit.sigma;  // block-mean whitening of the fit
  std::vector<double> r(blocks.size() * 6, 0.0);
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    for (std::size_t i = blocks[b].first; i < blocks[b].first + blocks[b].second; ++i)
      for (int k = 0; k < 6; ++k) r[b * 6 + k] += base.res[i][k];
    for (int k = 0; k < 6; ++k) r[b * 6 + k] /= static_cast<double>(blocks[b].second) * sigma[k];
  }
  return r;
}

// The blocks as the fit forms them (o.fit.block_samples each); none if too few to search on.
std::optional<DiscoveryBlocks> discovery_blocks(const Baseline& base, const Split& split,
                                                const DiagnoseOptions& o) {
  DiscoveryBlocks out;
  out.m = static_cast<std::size_t>(std::max(1, o.fit.block_samples));
  out.train = mask_blocks(split.train, out.m);
  out.held = mask_blocks(split.heldout, out.m);
  if (out.train.size() < 20 || out.held.size() < 5) return std::nullopt;
  out.r_train = residual_means(base, out.train);
  out.r_held = residual_means(base, out.held);
  return out;
}

// The baseline's free parameters in `p` (the effects in library order without the frozen ones,
// then the user terms): the columns of its tangent space.
std::vector<double*> free_parameters(model::ModelParams& p, const DiagnoseOptions& o) {
  std::vector<double*> params;
  for (Effect e : model::kAllEffects) {
    if (!p.effects.has(e) || o.fit.frozen.has(e)) continue;
    for (int i = 0; i < model::info(e).num_params; ++i) params.push_back(p.block(e) + i);
  }
  for (int j = 0; j < p.user.num_terms; ++j)
    params.push_back(&p.user.coeff[static_cast<std::size_t>(j)]);
  return params;
}

// The whitened block-mean Jacobian of the prediction of `p` with respect to `params` (pointers
// into `p`, left as they were) by central differences: the fallback of analytic_jacobian.
Eigen::MatrixXd central_jacobian(const Dataset& data, model::ModelParams& p,
                                 const std::vector<double*>& params, const Blocks& blocks,
                                 const std::array<double, 6>& sigma) {
  const std::size_t np = params.size();
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(blocks.size() * 6),
                                            static_cast<Eigen::Index>(np));
  for (std::size_t q = 0; q < np; ++q) {
    const double x0 = *params[q];
    const double h = 1e-6 * std::max(1.0, std::abs(x0));
    for (int side = 0; side < 2; ++side) {
      *params[q] = x0 + (side == 0 ? h : -h);
      ResidentWindow window(data);
      for (std::size_t b = 0; b < blocks.size(); ++b) {
        window.advance(blocks[b].first + blocks[b].second);
        Wrench mean = Wrench::Zero();
        for (std::size_t i = blocks[b].first; i < blocks[b].first + blocks[b].second; ++i)
          mean += predict(p, data, i);
        mean /= static_cast<double>(blocks[b].second);
        for (int k = 0; k < 6; ++k)
          J(static_cast<Eigen::Index>(b * 6 + k), static_cast<Eigen::Index>(q)) +=
              (side == 0 ? 1.0 : -1.0) * mean[k] / (2.0 * h * sigma[k]);
      }
    }
    *params[q] = x0;
  }
  return J;
}

// The same Jacobian from the fit's own block evaluation: analytic derivatives of the block
// means, one pass over the blocks instead of two model evaluations per parameter, which made a
// quarter of discovery's time (issue 16). Its columns are packed as free_parameters' (`np` of
// them) and its blocks are mask_blocks' (tests/integration/diagnose_screening_test.cpp,
// TrainingProblem); the residual's derivative is the negated prediction's. Where the packing or
// the blocks differ (rows without time: the fit's blocks are single rows) or the evaluation
// fails, none: the central differences stand in.
std::optional<Eigen::MatrixXd> analytic_jacobian(const Dataset& data, const Baseline& base,
                                                 const DiagnoseOptions& o,
                                                 const std::vector<std::uint8_t>& mask,
                                                 const Blocks& blocks, std::size_t np) {
  FitOptions fo = o.fit;
  fo.effects = base.fit.params.effects;
  fo.user = base.fit.params.user;
  fo.mask = &mask;
  fo.sigma = base.fit.sigma;
  fo.initial = nullptr;
  try {
    const screening::TrainingProblem problem(data, fo, base.fit.params);
    if (problem.num_params() != static_cast<int>(np) || problem.num_blocks() != blocks.size())
      return std::nullopt;
    Eigen::MatrixXd J(static_cast<Eigen::Index>(blocks.size() * 6), static_cast<Eigen::Index>(np));
    // Each block's rows on their own (the evaluation is concurrent: normal_equations.hpp).
    constexpr std::size_t kBlocksPerTask = 512;
    std::atomic<bool> ok{true};
    parallel::for_each((blocks.size() + kBlocksPerTask - 1) / kBlocksPerTask, o.fit.threads,
                       [&](std::size_t task, int) {
                         Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::RowMajor> jb(
                             6, static_cast<Eigen::Index>(np));
                         std::array<double, 6> r{};
                         const std::size_t b0 = task * kBlocksPerTask;
                         const std::size_t b1 = std::min(blocks.size(), b0 + kBlocksPerTask);
                         for (std::size_t b = b0; b < b1 && ok; ++b) {
                           if (!problem.evaluate(b, r.data(), jb.data())) ok = false;
                           J.middleRows(static_cast<Eigen::Index>(b * 6), 6) = -jb;
                         }
                       });
    if (!ok) return std::nullopt;
    return J;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

// The baseline's tangent space on the training and on the held-out blocks: the whitened
// block-mean Jacobian of its free parameters, so that a term the model can already absorb (a
// constant, a change of mass) scores nothing.
struct TangentSpace {
  Eigen::MatrixXd train, held;  // (blocks × 6) × free parameters
};

TangentSpace tangent_space(const Dataset& data, const Baseline& base, const Split& split,
                           const DiagnoseOptions& o, const DiscoveryBlocks& blocks) {
  model::ModelParams p = base.fit.params;
  const std::vector<double*> params = free_parameters(p, o);
  const std::size_t np = params.size();
  // The training and the held-out blocks' problems are set up side by side (each on its own).
  std::optional<Eigen::MatrixXd> J_train_a, J_held_a;
  parallel::for_each(2, o.fit.threads, [&](std::size_t side, int) {
    if (side == 0)
      J_train_a = analytic_jacobian(data, base, o, split.train, blocks.train, np);
    else
      J_held_a = analytic_jacobian(data, base, o, split.heldout, blocks.held, np);
  });
  if (!J_train_a) J_held_a.reset();
  TangentSpace t;
  t.train = J_held_a ? std::move(*J_train_a)
                     : central_jacobian(data, p, params, blocks.train, base.fit.sigma);
  t.held = J_held_a ? std::move(*J_held_a)
                    : central_jacobian(data, p, params, blocks.held, base.fit.sigma);
  return t;
}

// An orthonormal basis of the training tangent space (column-pivoted QR drops dependent ones).
struct TangentBasis {
  explicit TangentBasis(const Eigen::MatrixXd& J)
      : qr(J), rank(qr.rank()), Q(thin_q(qr, J.rows())) {}
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr;
  Eigen::Index rank;
  Eigen::MatrixXd Q;  // the first `rank` columns of Q
};

// The rows every basis's training block means are projected on, by one matrix product per batch
// of bases: one matrix-vector product per basis and axis dominated discovery (issue 16).
// |Q_kᵀ c|² = Σ_j ((Q_k v_j)ᵀ c)² over the eigenvectors v_j of Q_kᵀ Q_k (Q_k: the tangent basis's
// rows of axis k), and an axis's slice of the tangent space has far fewer directions than the
// model has parameters (a force axis sees only its bias and the mass), so only the directions
// with weight (λ_j above 1e-14 of the largest: what is dropped is far below the 1e-9 cut on the
// remaining part in shortlist) become rows. Rows: each axis's directions, then r_0ᵀ … r_5ᵀ.
struct ProjectionRows {
  std::array<Eigen::Index, 7> row0{};  // axis k's directions: rows row0[k] to row0[k + 1]
  Eigen::Index nq = 0;                 // rows of directions; axis k's residual is row nq + k
  Eigen::MatrixXd M;                   // (nq + 6) × training blocks
};

ProjectionRows projection_rows(const TangentBasis& basis, const std::vector<double>& r_train,
                               std::size_t nt) {
  const Eigen::Index rank = basis.rank;
  // The basis's rows per axis, contiguous: Qk[k] is nt × rank.
  std::array<Eigen::MatrixXd, 6> Qk;
  std::array<Eigen::VectorXd, 6> rk;
  for (int k = 0; k < 6; ++k) {
    Qk[static_cast<std::size_t>(k)].resize(static_cast<Eigen::Index>(nt), rank);
    rk[static_cast<std::size_t>(k)].resize(static_cast<Eigen::Index>(nt));
    for (std::size_t t = 0; t < nt; ++t) {
      Qk[static_cast<std::size_t>(k)].row(static_cast<Eigen::Index>(t)) =
          basis.Q.row(static_cast<Eigen::Index>(t * 6 + k));
      rk[static_cast<std::size_t>(k)][static_cast<Eigen::Index>(t)] = r_train[t * 6 + k];
    }
  }
  ProjectionRows rows;
  std::array<Eigen::MatrixXd, 6> dirs;
  for (int k = 0; k < 6; ++k) {
    const Eigen::MatrixXd& q = Qk[static_cast<std::size_t>(k)];
    Eigen::MatrixXd& out = dirs[static_cast<std::size_t>(k)];
    if (rank == 0) {
      out.resize(0, static_cast<Eigen::Index>(nt));
    } else {
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(q.transpose() * q);
      const Eigen::VectorXd& l = eig.eigenvalues();  // ascending
      const double cut = 1e-14 * std::max(l.maxCoeff(), 0.0);
      Eigen::Index first = 0;
      while (first < l.size() && !(l[first] > cut)) ++first;
      out = (q * eig.eigenvectors().rightCols(l.size() - first)).transpose();
    }
    rows.row0[static_cast<std::size_t>(k) + 1] =
        rows.row0[static_cast<std::size_t>(k)] + out.rows();
  }
  rows.nq = rows.row0[6];
  rows.M.resize(rows.nq + 6, static_cast<Eigen::Index>(nt));
  for (int k = 0; k < 6; ++k) {
    const auto ks = static_cast<std::size_t>(k);
    rows.M.middleRows(rows.row0[ks], dirs[ks].rows()) = dirs[ks];
    rows.M.row(rows.nq + k) = rk[ks].transpose();
  }
  return rows;
}

// Every basis (a factor, or the product of two) and its projections on the projection rows:
// P = M C over the training blocks (C: each basis's block means, a column per basis), and
// c2 = |c|² per basis.
struct BasisProducts {
  std::vector<std::pair<std::size_t, std::size_t>> bases;  // (a, b); b == nf: factor a alone
  Eigen::MatrixXd P;                                       // (nq + 6) × bases
  Eigen::VectorXd c2;                                      // bases
};

// Training blocks per chunk of basis_products.
constexpr std::size_t kProductChunk = 128;

// A worker's scratch of basis_products: a chunk's block means of every basis, and the chunk's
// samples of every factor, [(factor * m + sample) * kProductChunk + block].
struct ChunkScratch {
  Eigen::MatrixXd C;
  std::vector<double> local;
};

// Every basis's block means over the training blocks t0 … t0 + nb − 1 into w.C's first nb rows.
// The chunk's samples of every factor are copied together first (sample i of every block side
// by side), so that all bases read them from cache rather than streaming two whole factor
// columns each. Each block's sum still runs in sample order from zero (as a sum over a product
// column would), and the sums of neighbouring blocks are independent.
void chunk_means(const std::vector<FactorColumn>& factors, const Blocks& train, std::size_t m,
                 const std::vector<std::pair<std::size_t, std::size_t>>& bases, std::size_t t0,
                 std::size_t nb, ChunkScratch& w) {
  const std::size_t nf = factors.size();
  std::vector<double>& local = w.local;
  for (std::size_t f = 0; f < nf; ++f)
    for (std::size_t i = 0; i < m; ++i)
      for (std::size_t t = 0; t < nb; ++t)
        local[(f * m + i) * kProductChunk + t] = factors[f].v[train[t0 + t].first + i];
  for (Eigen::Index j = 0; j < w.C.cols(); ++j) {
    const auto [a, b] = bases[static_cast<std::size_t>(j)];
    double* out = w.C.col(j).data();
    std::fill(out, out + nb, 0.0);
    for (std::size_t i = 0; i < m; ++i) {
      const double* xa = &local[(a * m + i) * kProductChunk];
      if (b < nf) {
        const double* xb = &local[(b * m + i) * kProductChunk];
        for (std::size_t t = 0; t < nb; ++t) out[t] += xa[t] * xb[t];
      } else {
        for (std::size_t t = 0; t < nb; ++t) out[t] += xa[t];
      }
    }
    for (std::size_t t = 0; t < nb; ++t) out[t] /= static_cast<double>(m);
  }
}

// The chunks run on the fit's threads (parallel.hpp): each forms its block means and its
// products into its worker's scratch, and they are added into P and c2 in chunk order, so the
// sums are those of one thread, chunk after chunk.
BasisProducts basis_products(const std::vector<FactorColumn>& factors,
                             const DiscoveryBlocks& blocks, const ProjectionRows& rows,
                             int threads) {
  const std::size_t nf = factors.size(), nt = blocks.train.size(), m = blocks.m;
  BasisProducts out;
  for (std::size_t a = 0; a < nf; ++a)
    for (std::size_t b = a; b <= nf; ++b) out.bases.emplace_back(a, b);
  const auto nbases = static_cast<Eigen::Index>(out.bases.size());
  out.P = Eigen::MatrixXd::Zero(rows.nq + 6, nbases);
  out.c2 = Eigen::VectorXd::Zero(nbases);
  struct ChunkResult {
    Eigen::MatrixXd P;
    Eigen::VectorXd c2;
  };
  const std::size_t chunks = (nt + kProductChunk - 1) / kProductChunk;
  std::vector<ChunkScratch> scratch(static_cast<std::size_t>(parallel::workers(chunks, threads)));
  for (ChunkScratch& w : scratch) {
    w.C.resize(static_cast<Eigen::Index>(kProductChunk), nbases);
    w.local.resize(nf * m * kProductChunk);
  }
  constexpr std::size_t kWindow = 8;
  std::vector<ChunkResult> results(kWindow);
  const auto chunk_products = [&](std::size_t chunk, int worker, std::size_t slot) {
    ChunkScratch& w = scratch[static_cast<std::size_t>(worker)];
    ChunkResult& result = results[slot];
    const std::size_t t0 = chunk * kProductChunk;
    const std::size_t nb = std::min(kProductChunk, nt - t0);
    chunk_means(factors, blocks.train, m, out.bases, t0, nb, w);
    const auto n = static_cast<Eigen::Index>(nb);
    result.P.noalias() = rows.M.middleCols(static_cast<Eigen::Index>(t0), n) * w.C.topRows(n);
    result.c2 = w.C.topRows(n).colwise().squaredNorm().transpose();
  };
  parallel::ordered(chunks, threads, kWindow, chunk_products, [&](std::size_t, std::size_t slot) {
    out.P += results[slot].P;
    out.c2 += results[slot].c2;
  });
  return out;
}

// The best few bases per axis (score, basis), in the order the bases were searched.
struct Shortlist {
  std::array<std::vector<std::pair<double, Eigen::Index>>, 6> top;
  int searched = 0;  // basis-axis columns searched
};

// Every basis on every axis scored by the training sum of squares it would remove alone after
// the model's own parameters (its squared partial correlation with the residual); the best
// kKeepPerAxis per axis go on.
Shortlist shortlist(const BasisProducts& products, const ProjectionRows& rows,
                    const std::array<double, 6>& sigma) {
  constexpr int kKeepPerAxis = 10;
  const Eigen::MatrixXd& P = products.P;
  const Eigen::Index nq = rows.nq;
  Shortlist out;
  for (Eigen::Index j = 0; j < P.cols(); ++j) {
    for (int k = 0; k < 6; ++k) {
      ++out.searched;
      const auto ks = static_cast<std::size_t>(k);
      const double w = 1.0 / sigma[k];
      const double rc = w * P(nq + k, j), cc = w * w * products.c2[j];
      const double qq =
          w * w * P.col(j).segment(rows.row0[ks], rows.row0[ks + 1] - rows.row0[ks]).squaredNorm();
      const double perp = cc - qq;
      if (!(perp > 1e-9 * std::max(cc, 1e-300))) continue;
      const double score = rc * rc / perp;
      auto& list = out.top[ks];
      if (static_cast<int>(list.size()) == kKeepPerAxis && score <= list.back().first) continue;
      list.emplace_back(score, j);
      std::sort(list.begin(), list.end(),
                [](const auto& x, const auto& y) { return x.first > y.first; });
      if (static_cast<int>(list.size()) > kKeepPerAxis) list.pop_back();
    }
  }
  return out;
}

// A basis's block means, the product fused in (no per-sample column is formed). Blocks hold
// `m` samples each; the sums run over the blocks side by side, each block's in sample order as
// before, so that consecutive additions are independent (a single running sum per block is
// bound by the latency of the addition).
void basis_means(const std::vector<FactorColumn>& factors, std::size_t a, std::size_t b,
                 const Blocks& blocks, std::size_t m, double* out) {
  const std::size_t nf = factors.size();
  const double* fa = factors[a].v.get();
  const double* fb = b < nf ? factors[b].v.get() : nullptr;
  constexpr std::size_t kChunk = 256;  // blocks per pass: their samples stay in cache
  for (std::size_t t0 = 0; t0 < blocks.size(); t0 += kChunk) {
    const std::size_t t1 = std::min(blocks.size(), t0 + kChunk);
    for (std::size_t t = t0; t < t1; ++t) out[t] = 0.0;
    for (std::size_t i = 0; i < m; ++i) {
      if (fb) {
        for (std::size_t t = t0; t < t1; ++t)
          out[t] += fa[blocks[t].first + i] * fb[blocks[t].first + i];
      } else {
        for (std::size_t t = t0; t < t1; ++t) out[t] += fa[blocks[t].first + i];
      }
    }
    for (std::size_t t = t0; t < t1; ++t) out[t] /= static_cast<double>(m);
  }
}

// The shortlisted columns, axis by axis: only these get their block means.
std::vector<Column> shortlisted_columns(const Shortlist& list, const BasisProducts& products,
                                        const std::vector<FactorColumn>& factors,
                                        const DiscoveryBlocks& blocks,
                                        const std::array<double, 6>& sigma) {
  const std::size_t nf = factors.size(), nt = blocks.train.size(), nh = blocks.held.size();
  std::vector<Column> cand;
  std::vector<double> mt(nt), mh(nh);
  for (int k = 0; k < 6; ++k) {
    for (const auto& [score, j] : list.top[static_cast<std::size_t>(k)]) {
      const auto [a, b] = products.bases[static_cast<std::size_t>(j)];
      Column col;
      col.basis.a = factors[a].factor;
      if (b < nf) {
        // A product of two; the same angle's sin·cos and a velocity's tanh·value repeat simpler
        // shapes, but are kept: the search decides.
        col.basis.b = factors[b].factor;
        col.basis.product = true;
      }
      col.axis = k;
      col.score = score;
      basis_means(factors, a, b, blocks.train, blocks.m, mt.data());
      basis_means(factors, a, b, blocks.held, blocks.m, mh.data());
      col.train.resize(nt);
      for (std::size_t t = 0; t < nt; ++t) col.train[t] = mt[t] / sigma[k];
      col.held.resize(nh);
      for (std::size_t t = 0; t < nh; ++t) col.held[t] = mh[t] / sigma[k];
      cand.push_back(std::move(col));
    }
  }
  return cand;
}

// Candidates per task of the pursuit's passes on the fit's threads (parallel.hpp): each
// candidate's data and statistic are its own, and the best is taken in candidate order, so the
// results do not depend on the thread count.
constexpr Eigen::Index kColumnsPerTask = 8;

std::size_t column_tasks(Eigen::Index columns) {
  return static_cast<std::size_t>((columns + kColumnsPerTask - 1) / kColumnsPerTask);
}

// Every candidate projected out of the tangent space into the growing fit, by one matrix
// product per few (a column is nonzero on one axis only, so Qᵀ x reads that axis's rows of Q),
// and each candidate's |x|² into x2.
void start_candidates(GrowingFit& gf, std::vector<double>& x2, const std::vector<Column>& cand,
                      const TangentBasis& basis, std::size_t nt, int threads) {
  const Eigen::MatrixXd& Q = basis.Q;
  const Eigen::Index rank = basis.rank;
  const auto ncand = static_cast<Eigen::Index>(cand.size());
  parallel::for_each(column_tasks(ncand), threads, [&](std::size_t task, int) {
    const Eigen::Index j0 = static_cast<Eigen::Index>(task) * kColumnsPerTask;
    const Eigen::Index nj = std::min(kColumnsPerTask, ncand - j0);
    Eigen::MatrixXd G(rank, nj);
    for (Eigen::Index j = 0; j < nj; ++j) {
      const Column& c = cand[static_cast<std::size_t>(j0 + j)];
      const Eigen::Map<const Eigen::MatrixXd, 0, Eigen::Stride<Eigen::Dynamic, 6>> rows(
          Q.data() + c.axis, static_cast<Eigen::Index>(nt), rank,
          Eigen::Stride<Eigen::Dynamic, 6>(Q.outerStride(), 6));
      G.col(j).noalias() = rows.transpose() * Eigen::Map<const Eigen::VectorXd>(
                                                  c.train.data(), static_cast<Eigen::Index>(nt));
    }
    gf.projections().middleCols(j0, nj).noalias() = -Q * G;
    gf.coefficients().block(0, j0, rank, nj) = G;
    for (Eigen::Index j = 0; j < nj; ++j) {
      const Column& c = cand[static_cast<std::size_t>(j0 + j)];
      double& xx = x2[static_cast<std::size_t>(j0 + j)];
      for (std::size_t t = 0; t < nt; ++t) {
        gf.projections()(static_cast<Eigen::Index>(t * 6) + c.axis, j0 + j) += c.train[t];
        xx += c.train[t] * c.train[t];
      }
    }
  });
}

// The statistic of each open candidate (zero where its projection is negligible): the
// heteroscedasticity-robust statistic of its coefficient (White's sandwich, HC0, on the residual
// with the column in the fit): moving blocks carry more noise (IMU noise × mass) than dwells.
std::vector<double> candidate_statistics(GrowingFit& gf, const std::vector<std::size_t>& open,
                                         const std::vector<double>& x2, int threads) {
  const Eigen::Index nopen = static_cast<Eigen::Index>(open.size());
  const Eigen::VectorXd& r_cur = gf.residual();
  std::vector<double> zs(open.size(), 0.0);
  parallel::for_each(column_tasks(nopen), threads, [&](std::size_t task, int) {
    const Eigen::Index j0 = static_cast<Eigen::Index>(task) * kColumnsPerTask;
    const Eigen::Index nj = std::min(kColumnsPerTask, nopen - j0);
    for (Eigen::Index j = j0; j < j0 + nj; ++j) {
      const std::size_t c = open[static_cast<std::size_t>(j)];
      gf.refresh(static_cast<Eigen::Index>(c));
      const auto xp = gf.projections().col(static_cast<Eigen::Index>(c));
      const double xx = xp.squaredNorm();
      if (!(xx > 1e-9 * x2[c])) continue;
      const double num = xp.dot(r_cur);
      const double var =
          (xp.array().square() * (r_cur.array() - (num / xx) * xp.array()).square()).sum();
      zs[static_cast<std::size_t>(j)] = var > 0 ? std::abs(num) / std::sqrt(var) : 0.0;
    }
  });
  return zs;
}

// The held-out prediction of the linearised refit on trial (the accepted columns `chosen`, then
// `best`). The tangent space's dependent columns (beyond its pivoted QR's rank) get no
// coefficient.
Eigen::VectorXd trial_held_prediction(const GrowingFit::Trial& trial, const TangentBasis& basis,
                                      const Eigen::MatrixXd& J_held,
                                      const std::vector<Column>& cand,
                                      const std::vector<std::size_t>& chosen, std::size_t best,
                                      std::size_t nh) {
  const Eigen::Index rank = basis.rank;
  Eigen::VectorXd theta_j = Eigen::VectorXd::Zero(J_held.cols());
  for (Eigen::Index i = 0; i < rank; ++i)
    theta_j[basis.qr.colsPermutation().indices()[i]] = trial.theta[i];
  Eigen::VectorXd pred_held = J_held * theta_j;
  for (std::size_t i = 0; i <= chosen.size(); ++i) {
    const Column& c = cand[i < chosen.size() ? chosen[i] : best];
    const double w = trial.theta[rank + static_cast<Eigen::Index>(i)];
    for (std::size_t t = 0; t < nh; ++t)
      pred_held[static_cast<Eigen::Index>(t * 6) + c.axis] += w * c.held[t];
  }
  return pred_held;
}

// The terms the pursuit accepted (indices into the candidates) and their statistics.
struct Pursuit {
  std::vector<std::size_t> chosen;
  std::vector<double> z;
};

// Orthogonal matching pursuit over the shortlisted columns, in the full whitened space (all six
// axes), with the model's tangent space always in the regression. Each step takes the candidate
// of the largest statistic if it is above `z_threshold` and the linearised refit with it lowers
// the held-out error by at least o.min_term_gain of the baseline's.
Pursuit pursue(const std::vector<Column>& cand, const DiscoveryBlocks& blocks,
               const TangentBasis& basis, const Eigen::MatrixXd& J_held, double z_threshold,
               const DiagnoseOptions& o) {
  const std::size_t nt = blocks.train.size(), nh = blocks.held.size();
  const Eigen::Index Nt = static_cast<Eigen::Index>(nt * 6), Nh = static_cast<Eigen::Index>(nh * 6);
  const Eigen::Map<const Eigen::VectorXd> rt(blocks.r_train.data(), Nt),
      rh(blocks.r_held.data(), Nh);
  const double held_base = rh.squaredNorm();
  double held_prev = held_base;
  // The current fit's columns on training, [J_sel, X] (J_sel: the tangent space's independent
  // columns, in its pivoted QR's order; X: the accepted terms), and every candidate with it
  // projected out, grown column by column (growing_fit.hpp): a fresh QR of [J, X] per step, its
  // thin Q, a second one for the held-out check and every candidate's projection on all of it
  // made half of the search (issue 16).
  GrowingFit gf(basis.qr, basis.Q, rt, o.max_discovered_terms,
                static_cast<Eigen::Index>(cand.size()));
  std::vector<double> x2(cand.size(), 0.0);  // |x|² of each candidate
  start_candidates(gf, x2, cand, basis, nt, o.fit.threads);
  Pursuit out;
  std::vector<std::size_t>& chosen = out.chosen;
  for (int step = 0; step < o.max_discovered_terms; ++step) {
    std::vector<std::size_t> open;
    for (std::size_t c = 0; c < cand.size(); ++c)
      if (std::find(chosen.begin(), chosen.end(), c) == chosen.end()) open.push_back(c);
    const std::vector<double> zs = candidate_statistics(gf, open, x2, o.fit.threads);
    double best_z = 0.0;
    std::size_t best = cand.size();
    for (std::size_t j = 0; j < open.size(); ++j)
      if (zs[j] > best_z) best_z = zs[j], best = open[j];
    if (best == cand.size() || best_z < z_threshold) break;
    // Held-out check: the linearised refit with the new column must lower the held-out error.
    const GrowingFit::Trial trial = gf.trial(static_cast<Eigen::Index>(best));
    const double held_new =
        (rh - trial_held_prediction(trial, basis, J_held, cand, chosen, best, nh)).squaredNorm();
    if (held_prev - held_new < o.min_term_gain * held_base) break;
    held_prev = held_new;
    gf.accept(trial);
    chosen.push_back(best);
    out.z.push_back(best_z);
  }
  return out;
}

// The effect of the chosen terms, named "discovered", or "discovered_2", "_3", ... when the
// model already carries that name (the loop iterates: a law found on top of an earlier one).
model::UserEffects law_effect(const Baseline& base, const std::vector<Column>& cand,
                              const std::vector<std::size_t>& chosen) {
  model::UserEffects u;
  std::string name = "discovered";
  const auto taken = [&](const std::string& n) {
    for (int k = 0; k < base.fit.params.user.num_effects; ++k)
      if (io::user_effect_name(base.fit.params.user, k) == n) return true;
    return false;
  };
  for (int n = 2; taken(name); ++n) name = "discovered_" + std::to_string(n);
  u.num_effects = 1;
  std::copy(name.begin(), name.end(), u.names[0].begin());
  for (std::size_t c : chosen) {
    model::UserTerm t;
    t.basis = cand[c].basis;
    t.axis = static_cast<std::uint8_t>(cand[c].axis);
    u.terms[static_cast<std::size_t>(u.num_terms++)] = t;
  }
  return u;
}

// The law (d.effect) refitted with the whole model on the training blocks: its coefficients,
// their standard deviations and words, its held-out error and gain. False if the fit is not
// usable.
bool fit_law(const Dataset& data, const Baseline& base, const Split& split,
             const DiagnoseOptions& o, const std::array<double, 6>& scale, Discovery& d) {
  model::UserEffects& u = d.effect;
  FitOptions fo = o.fit;
  fo.effects = base.fit.params.effects;
  fo.user = base.fit.params.user;
  io::append_user_effects(fo.user, u);
  fo.mask = &split.train;
  fo.covariance = true;
  fo.initial = &base.fit.params;
  fo.progress = nullptr;
  d.fit = fit(data, fo);
  if (!d.fit.usable) return false;
  const int offset = base.fit.params.user.num_terms;
  for (int j = 0; j < u.num_terms; ++j) {
    u.coeff[static_cast<std::size_t>(j)] =
        d.fit.params.user.coeff[static_cast<std::size_t>(offset + j)];
    d.std.push_back(static_cast<std::size_t>(offset + j) < d.fit.user_std.size()
                        ? d.fit.user_std[static_cast<std::size_t>(offset + j)]
                        : std::numeric_limits<double>::quiet_NaN());
    d.laws.push_back(law_text(u, j, d.std.back()));
  }
  d.heldout = heldout_error(residuals_of(d.fit.params, data, &split.heldout, o.fit.threads),
                            split.heldout, scale);
  d.gain = 1.0 - d.heldout.whitened_mse / base.heldout.whitened_mse;
  return true;
}

// A law in the signal dictionary beyond the baseline's model, or none: the dictionary's columns
// (factor or product of two, on one axis) the residual follows beyond the model's tangent space,
// shortlisted per axis, chosen by a pursuit with a Bonferroni threshold and a held-out check,
// and refitted with the model. Gains against `scale`.
std::optional<Discovery> discover_law(const Dataset& data, const Baseline& base, const Split& split,
                                      const DiagnoseOptions& o,
                                      const std::array<double, 6>& scale) {
  const auto start = std::chrono::steady_clock::now();
  const auto since_start = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  const std::optional<DiscoveryBlocks> blocks = discovery_blocks(base, split, o);
  if (!blocks) return std::nullopt;
  const std::vector<FactorColumn> factors = dictionary_factors(data, o.fit.threads);
  const TangentSpace tangent = tangent_space(data, base, split, o, *blocks);
  const TangentBasis basis(tangent.train);
  const ProjectionRows rows = projection_rows(basis, blocks->r_train, blocks->train.size());
  const BasisProducts products = basis_products(factors, *blocks, rows, o.fit.threads);
  const Shortlist list = shortlist(products, rows, base.fit.sigma);
  const std::vector<Column> cand =
      shortlisted_columns(list, products, factors, *blocks, base.fit.sigma);

  Discovery d;
  d.dictionary_size = list.searched;
  for (const Column& c : cand) d.column_scores.push_back(c.score);
  // Bonferroni over every column searched: a noise column passes with probability 1 %.
  d.z_threshold = normal_two_sided_quantile(o.discovery_alpha / std::max(1, list.searched));
  Pursuit found = pursue(cand, *blocks, basis, tangent.held, d.z_threshold, o);
  d.z = std::move(found.z);
  d.search_seconds = since_start();
  if (found.chosen.empty()) return std::nullopt;

  d.effect = law_effect(base, cand, found.chosen);
  if (!fit_law(data, base, split, o, scale, d)) return std::nullopt;
  d.seconds = since_start();
  return d;
}

// A library effect pays on its own when it removes at least this share of the held-out error
// and the information criterion takes it; the law is then searched on top of it.
constexpr double kPaysOnItsOwn = 0.10;
// ...and it stays in the proposal only if the model with the law but without it is worse by at
// least this share of the baseline's held-out error.
constexpr double kStillNeeded = 0.02;

}  // namespace

// The law when no library effect explains the residual. If the best library candidate pays on its
// own but leaves structure (a library effect and a law outside the library hidden together), the
// law is searched on top of it: searched alone, in a residual the effect dominates, it comes out
// mangled (a cable's gravity seen as sin(q2)·tanh(qd6)) and the loop needs a turn per confusion.
// Both are proposed together if each is needed; otherwise the law on top of the model as given.
std::optional<Discovery> discover_beyond(const Dataset& data, const Baseline& base,
                                         const Split& split, const DiagnoseOptions& o,
                                         const Diagnosis& d) {
  if (!d.candidates.empty() && d.candidates[0].user < 0 && d.candidates[0].gain >= kPaysOnItsOwn &&
      d.candidates[0].delta_bic < 0) {
    const Candidate& c = d.candidates[0];
    if (o.progress)
      o.progress("diagnose: " + c.name + " pays on its own; searching the law on top of it");
    Baseline on = fit_baseline(data, c.effects, o.fit.user, split, o, &c.fit.params);
    on.heldout = heldout_error(on.res, split.heldout, d.noise_rms);
    std::optional<Discovery> x = discover_law(data, on, split, o, d.noise_rms);
    if (x && x->gain >= o.min_law_gain) {
      // Without the library effect, the law alone: is the effect still needed?
      FitOptions fo = o.fit;
      fo.effects = base.fit.params.effects;
      fo.user = base.fit.params.user;
      io::append_user_effects(fo.user, x->effect);
      fo.mask = &split.train;
      fo.covariance = false;
      fo.initial = nullptr;
      fo.progress = nullptr;
      const FitResult alone = fit(data, fo);
      const double alone_mse =
          alone.usable
              ? heldout_error(residuals_of(alone.params, data, &split.heldout, o.fit.threads),
                              split.heldout, d.noise_rms)
                    .whitened_mse
              : std::numeric_limits<double>::infinity();
      if ((alone_mse - x->heldout.whitened_mse) / base.heldout.whitened_mse >= kStillNeeded) {
        x->with_effect = c.name;
        x->with_effects = c.effects;
        x->law_gain = x->gain;
        x->gain = 1.0 - x->heldout.whitened_mse / base.heldout.whitened_mse;
        return x;
      }
    }
  }
  std::optional<Discovery> x = discover_law(data, base, split, o, d.noise_rms);
  if (!x || x->gain < o.min_law_gain) return std::nullopt;
  x->law_gain = x->gain;
  return x;
}

}  // namespace zerog::ident::diagnosis
