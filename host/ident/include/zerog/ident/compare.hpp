#pragma once
// Measured against predicted: per-axis error statistics, split by motion and by joint angle.
#include <array>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "zerog/ident/dataset.hpp"

namespace zerog::ident {

inline constexpr std::array<const char*, 6> kAxisNames = {"Fx", "Fy", "Fz", "Mx", "My", "Mz"};
inline constexpr std::array<const char*, 6> kAxisUnits = {"N", "N", "N", "N*m", "N*m", "N*m"};

/// Error statistics of one set of samples.
struct ErrorStats {
  std::size_t count = 0;
  std::array<double, 6> rms{};
  std::array<double, 6> max_abs{};
  double force_rms = 0.0;   ///< RMS over the three force components pooled, N
  double torque_rms = 0.0;  ///< RMS over the three torque components pooled, N·m
};

/// Accumulates residuals (measured − predicted).
class ErrorAccumulator {
 public:
  void add(const Wrench& e);
  ErrorStats stats() const;

 private:
  std::size_t n_ = 0;
  std::array<double, 6> ss_{};
  std::array<double, 6> max_{};
};

struct JointBins {
  int joint = 0;                  ///< 0-based (A1 = 0)
  std::vector<double> edges_rad;  ///< bins+1 edges over the joint's range in the log
  std::vector<ErrorStats> bins;
};

struct Comparison {
  ErrorStats all, stat, moving;
  std::vector<JointBins> joints;  ///< empty if the log has no joint angles
  struct Worst {
    int axis = 0;
    std::string segment;
    int joint = -1;
    double lo = 0, hi = 0, rms = 0;
  } worst;
};

/// Residuals of every sample (measured − predicted); `mask` (optional) selects samples.
std::vector<Wrench> residuals(const model::ModelParams& params, const Dataset& data);
Comparison compare(const std::vector<Wrench>& residuals, const Dataset& data,
                   const std::vector<std::uint8_t>* mask = nullptr, int bins = 6);

nlohmann::json to_json(const ErrorStats& s);
nlohmann::json to_json(const Comparison& c);
/// Human-readable table.
std::string format_comparison(const Comparison& c, const Comparison* floor = nullptr);

}  // namespace zerog::ident
