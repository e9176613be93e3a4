#pragma once
// The results table: the paper methods, the physics model, physics + residual network (float and
// quantised), the true-model reference and the sensor floor, on one simulated KR210/100 kg run
// and the same time-blocked held-out data, static and moving separately; with the papers' own
// figures quoted beside them.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "zerog/ident/compare.hpp"

namespace zerog::learn {

struct ResultsOptions {
  std::uint64_t seed = 42;       ///< simulation seed (effect magnitudes and noise)
  std::uint64_t train_seed = 1;  ///< network initialisation and splits
  std::string truth_effects = "cable,joint6_friction";  ///< on top of the simulator's default
  int threads = 2;
  int max_iterations = 150;        ///< Levenberg–Marquardt iterations (TrainOptions)
  int max_train_samples = 4000;    ///< Levenberg–Marquardt subsample (TrainOptions)
  int adam_iterations = 30000;     ///< paper-zp
  std::filesystem::path keep_dir;  ///< if set: write the run, the physics fit and the networks
  std::function<void(const std::string&)> progress;
};

struct MethodResult {
  /// paper-bp, paper-zp, physics, residual, residual-quantised, true-model-reference,
  /// sensor-floor
  std::string key;
  std::string label;  ///< plain words for the table
  bool available = true;
  std::string note;                     ///< why not available, or a remark
  ident::ErrorStats all, stat, moving;  ///< held-out samples
  double train_seconds = 0.0;
};

struct Results {
  std::uint64_t seed = 0;
  std::string truth_effects;
  std::size_t samples = 0;
  double duration_s = 0.0;
  std::size_t heldout_static = 0, heldout_moving = 0;
  std::string physics_effects;  ///< the ladder's model
  /// Largest |quantised − float| prediction over the held-out samples, force axes (N) and torque
  /// axes (N·m); negative when the quantised inference is not available.
  double quantised_vs_float_max_N = -1.0, quantised_vs_float_max_Nm = -1.0;
  std::string residual_inputs;
  std::vector<MethodResult> methods;
  nlohmann::json details = nlohmann::json::object();  ///< ladder, tool load, training summaries
  const MethodResult& method(const std::string& key) const;  ///< throws if absent
};

/// Simulates the run, climbs the ladder for the physics model, trains every method on the
/// training blocks and evaluates all of them on the held-out blocks (ident::heldout_mask).
Results run_results(const ResultsOptions& options);

std::string format_markdown(const Results& r);
nlohmann::json to_json(const Results& r);

}  // namespace zerog::learn
