#pragma once
// `zerog train`: one code path for the three kinds of network (paper-bp, paper-zp, residual),
// from a log to a network file. Host only.
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "zerog/formats/log.hpp"
#include "zerog/ident/dataset.hpp"
#include "zerog/io/model_file.hpp"
#include "zerog/learn/network_file.hpp"

namespace zerog::learn {

struct TrainOptions {
  NetworkKind kind = NetworkKind::residual;
  /// Hidden units: paper-bp one layer (default 8, 000_… §4.3); residual one tanh layer (default
  /// 12); paper-zp ignores it (45 and 90, 001_… §3.1).
  std::optional<int> hidden;
  std::uint64_t seed = 1;
  /// residual: input features; empty = from ident::diagnose (its most correlated signals).
  std::vector<model::Feature> inputs;
  /// residual: the physics model whose residual the network learns (required).
  std::optional<io::ModelFile> physics;
  /// Samples that may be used for training and validation (null = all). The results table
  /// passes the complement of ident::heldout_mask.
  const std::vector<std::uint8_t>* usable = nullptr;
  /// Levenberg–Marquardt training sets are subsampled (seeded) to at most this many samples:
  /// the dense Jacobian is samples × 6 × parameters.
  int max_train_samples = 4000;
  int max_iterations = 150;     ///< Levenberg–Marquardt iterations
  int adam_iterations = 30000;  ///< paper-zp: 001_… used 100,000
  int threads = 2;
  std::function<void(const std::string&)> progress;
};

/// Trains a network of `options.kind` on `data` (made from `log`). Deterministic for a seed
/// (any thread count). Throws std::invalid_argument / std::runtime_error with a clear message on
/// bad options, missing signals or too little data.
NetworkFile train(const ident::Dataset& data, const formats::Log& log, const TrainOptions& options);

/// The residual network's default inputs: ident::diagnose on the physics model, its correlated
/// signals (|ρ| ≥ min_correlation, strongest first, at least the first) mapped to features.
/// `signals` (optional) receives the signal names used. Only samples with (*usable)[i] == 1 are
/// fitted or correlated (all if null), so a test set stays unseen.
std::vector<model::Feature> inputs_from_diagnosis(
    const ident::Dataset& data, const io::ModelFile& physics, int threads,
    std::vector<std::string>* signals = nullptr, double min_correlation = 0.2,
    std::function<void(const std::string&)> progress = {},
    const std::vector<std::uint8_t>* usable = nullptr);

/// 000_… §4.3 (Figure 12): validation MSE of paper-bp for each hidden-layer size, `repeats`
/// trainings each (seeds seed, seed+1, …); mean and each value.
struct SweepRow {
  int hidden = 0;
  std::vector<double> validation_mse;  ///< normalised units, one per repeat
  double mean = 0.0;
  double seconds = 0.0;
};
std::vector<SweepRow> sweep_hidden(const ident::Dataset& data, const formats::Log& log,
                                   const TrainOptions& options, const std::vector<int>& hidden,
                                   int repeats = 3);

}  // namespace zerog::learn
