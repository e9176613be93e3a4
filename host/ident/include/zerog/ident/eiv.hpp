#pragma once
// Errors in variables: the fit corrected for the noise in its IMU regressors
// (FitOptions::errors_in_variables; proto/effects.md, "Angular acceleration and noise").
//
// Why. The model predicts the wrench from the IMU's signals, which are measured with noise: the
// angular acceleration ω̇ (the gyro through the 5-point difference, which amplifies white gyro
// noise σ_ω to about 0.95 σ_ω / Δt), the angular rate ω and the specific force f. Least squares
// with a noisy regressor X̃ = X + U is biased towards zero: E[X̃ᵀX̃] = XᵀX + S with S = E[UᵀU]
// (attenuation). The fit's block means of m rows shrink S by about m² for ω̇ (the differences
// telescope), enough when a row is already a mean over its period, not when rows are point
// samples (one raw IMU reading per row: larger σ).
//
// What. The corrected least squares of Fuller (Measurement Error Models, 1987, §2.2, the
// "method-of-moments" estimator), generalised to the nonlinear model: minimise
//   Q(θ) = ‖r̃(θ)‖² − E‖δp(θ)‖²,
// r̃ the whitened block-mean residuals the fit minimises, δp(θ) the change of the whitened
// block-mean prediction that the regressor noise causes. E‖r̃(θ)‖² = ‖r(θ)‖² + E‖δp(θ)‖² (the
// cross term has zero mean), so Q is, in expectation, the noise-free objective. Gauss–Newton on
// Q from the fit's solution θ̂, J = ∂p̃/∂θ at the log's signals:
//   (JᵀJ − S) Δ = Jᵀr̃ + E[δJᵀ δp(θ̂)] + S (θ − θ̂),   S = E[δJᵀ δJ],  δJ = ∂δp/∂θ,
// which for a model linear in θ (p = Xθ) is exactly θ = (X̃ᵀX̃ − S)⁻¹ X̃ᵀ y in one step.
// S and E[δJᵀδp] come from the model itself, for any effect list and engine: the log's IMU
// columns are perturbed again with white noise of the row noise σ (deterministic draws, fixed
// seed), ω̇ is re-formed from the perturbed gyro by the same differentiator
// (angular_accel_from_rate), and δp, δJ are the differences of the block-mean predictions (and of
// their central-difference Jacobians) between the perturbed and the logged signals. For noise
// entering linearly (ω̇, f: every effect) that is exact in distribution; ω enters the payload
// stage also through ω × (I ω), whose noise-squared mean u × (I u) is zero for a symmetric I.
//
// The IMU row noise: FitOptions::imu_noise, else the rig's `[imu_sampling]`, else estimated per
// axis from the log (estimate_imu_row_noise).
//
// Covariance (honest, sandwich): cov(θ) = s² A⁻¹ (JᵀJ) A⁻¹, A = JᵀJ − S, s² the whitened
// block residuals' mean square at the corrected θ (which contains the regressor noise) per
// degree of freedom; s² JᵀJ is the variance of the score Jᵀr̃ for independent block residuals,
// the fit's own assumption. The Monte Carlo error of S (a sum over every block of every draw) is
// far below it and not included.
//
// Scope: the free parameters, in the directions the data identifies (as the fit's covariance:
// columns scaled to a unit diagonal of JᵀJ, eigenvalues above 1e-9 of the largest; the steps and
// the covariance are taken in that subspace, so rank-deficient combinations keep the fit's values
// and their NaN std); a robust loss is refused ("on") or skips it ("auto"); a
// logged ω̇ (imu_dw* columns) keeps its noise uncorrected (only ω and f are perturbed; said in
// the reason). Host only; allocates: a copy of the dataset and the block Jacobians (6 × blocks ×
// parameters doubles).
#include <string>

#include "zerog/ident/block_stats.hpp"
#include "zerog/ident/dataset.hpp"
#include "zerog/ident/fit.hpp"

namespace zerog::ident {

/// Monte Carlo draws of the regressor noise for S and E[δJᵀδp].
inline constexpr int kEivDraws = 8;

/// White noise of one IMU row per axis of I, from the log's high-frequency content: the robust
/// (median absolute) scale of the 4th differences of each column, / √70 (the sum of the squared
/// weights 1, −4, 6, −4, 1). A smooth motion sampled at 12 ms has 4th differences far below the
/// noise; the rare rows where a move's acceleration jumps are outliers that the median ignores.
/// Zero for a group the log lacks, and for logs of static rows (no order between rows).
ImuRowNoise estimate_imu_row_noise(const Dataset& data);

/// Whether the fit with `options` on `data` gets the correction, and why (for
/// EivSummary::reason). Throws std::invalid_argument for an unknown mode or for "on" with a
/// robust loss.
bool errors_in_variables_applies(const FitOptions& options, const Dataset& data,
                                 std::string* reason);

/// The correction at the fit's solution: moves `result`'s free parameters (within the
/// identified subspace) to the
/// corrected least-squares solution, replaces their standard deviations by the sandwich
/// covariance's, updates residual_rms and bic, and fills result.errors_in_variables. `blocks` are
/// the fit's blocks of samples, result.sigma its whitening. Call only when
/// errors_in_variables_applies; throws std::runtime_error when the corrected normal matrix is not
/// positive definite (the noise would swamp the regressors).
void correct_errors_in_variables(const Dataset& data, const FitOptions& options,
                                 const SampleBlocks& blocks, FitResult& result);

}  // namespace zerog::ident
