#pragma once
// Measured against predicted: per-axis error statistics, split by motion and by joint angle.
#include <array>
#include <filesystem>
#include <optional>
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

/// Error statistics of one residual over all, static and moving samples (`mask` selects).
struct SegmentStats {
  ErrorStats all, stat, moving;
};
SegmentStats segment_stats(const std::vector<Wrench>& residuals, const Dataset& data,
                           const std::vector<std::uint8_t>* mask = nullptr);

/// The two yardsticks of a simulated run (docs/insight-loop.md, "Sensor floor and true-model
/// reference"):
/// - the true-model reference: the true model with the true parameters on the log's own noisy
///   signals, against its wrench. What a perfect fit of the complete model leaves; not a lower
///   bound: the IMU's noise enters through the regressors (mass × accelerometer noise, inertia ×
///   differenced gyro), and a model that uses the IMU otherwise (a network) can beat it.
/// - the sensor floor: the true model on the noise-free signals of the same rows (the clean log
///   zerog sim writes beside the log) against the same noisy wrench: the F/T sensor's own noise
///   and quantisation, which no model of the signals beats on average.
struct Floors {
  std::vector<Wrench> reference_residuals;  ///< measured − true model on the log, every row
  std::vector<Wrench> sensor_residuals;     ///< measured − true model on clean signals; or empty
  SegmentStats reference;
  std::optional<SegmentStats> sensor;
  std::string clean_log;    ///< the noise-free log the sensor floor came from; empty if none
  std::string sensor_note;  ///< why there is no sensor floor; empty when there is one
};

/// Both floors of `data` with the truth `truth` (its user terms are the effects outside the
/// library, so ident::predict is the complete true model). `clean`: the noise-free copy of `data`
/// (sim::SimOutput::clean_log); null gives only the reference. `mask` selects the samples of the
/// statistics (the ladder's held-out blocks); the residuals cover every row. Throws
/// std::runtime_error if `clean` does not match `data` row for row (time and wrench).
Floors floors(const model::ModelParams& truth, const Dataset& data, const Dataset* clean,
              const std::vector<std::uint8_t>* mask = nullptr);
/// The same from a truth model file (zerog sim): reads the clean log that the truth names in
/// extra.clean_signals_log (relative to the truth file's folder). A truth file naming none (from
/// before the clean log, or not from zerog sim) gives only the reference, and sensor_note says
/// so. Throws if the named log cannot be read or does not belong to `data`.
Floors floors(const std::filesystem::path& truth_path, const Dataset& data,
              const std::vector<std::uint8_t>* mask = nullptr);

nlohmann::json to_json(const ErrorStats& s);
nlohmann::json to_json(const Comparison& c);
/// {"all": stats, "static": stats, "moving": stats}.
nlohmann::json to_json(const SegmentStats& s);
/// Human-readable table; with `floors`, per-axis columns and lines for both floors.
std::string format_comparison(const Comparison& c, const Floors* floors = nullptr);
/// Two lines, the true-model reference and the sensor floor (or why it is unknown), force and
/// torque RMS for all, static and moving samples; `scope` e.g. "held-out" or "" .
std::string format_floors(const Floors& f, const std::string& scope = "");

}  // namespace zerog::ident
