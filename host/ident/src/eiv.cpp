#include "zerog/ident/eiv.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <random>
#include <stdexcept>
#include <vector>

#include "zerog/io/effect_file.hpp"
#include "zerog/model/user_effects.hpp"

namespace zerog::ident {
namespace {

using model::Effect;

// Robust scale of one IMU column (row stride 9, offset `col`): MAD of the 4th differences.
double fourth_difference_scale(const Dataset& data, int col) {
  const std::size_t n = data.size();
  if (n < 5) return 0.0;
  std::vector<double> d;
  d.reserve(n - 4);
  ResidentWindow window(data);
  for (std::size_t i = 0; i + 4 < n; ++i) {
    window.advance(i + 4);
    const auto x = [&](std::size_t k) {
      return data.imu[(i + k) * 9 + static_cast<std::size_t>(col)];
    };
    d.push_back(std::abs(x(0) - 4.0 * x(1) + 6.0 * x(2) - 4.0 * x(3) + x(4)));
  }
  auto mid = d.begin() + static_cast<std::ptrdiff_t>(d.size() / 2);
  std::nth_element(d.begin(), mid, d.end());
  // σ = 1.4826 · median|d| for normal d; var(d) = 70 σ_row².
  return 1.4826 * *mid / std::sqrt(70.0);
}

// The free, identifiable parameters the correction moves: pointers into `params`, and each one's
// standard deviation in the fit (NaN if the fit computed none).
struct FreeParams {
  std::vector<double*> value;
  std::vector<double> fit_std;
  std::vector<std::string> label;
  std::vector<std::pair<int, int>> where;  // (effect index, i), or (-1, user term)
};

FreeParams free_params(const FitOptions& o, FitResult& r) {
  FreeParams f;
  for (Effect e : model::kAllEffects) {
    if (!o.effects.has(e) || o.frozen.has(e)) continue;
    for (int i = 0; i < model::info(e).num_params; ++i) {
      const double sd = r.std ? (*r.std)[model::index(e)][i] : 0.0;
      f.value.push_back(&r.params.block(e)[i]);
      f.fit_std.push_back(r.std ? sd : std::numeric_limits<double>::quiet_NaN());
      f.label.push_back(param_label(e, i));
      f.where.emplace_back(static_cast<int>(model::index(e)), i);
    }
  }
  for (int j = 0; j < r.params.user.num_terms; ++j) {
    const auto ju = static_cast<std::size_t>(j);
    const double sd = ju < r.user_std.size() ? r.user_std[ju] : 0.0;
    f.value.push_back(&r.params.user.coeff[ju]);
    f.fit_std.push_back(ju < r.user_std.size() ? sd : std::numeric_limits<double>::quiet_NaN());
    f.label.push_back(io::term_label(r.params.user, j));
    f.where.emplace_back(-1, j);
  }
  return f;
}

// Whitened block-mean predictions of one dataset (the log's signals, or perturbed ones), from
// the block statistics (BlockStats: equal to the samples to rounding, fit_engine_test).
class BlockPredictor {
 public:
  BlockPredictor(const Dataset& data, const SampleBlocks& blocks, const model::ModelParams& params,
                 const std::array<double, 6>& sigma)
      : stats_(data, blocks, params.effects), blocks_(blocks.size()) {
    for (int k = 0; k < 6; ++k) inv_sigma_[k] = 1.0 / sigma[k];
    // The user terms' block-mean design (6 × terms a block), as the fit forms it.
    const int nu = params.user.num_terms;
    if (nu == 0) return;
    user_design_.assign(blocks_ * 6 * static_cast<std::size_t>(nu), 0.0);
    std::array<double, 6 * model::kMaxUserTerms> row{};
    ResidentWindow window(data);
    for (std::size_t b = 0; b < blocks_; ++b) {
      const auto [first, count] = blocks[b];
      window.advance(first + count);
      double* mean = &user_design_[b * 6 * static_cast<std::size_t>(nu)];
      for (std::size_t i = first; i < first + count; ++i) {
        model::user_design(params.user, data.dictionary(i), data.pose(i).R_base_sensor, row.data());
        for (int k = 0; k < 6 * nu; ++k)
          mean[k] += row[static_cast<std::size_t>(k)] / static_cast<double>(count);
      }
    }
  }

  std::size_t rows() const { return 6 * blocks_; }

  /// Whitened measured block means.
  Eigen::VectorXd measured() const {
    Eigen::VectorXd y(static_cast<Eigen::Index>(rows()));
    for (std::size_t b = 0; b < blocks_; ++b)
      for (int k = 0; k < 6; ++k)
        y[static_cast<Eigen::Index>(6 * b) + k] =
            stats_.sensor_means(b).measured[k] * inv_sigma_[k];
    return y;
  }

  /// Whitened predicted block means with `params`.
  void predict(const model::ModelParams& params, Eigen::VectorXd& out) const {
    out.resize(static_cast<Eigen::Index>(rows()));
    const auto p = model::pointers(params);
    const int nu = params.user.num_terms;
    for (std::size_t b = 0; b < blocks_; ++b) {
      const Wrench w1 = stats_.payload_mean<double>(params.effects, p, b);
      Wrench pred =
          model::sensor_output<double>(params.effects, p, stats_.sensor_means(b).inputs, w1);
      for (int j = 0; j < nu; ++j)
        pred += params.user.coeff[static_cast<std::size_t>(j)] *
                Eigen::Map<const Wrench>(
                    &user_design_[(b * static_cast<std::size_t>(nu) + static_cast<std::size_t>(j)) *
                                  6]);
      for (int k = 0; k < 6; ++k)
        out[static_cast<Eigen::Index>(6 * b) + k] = pred[k] * inv_sigma_[k];
    }
  }

 private:
  BlockStats stats_;
  std::size_t blocks_;
  std::array<double, 6> inv_sigma_{};
  std::vector<double> user_design_;
};

// Central-difference Jacobian of the whitened block-mean predictions over the free parameters,
// and the prediction itself. `params` is restored.
void jacobian(const BlockPredictor& pred, model::ModelParams& params, const FreeParams& f,
              const std::vector<double>& step, Eigen::VectorXd& value, Eigen::MatrixXd& J) {
  pred.predict(params, value);
  J.resize(value.size(), static_cast<Eigen::Index>(f.value.size()));
  Eigen::VectorXd plus, minus;
  // Pointers in `f` point into the fit's result; `params` may be a copy: map by position.
  for (std::size_t q = 0; q < f.value.size(); ++q) {
    const auto [e, i] = f.where[q];
    double& x = e >= 0 ? params.values[static_cast<std::size_t>(e)][static_cast<std::size_t>(i)]
                       : params.user.coeff[static_cast<std::size_t>(i)];
    const double x0 = x;
    x = x0 + step[q];
    pred.predict(params, plus);
    x = x0 - step[q];
    pred.predict(params, minus);
    x = x0;
    J.col(static_cast<Eigen::Index>(q)) = (plus - minus) / (2.0 * step[q]);
  }
}

}  // namespace

ImuRowNoise estimate_imu_row_noise(const Dataset& data) {
  ImuRowNoise n;
  if (data.columns.static_rows) return n;
  for (int k = 0; k < 3; ++k) {
    if (data.columns.specific_force) n.accel_mps2[k] = fourth_difference_scale(data, k);
    if (data.columns.angular_rate) n.gyro_radps[k] = fourth_difference_scale(data, 3 + k);
  }
  return n;
}

bool errors_in_variables_applies(const FitOptions& o, const Dataset& data, std::string* reason) {
  std::string why;
  bool on = false;
  const std::string& mode = o.errors_in_variables;
  if (mode != "off" && mode != "on" && mode != "auto")
    throw std::invalid_argument("unknown errors_in_variables '" + mode + "' (off, on, auto)");
  const bool point = data.imu_sampling.rows == formats::ImuRows::point;
  if (mode == "off") {
    why = "off as asked";
  } else if (!data.columns.any_imu()) {
    why = "the log has no IMU columns: no regressor noise to correct";
  } else if (mode == "auto" && !point) {
    why = std::string("auto: the rig says the IMU rows are ") +
          (data.imu_sampling.rows == formats::ImuRows::mean ? "means over the row period"
                                                            : "not how they were sampled") +
          ", not point samples: the block means suffice";
  } else if (o.loss != "none") {
    if (mode == "on")
      throw std::invalid_argument(
          "errors_in_variables = on needs loss = none (the correction is "
          "of least squares), loss is '" +
          o.loss + "'");
    why =
        "auto: skipped with the robust loss '" + o.loss + "' (the correction is of least squares)";
  } else {
    on = true;
    why = mode == "on" ? "on as asked" : "auto: the rig says the IMU rows are point samples";
  }
  if (reason != nullptr) *reason = why;
  return on;
}

namespace {

// Phase 1: the row noise: options, else the rig, else estimated (per group), and what the
// correction will not cover. Returns whether the angular acceleration is differenced from the rate.
bool choose_row_noise(const Dataset& data, const FitOptions& o, EivSummary& s) {
  const ImuRowNoise estimated = estimate_imu_row_noise(data);
  std::string gyro_source = "estimated", accel_source = "estimated";
  s.noise = estimated;
  if (o.imu_noise) {
    s.noise = *o.imu_noise;
    gyro_source = accel_source = "options";
  } else {
    if (data.imu_sampling.gyro_noise_radps > 0.0) {
      s.noise.gyro_radps.fill(data.imu_sampling.gyro_noise_radps);
      gyro_source = "rig";
    }
    if (data.imu_sampling.accel_noise_mps2 > 0.0) {
      s.noise.accel_mps2.fill(data.imu_sampling.accel_noise_mps2);
      accel_source = "rig";
    }
  }
  s.noise_source = gyro_source == accel_source ? gyro_source : gyro_source + ", " + accel_source;
  if (!data.columns.angular_rate) s.noise.gyro_radps = {};
  if (!data.columns.specific_force) s.noise.accel_mps2 = {};
  const bool difference = differences_angular_rate(data);
  if (data.columns.angular_rate && !difference)
    s.reason += " (the logged angular acceleration's own noise is not corrected)";
  bool any_noise = false;
  for (int k = 0; k < 3; ++k)
    any_noise = any_noise || s.noise.gyro_radps[k] > 0.0 || s.noise.accel_mps2[k] > 0.0;
  if (!any_noise) s.reason += " (no IMU row noise given or estimable: nothing to correct)";
  return difference;
}

// S = E[δJᵀδJ] and c = E[δJᵀδp] at θ̂.
struct NoiseMoments {
  Eigen::MatrixXd S;
  Eigen::VectorXd c;
};

// Phase 2: the moments at θ̂ = r.params, over deterministic draws of the row noise.
NoiseMoments expected_noise_moments(const Dataset& data, const SampleBlocks& blocks,
                                    const FitResult& r, const FreeParams& f,
                                    const std::vector<double>& step, const BlockPredictor& logged,
                                    const ImuRowNoise& noise, bool difference) {
  const auto p = static_cast<Eigen::Index>(f.value.size());
  model::ModelParams theta_hat = r.params;
  NoiseMoments m{Eigen::MatrixXd::Zero(p, p), Eigen::VectorXd::Zero(p)};
  Eigen::VectorXd p0, p1;
  Eigen::MatrixXd J0, J1;
  model::ModelParams work = theta_hat;
  jacobian(logged, work, f, step, p0, J0);
  Dataset noisy = data;
  noisy.release_rows(0, noisy.size());  // the copy walked every row (spill.hpp)
  data.release_rows(0, data.size());
  std::mt19937_64 rng(0x5eed'e1f5ULL);
  std::normal_distribution<double> normal;
  for (int d = 0; d < kEivDraws; ++d) {
    ResidentWindow window(data), noisy_window(noisy);
    for (std::size_t i = 0; i < data.size(); ++i) {
      window.advance(i);
      noisy_window.advance(i);
      for (int k = 0; k < 3; ++k) {
        noisy.imu[i * 9 + static_cast<std::size_t>(k)] =
            data.imu[i * 9 + static_cast<std::size_t>(k)] + noise.accel_mps2[k] * normal(rng);
        noisy.imu[i * 9 + 3 + static_cast<std::size_t>(k)] =
            data.imu[i * 9 + 3 + static_cast<std::size_t>(k)] + noise.gyro_radps[k] * normal(rng);
      }
    }
    if (difference) angular_accel_from_rate(noisy);
    const BlockPredictor perturbed(noisy, blocks, r.params, r.sigma);
    jacobian(perturbed, work, f, step, p1, J1);
    const Eigen::MatrixXd dJ = J1 - J0;
    m.S += dJ.transpose() * dJ;
    m.c += dJ.transpose() * (p1 - p0);
  }
  m.S /= kEivDraws;
  m.c /= kEivDraws;
  return m;
}

// The corrected θ and the identified subspace at its last Jacobian, which the covariance uses.
struct CorrectedSolve {
  Eigen::VectorXd theta0, theta;  // the fit's and the corrected free parameters
  Eigen::MatrixXd J, V, M;        // M = Vᵀ D (JᵀJ − S) D V
  Eigen::VectorXd d, lambda;      // D's diagonal, and Vᵀ D JᵀJ D V = diag(lambda)
};

// As the fit's covariance: columns scaled to unit diagonal of JᵀJ, and only the directions it
// identifies (eigenvalues above 1e-9 of the largest); rank-deficient combinations keep the
// fit's values. A parameter the prediction does not depend on at all (a zero column, e.g.
// base_tilt beside linear_inertia, which takes gravity from the IMU) keeps its value: scaled by
// 1/√1e-300 instead, the rounding in the eigenvectors' other columns threw it to 1e140.
void identified_subspace(const Eigen::MatrixXd& S, CorrectedSolve& g) {
  const Eigen::Index p = g.J.cols();
  const Eigen::MatrixXd JtJ = g.J.transpose() * g.J;
  g.d = JtJ.diagonal().unaryExpr([](double v) { return v > 0.0 ? 1.0 / std::sqrt(v) : 0.0; });
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(g.d.asDiagonal() * JtJ *
                                                           g.d.asDiagonal());
  const double lmax = eig.eigenvalues().maxCoeff();
  std::vector<Eigen::Index> keep;
  for (Eigen::Index k = 0; k < p; ++k)
    if (eig.eigenvalues()[k] > 1e-9 * lmax) keep.push_back(k);
  g.V.resize(p, static_cast<Eigen::Index>(keep.size()));
  g.lambda.resize(g.V.cols());
  for (Eigen::Index k = 0; k < g.V.cols(); ++k) {
    g.V.col(k) = eig.eigenvectors().col(keep[static_cast<std::size_t>(k)]);
    g.lambda[k] = eig.eigenvalues()[keep[static_cast<std::size_t>(k)]];
  }
  g.M = g.V.transpose() * (g.d.asDiagonal() * (JtJ - S) * g.d.asDiagonal()) * g.V;
}

// Phase 3: Gauss–Newton on Q(θ) = ‖r̃‖² − E‖δp‖², δp linearised about θ̂. Moves the free
// parameters in r.params (through f) and counts s.iterations.
CorrectedSolve corrected_gauss_newton(const BlockPredictor& logged, const Eigen::VectorXd& y,
                                      FitResult& r, const FreeParams& f,
                                      const std::vector<double>& step, const NoiseMoments& m,
                                      EivSummary& s) {
  const auto p = static_cast<Eigen::Index>(f.value.size());
  CorrectedSolve g;
  Eigen::VectorXd pred;
  g.theta0.resize(p);
  for (Eigen::Index q = 0; q < p; ++q) g.theta0[q] = *f.value[static_cast<std::size_t>(q)];
  g.theta = g.theta0;
  for (int it = 0; it < 10; ++it) {
    jacobian(logged, r.params, f, step, pred, g.J);
    const Eigen::VectorXd res = y - pred;
    identified_subspace(m.S, g);
    const Eigen::VectorXd grad = g.J.transpose() * res + m.c + m.S * (g.theta - g.theta0);
    const Eigen::LDLT<Eigen::MatrixXd> ldlt(g.M);
    if (ldlt.info() != Eigen::Success || !ldlt.isPositive() || (ldlt.vectorD().array() <= 0).any())
      throw std::runtime_error(
          "errors in variables: JᵀJ − S is not positive definite (the IMU noise swamps the "
          "regressors); fit without the correction");
    const Eigen::VectorXd delta =
        g.d.asDiagonal() * (g.V * ldlt.solve(g.V.transpose() * (g.d.asDiagonal() * grad)));
    g.theta += delta;
    for (Eigen::Index q = 0; q < p; ++q) *f.value[static_cast<std::size_t>(q)] = g.theta[q];
    ++s.iterations;
    // Converged when no parameter moves by more than 1e-6 of its step scale.
    bool small = true;
    for (Eigen::Index q = 0; q < p; ++q)
      small = small && std::abs(delta[q]) <= 1e-6 * std::max(std::abs(g.theta[q]), 1e-3);
    if (small) break;
  }
  return g;
}

// Phase 4: residual RMS per axis over the blocks' rows at the corrected θ.
void corrected_residual_rms(const Dataset& data, const SampleBlocks& blocks, FitResult& r) {
  std::array<double, 6> ss{};
  std::size_t n = 0;
  ResidentWindow window(data);
  for (const auto& [first, count] : blocks) {
    window.advance(first + count);
    for (std::size_t i = first; i < first + count; ++i, ++n) {
      const Wrench e = data.measured[i] - predict(r.params, data, i);
      for (int k = 0; k < 6; ++k) ss[k] += e[k] * e[k];
    }
  }
  for (int k = 0; k < 6; ++k) r.residual_rms[k] = std::sqrt(ss[k] / static_cast<double>(n));
}

// Phase 5: the sandwich covariance at the corrected θ, s² D V M⁻¹ (Vᵀ D JᵀJ D V = Λ) M⁻¹ Vᵀ D,
// into r's deviations, and the largest shift in the fit's deviations into s.
void corrected_covariance(const CorrectedSolve& g, const FreeParams& f, double ssr, double n_res,
                          FitResult& r, EivSummary& s) {
  const auto p = static_cast<Eigen::Index>(f.value.size());
  const double s2 = ssr / std::max(1.0, n_res - r.num_params);
  const Eigen::MatrixXd Minv = g.M.ldlt().solve(Eigen::MatrixXd::Identity(g.M.rows(), g.M.cols()));
  const Eigen::MatrixXd B = g.d.asDiagonal() * g.V * Minv;
  const Eigen::MatrixXd cov = s2 * B * g.lambda.asDiagonal() * B.transpose();
  for (Eigen::Index q = 0; q < p; ++q) {
    const auto qi = static_cast<std::size_t>(q);
    if (std::isnan(f.fit_std[qi])) continue;  // not identified: no std, as in the fit
    const double shift = std::abs(g.theta[q] - g.theta0[q]) / f.fit_std[qi];
    if (shift > s.max_shift_std) s.max_shift_std = shift, s.max_shift_param = f.label[qi];
    const double sd = std::sqrt(std::max(cov(q, q), 0.0));
    const auto [e, i] = f.where[qi];
    const auto ei = static_cast<std::size_t>(e), ii = static_cast<std::size_t>(i);
    // The robust deviation's share above the model-based one (fit.hpp, std_kind) carries
    // over to the corrected fit's model-based deviation.
    double white = f.fit_std[qi];
    if (e >= 0 && r.std_white)
      white = (*r.std_white)[ei][ii];
    else if (e < 0 && ii < r.user_std_white.size())
      white = r.user_std_white[ii];
    const double inflation =
        std::isfinite(white) && white > 0.0 ? std::max(1.0, f.fit_std[qi] / white) : 1.0;
    if (e >= 0) {
      (*r.std)[ei][ii] = sd * inflation;
      if (r.std_white) (*r.std_white)[ei][ii] = sd;
    } else {
      r.user_std[ii] = sd * inflation;
      if (ii < r.user_std_white.size()) r.user_std_white[ii] = sd;
    }
  }
}

}  // namespace

void correct_errors_in_variables(const Dataset& data, const FitOptions& o,
                                 const SampleBlocks& blocks, FitResult& r) {
  EivSummary& s = r.errors_in_variables;
  s.mode = o.errors_in_variables;
  const bool difference = choose_row_noise(data, o, s);

  FreeParams f = free_params(o, r);
  const auto p = static_cast<Eigen::Index>(f.value.size());
  if (p == 0 || blocks.empty()) return;
  std::vector<double> step(f.value.size());
  for (std::size_t q = 0; q < step.size(); ++q)
    step[q] = 1e-5 * std::max(std::abs(*f.value[q]), 1e-3);

  const BlockPredictor logged(data, blocks, r.params, r.sigma);
  const Eigen::VectorXd y = logged.measured();
  const NoiseMoments m =
      expected_noise_moments(data, blocks, r, f, step, logged, s.noise, difference);
  s.draws = kEivDraws;
  const CorrectedSolve g = corrected_gauss_newton(logged, y, r, f, step, m, s);

  // Residuals, BIC and the sandwich covariance at the corrected θ.
  Eigen::VectorXd pred;
  logged.predict(r.params, pred);
  const Eigen::VectorXd res = y - pred;
  const double n_res = static_cast<double>(res.size());
  const double ssr = res.squaredNorm();
  r.bic = n_res * std::log(ssr / n_res) + r.num_params * std::log(n_res);
  corrected_residual_rms(data, blocks, r);
  s.corrected_params = static_cast<int>(p);
  if (r.std) corrected_covariance(g, f, ssr, n_res, r, s);
  s.applied = true;
}

}  // namespace zerog::ident
