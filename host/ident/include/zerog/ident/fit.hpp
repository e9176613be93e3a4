#pragma once
// Identification of the model parameters with Ceres (Levenberg–Marquardt, autodiff through the
// one templated model of firmware/model).
#include <array>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "zerog/ident/dataset.hpp"
#include "zerog/model/effects.hpp"

namespace zerog::ident {

using ParamArray = std::array<std::array<double, model::kMaxEffectParams>, model::kEffectCount>;

struct FitOptions {
  model::EffectSet effects;
  std::string loss = "none";  ///< none | huber | cauchy (on residuals whitened per axis)
  double loss_scale = 3.0;    ///< robust-loss scale in units of the per-axis noise
  int max_iterations = 50;
  /// The fit compares block means of this many consecutive samples (1 = every sample); see
  /// proto/effects.md, "Angular acceleration and noise".
  int block_samples = 8;
  int threads = 2;
  bool covariance = true;  ///< compute standard deviations and identifiability
  const std::vector<std::uint8_t>* mask = nullptr;  ///< use sample i only if (*mask)[i] == 1
  const model::ModelParams* initial = nullptr;      ///< start values (others: linear init)
  /// Per-axis noise for whitening; if absent, estimated (two passes).
  std::optional<std::array<double, 6>> sigma;
  std::function<void(const std::string&)> progress;  ///< progress lines (may be empty)
};

struct Warning {
  std::string kind;     ///< "rank_deficient" | "correlated" | "not_converged"
  std::string message;  ///< plain words, names the parameters
};

struct FitResult {
  model::ModelParams params;
  std::optional<ParamArray> std;  ///< standard deviations (absent where unidentifiable: NaN)
  bool usable = false;
  std::string termination;
  int iterations = 0;
  double seconds = 0.0;
  std::size_t samples = 0;
  std::array<double, 6> sigma{};         ///< per-axis whitening of the block residuals
  std::array<double, 6> residual_rms{};  ///< per axis, per sample, on the fitted samples
  double bic = 0.0;                      ///< Bayesian information criterion of the block residuals
  int num_params = 0;
  std::vector<Warning> warnings;
};

/// Fits the effects in `options.effects` to `data`. Accepts the solution only if Ceres reports
/// it usable; otherwise `usable` is false and `termination` says why.
FitResult fit(const Dataset& data, const FitOptions& options);

/// Name of a parameter for messages: "gravity.mass [kg]".
std::string param_label(model::Effect e, int i);

}  // namespace zerog::ident
