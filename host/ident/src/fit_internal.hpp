#pragma once
// What fit()'s files share (fit.hpp): the unknowns, the blocks every pass evaluates and what the
// passes leave (fit.cpp, the solve), for the covariance (fit_covariance.cpp); the residual blocks
// themselves are residual_blocks.hpp's. Host only: allocates.
#include <ceres/ceres.h>

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "zerog/ident/block_stats.hpp"
#include "zerog/ident/fit.hpp"

namespace zerog::ident::fitting {

// ---- The solve (fit.cpp) ----

// The unknowns: the model's effects with parameters in the order of model::kAllEffects (the
// parameter blocks of both engines), which of them stay frozen, and how many parameters are free.
struct Unknowns {
  std::vector<model::Effect> order;
  std::vector<bool> frozen;  // per effect of `order`
  int num_user = 0;          // user terms, free, after the effects
  int num_free = 0;
};

// What every pass evaluates: the blocks of samples, the engine, and what the engine computes once
// from the log (the block statistics, the user terms' mean design).
struct FitBlocks {
  int block_samples = 1;
  SampleBlocks blocks;
  bool normal_engine = false;       // else a Ceres problem
  std::optional<BlockStats> stats;  // engines normal and block_stats
  std::vector<double> user_design;  // mean_user_design
  const BlockStats* stats_or_null() const { return stats ? &*stats : nullptr; }
};

// What the passes leave for the summary and the covariance.
struct Solved {
  std::array<double, 6> sigma{};  // the last pass's whitening
  bool usable = false;
  bool no_convergence = false;  // stopped at max_iterations
  std::string message;
  Eigen::MatrixXd normal_JtJ;  // engine normal: JᵀJ of the free parameters at the solution
  std::array<double, 6> rms{};
  double ssr = 0.0;
  std::size_t n = 0;   // samples
  std::size_t nb = 0;  // block residuals
};

// ---- The covariance (fit_covariance.cpp) ----

// Identifiability and uncertainty from the column-scaled JᵀJ of the free parameters (rank,
// correlations): warnings, standard deviations.
void estimate_covariance(const Dataset& data, const FitOptions& o, const FitBlocks& fb,
                         const Unknowns& u, const Solved& solved, ceres::Problem* problem,
                         FitResult& r);

}  // namespace zerog::ident::fitting
