#pragma once
// Identification of the model parameters with Ceres (Levenberg–Marquardt, autodiff through the
// one templated model of firmware/model).
#include <array>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "zerog/ident/dataset.hpp"
#include "zerog/model/effects.hpp"

namespace zerog::ident {

using ParamArray = std::array<std::array<double, model::kMaxEffectParams>, model::kEffectCount>;

/// White noise of one logged IMU row, per axis of the IMU frame I (standard deviations).
struct ImuRowNoise {
  std::array<double, 3> gyro_radps{};  ///< of imu_w*_radps, rad/s
  std::array<double, 3> accel_mps2{};  ///< of imu_f*_mps2, m/s²
};

/// What the errors-in-variables correction (eiv.hpp) did: FitResult::errors_in_variables.
struct EivSummary {
  std::string mode = "off";  ///< FitOptions::errors_in_variables as asked: off | on | auto
  bool applied = false;
  std::string reason;        ///< why it was or was not applied, in plain words
  ImuRowNoise noise;         ///< the IMU row noise it used
  std::string noise_source;  ///< "options" | "rig" | "estimated" (per group, e.g. "rig, estimated")
  int draws = 0;             ///< Monte Carlo draws of the regressor noise
  int iterations = 0;        ///< corrected Gauss–Newton steps
  int corrected_params = 0;  ///< free parameters in it (rank-deficient combinations stay put)
  /// Largest |corrected − uncorrected| / std over those with a std, and whose.
  double max_shift_std = 0.0;
  std::string max_shift_param;
};

struct FitOptions {
  model::EffectSet effects;
  /// User-defined effects to fit with the library ones (proto/user_effects.md); their
  /// coefficients are the start values (or `initial`'s, when it holds the same terms).
  model::UserEffects user;
  std::string loss = "none";  ///< none | huber | cauchy (on residuals whitened per axis)
  double loss_scale = 3.0;    ///< robust-loss scale in units of the per-axis noise
  int max_iterations = 50;
  /// The fit compares block means of this many consecutive samples (1 = every sample); see
  /// proto/effects.md, "Angular acceleration and noise".
  int block_samples = 8;
  int threads = 2;         ///< the normal engine's result is bit-identical for any count
  bool covariance = true;  ///< compute standard deviations and identifiability
  /// What the standard deviations are (docs/calibrating.md, "What ± means"). "robust" (the
  /// default): the larger of the model-based one and a cluster-robust (sandwich) one, whose
  /// clusters are `cluster_s` of log time (a table's rows, without time, each its own): it holds
  /// when the noise is coloured or the model misses something. "white": the model-based one
  /// alone, (JᵀJ)⁻¹ s², right only for white, correctly modelled noise.
  std::string std_kind = "robust";
  double cluster_s = 10.0;
  const std::vector<std::uint8_t>* mask = nullptr;  ///< use sample i only if (*mask)[i] == 1
  const model::ModelParams* initial = nullptr;      ///< start values (others: linear init)
  /// Effects of `effects` whose parameter blocks are held constant at their `initial` values
  /// (Ceres SetParameterBlockConstant), e.g. the sensor's zero-point model after a tool change.
  /// `initial` must then hold every frozen effect. Standard deviations, correlations, the rank
  /// check and the BIC cover the free parameters only; frozen ones get no std (NaN).
  model::EffectSet frozen;
  /// How the fit evaluates and solves. "normal" (the default): the block means as
  /// "block_stats" does, accumulated into the whitened normal equations in one streaming pass
  /// per iteration (no per-block Jacobian is stored), solved by Levenberg–Marquardt; robust
  /// losses delegate to "block_stats" (normal_equations.hpp). "block_stats": Ceres on the block
  /// means from the blocks' sufficient statistics, one model evaluation per block
  /// (block_stats.hpp; exact); "samples": Ceres with the model on every sample of the block (the
  /// reference, slower). Results agree within 1e-6 (tests/unit/ident/fit_engine_test.cpp).
  std::string engine = "normal";
  /// Per-axis noise for whitening; if absent, estimated (two passes).
  std::optional<std::array<double, 6>> sigma;
  /// Errors in variables (eiv.hpp, proto/effects.md "Angular acceleration and noise"): correct
  /// the fit for the noise of the IMU regressors (above all the differenced gyro). "off", "on",
  /// or "auto": on where the log's rig says its IMU rows are point samples
  /// (Dataset::imu_sampling, proto/log_format.md `[imu_sampling]`), off otherwise.
  std::string errors_in_variables = "auto";
  /// The IMU row noise the correction uses; absent: the rig's (`[imu_sampling]`), else estimated
  /// from the log's high-frequency content (estimate_imu_row_noise).
  std::optional<ImuRowNoise> imu_noise;
  std::function<void(const std::string&)> progress;  ///< progress lines (may be empty)
};

struct Warning {
  std::string kind;     ///< "rank_deficient" | "correlated" | "not_converged"
  std::string message;  ///< plain words, names the parameters
};

struct FitResult {
  model::ModelParams params;
  std::optional<ParamArray> std;  ///< standard deviations (absent where unidentifiable: NaN)
  std::vector<double> user_std;   ///< of params.user's coefficients (with `std`; NaN likewise)
  /// The model-based standard deviations ((JᵀJ)⁻¹ s²: white, correctly modelled noise), which
  /// `std` equals with std_kind "white" and bounds from below with "robust".
  std::optional<ParamArray> std_white;
  std::vector<double> user_std_white;
  std::string std_kind;  ///< FitOptions::std_kind as applied
  int clusters = 0;      ///< clusters of the robust covariance (0 with "white")
  bool usable = false;
  std::string termination;
  std::string engine;  ///< the engine that ran (FitOptions::engine; "block_stats" where "normal"
                       ///< delegated a robust loss)
  int iterations = 0;
  double seconds = 0.0;
  std::size_t samples = 0;
  std::array<double, 6> sigma{};         ///< per-axis whitening of the block residuals
  std::array<double, 6> residual_rms{};  ///< per axis, per sample, on the fitted samples
  double bic = 0.0;                      ///< Bayesian information criterion of the block residuals
  int num_params = 0;                    ///< free (fitted) parameters
  std::vector<Warning> warnings;
  EivSummary errors_in_variables;  ///< the errors-in-variables correction (eiv.hpp)
};

/// Fits the effects in `options.effects` to `data`. Accepts the solution only if Ceres reports
/// it usable; otherwise `usable` is false and `termination` says why.
FitResult fit(const Dataset& data, const FitOptions& options);

/// Does the answer depend on which half of the data is used, or on the weighting (issue 25:
/// standard deviations that assume white, correctly modelled noise can be far too small)? The
/// fit again on the first and on the second half of its rows (in row order: time, or a table's
/// recording order), and once with plain weights (1 N, 0.1 N·m per axis group, not the per-axis
/// noise estimate).
struct Consistency {
  struct Half {
    std::size_t first_row = 0, last_row = 0;  ///< 0-based, of the rows used
    bool usable = false;
    model::ModelParams params;
    std::optional<ParamArray> std;
    std::string note;  ///< why it tells nothing (not usable, rank deficient), or empty
  };
  Half first, second;
  /// Largest |first − second| / sqrt(std1² + std2²) over the parameters both halves identify,
  /// and its parameter ("gravity.mass [kg]"); NaN when no parameter is comparable.
  double max_half_z = 0.0;
  std::string max_half_param;
  bool weighting_usable = false;
  model::ModelParams unweighted;
  /// Largest |unweighted − fit| / std over the fit's parameters, and its parameter.
  double max_weight_shift = 0.0;
  std::string max_weight_param;
  std::vector<Warning> warnings;  ///< "split_half", "weighting" (above 3)
};
/// `full` is fit(data, o); the halves and the unweighted fit use `o` otherwise.
Consistency check_consistency(const Dataset& data, const FitOptions& o, const FitResult& full);

/// 1 for the static samples of `data` (Dataset::moving == 0), 0 while the sensor moves.
std::vector<std::uint8_t> static_mask(const Dataset& data);

/// Tool change (paper 001_… §3.2, Appendix A): a new end-effector on a sensor whose zero-point
/// model is known. Only the payload's mass and centre of mass (the `gravity` block) are fitted,
/// from the static samples (dwells) of a run through a handful of attitudes; every other effect
/// of the base model keeps its values (FitOptions::frozen). The paper solves eq. 13–14 as two
/// linear least-squares problems on the zero-corrected output; here the same model is fitted in
/// one Ceres problem on block means of the dwell samples, with the frozen model in place of the
/// paper's f_zero.
struct ToolChangeOptions {
  int block_samples = 8;  ///< block means of this many consecutive static samples
  int max_iterations = 50;
  int threads = 2;
  std::string loss = "none";
  double loss_scale = 3.0;
  std::string engine = "normal";             ///< FitOptions::engine
  std::string errors_in_variables = "auto";  ///< FitOptions::errors_in_variables
  /// Warn ("poses_alike") when the gravity directions in S spread less than this: the angle
  /// asin √(1 − λmax) with λmax the largest eigenvalue of their mean outer product (0 if they
  /// are all parallel, about 55° if they are spread evenly over the sphere), degrees.
  double min_spread_deg = 10.0;
  /// Warn ("poorly_identified") when std(mass) / mass or a std of cx, cy, cz exceeds these.
  double max_rel_std_mass = 0.005;
  double max_std_com_m = 0.001;
  std::function<void(const std::string&)> progress;
};

struct ToolChangeResult {
  FitResult fit;                   ///< the whole model: base values, gravity re-fitted
  std::size_t static_samples = 0;  ///< samples with moving == 0 (of data.size())
  std::size_t dwells = 0;          ///< runs of consecutive static samples
  double spread_deg = 0.0;         ///< spread of the gravity directions in S (see options)
  model::EffectSet frozen;         ///< the base model's effects held constant
};

/// Re-identifies `gravity` (mass, cx, cy, cz) on the static samples of `data` with every other
/// effect of `base` frozen. `base` must contain `gravity` (its values are the start values).
/// Warnings (in fit.warnings) besides the fit's own: "poses_alike", "poorly_identified", and
/// "kept_inertia" when the base model's rotational_inertia (the old tool's) is carried over, which
/// static poses cannot update. Throws std::runtime_error when there are no static samples or the
/// base model lacks gravity.
ToolChangeResult fit_tool_change(const Dataset& data, const model::ModelParams& base,
                                 const ToolChangeOptions& options);

/// Name of a parameter for messages: "gravity.mass [kg]".
std::string param_label(model::Effect e, int i);

}  // namespace zerog::ident
