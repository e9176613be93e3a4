#pragma once
// Fitting a dense network (model::network_forward) to a training set: Levenberg–Marquardt with
// Ceres (autodiff through the forward pass with ceres::Jet), a minimal Adam (with the gradient by
// backpropagation), and the least-squares tool load of 001_… §3.2. Host only.
#include <cstdint>
#include <functional>
#include <limits>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "zerog/ident/dataset.hpp"
#include "zerog/learn/network_file.hpp"
#include "zerog/model/network.hpp"

namespace zerog::learn {

/// Raw inputs and targets, row-major: x is size() × inputs, y is size() × outputs.
struct TrainingSet {
  int inputs = 0;
  int outputs = 0;
  std::vector<double> x, y;
  std::size_t size() const { return inputs > 0 ? x.size() / static_cast<std::size_t>(inputs) : 0; }
};

/// Input mean and standard deviation (scale 1 for a constant input); output mean and standard
/// deviation (scale 1 for a constant output). Throws std::invalid_argument on an empty set.
model::NetworkNormalisation normalisation_for(const TrainingSet& set);

/// Uniform random weights (Glorot: ±√(6 / (fan_in + fan_out)); He for leaky ReLU: ±√(6 /
/// fan_in)), zero biases; deterministic for a seed (std::mt19937_64, own mapping to doubles).
std::vector<double> initial_params(const model::NetworkShape& shape, std::uint64_t seed);

/// Mean over samples and outputs of the squared error in normalised output units,
/// ((ŷ − y) / output_scale)².
double normalised_mse(const model::NetworkShape& shape, const model::NetworkNormalisation& norm,
                      std::span<const double> params, const TrainingSet& set);

/// Loss = normalised_mse + l2 · Σ weights² (biases not regularised); writes its gradient with
/// respect to the parameters to `grad` (shape.num_params() values) by backpropagation.
double loss_and_gradient(const model::NetworkShape& shape, const model::NetworkNormalisation& norm,
                         std::span<const double> params, const TrainingSet& set, double l2,
                         std::span<double> grad);

struct NetworkFitResult {
  std::vector<double> params;
  double train_mse = 0.0;  ///< normalised_mse on the training set at the returned parameters
  double validation_mse = std::numeric_limits<double>::quiet_NaN();
  int iterations = 0;      ///< optimiser iterations run
  int best_iteration = 0;  ///< iteration of the returned parameters (validation minimum)
  double seconds = 0.0;
  std::string termination;
};

struct LmOptions {
  int max_iterations = 100;
  /// Early stopping: stop after this many successful steps without a new validation minimum
  /// (MATLAB trainlm's max_fail = 6) and return the parameters of the minimum.
  int patience = 6;
  int threads = 2;  ///< Jacobian evaluation threads (static sample ranges: deterministic)
  std::string label = "lm";
  std::function<void(const std::string&)> progress;
};

/// Levenberg–Marquardt on the normalised squared error (Ceres, DENSE_NORMAL_CHOLESKY, Jacobian by
/// forward-mode autodiff through model::network_forward with a fixed-size ceres::Jet). At most
/// 1024 parameters. `validation` may be null (then no early stopping). Throws
/// std::runtime_error if Ceres reports the solution unusable.
NetworkFitResult fit_lm(const model::NetworkShape& shape, const model::NetworkNormalisation& norm,
                        const TrainingSet& train, const TrainingSet* validation,
                        std::vector<double> initial, const LmOptions& options);

struct AdamOptions {
  /// Learning-rate schedule: (first iteration, rate), ascending. Default: 001_… Table 2 with
  /// its 100,000 iterations scaled to `iterations`.
  std::vector<std::pair<int, double>> schedule;
  int iterations = 10000;
  double l2 = 1e-4;  ///< L2 regularisation weight (001_… §4.1), normalised units
  double beta1 = 0.9, beta2 = 0.999, epsilon = 1e-8;
  std::string label = "adam";
  std::function<void(const std::string&)> progress;
};
/// 001_… Table 2 (0.005 / 0.001 / 0.0005 / 0.0001 from iteration 0 / 10 % / 30 % / 50 %),
/// scaled to `iterations`.
std::vector<std::pair<int, double>> paper_zp_schedule(int iterations);

/// Full-batch Adam (Kingma & Ba 2015) on loss_and_gradient. Returns the final parameters.
NetworkFitResult fit_adam(const model::NetworkShape& shape, const model::NetworkNormalisation& norm,
                          const TrainingSet& train, const TrainingSet* validation,
                          std::vector<double> initial, const AdamOptions& options);

/// Least-squares tool load, 001_… eq. 9–14: ᴮG* = (RᵀR)⁻¹ Rᵀ ˢG (eq. 13) with R stacking
/// R_base_sensor,iᵀ, then r* = (A*ᵀA*)⁻¹ A*ᵀ ˢM (eq. 14) with A_i the cross-product matrix of
/// ˢG_i = R_iᵀ ᴮG* (eq. 8). `wrench` holds the static wrench minus the zero point per pose.
/// Throws std::invalid_argument with fewer than 3 poses or a singular system.
ToolLoad tool_load_ls(std::span<const Eigen::Matrix3d> R_base_sensor,
                      std::span<const ident::Wrench> wrench);

}  // namespace zerog::learn
