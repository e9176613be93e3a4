#pragma once
// The robot's position servo identified from a zerog-rt recording (`zerog servo`; issue 28;
// docs/zerog-rt.md, "Identifying the servo model"): the bandwidth of [filter] servo_hz, which the
// motion estimator's servo model needs (loop::ServoModel, proto/loop.md "The servo model").
//
// The recording (cycles.csv) holds, per robot cycle, the measured joints (AIPos) and the
// correction zerog-rt sent in reply. Each correction is turned into the joint increment the
// controller executes (loop::commanded_increment, the servo model's own input) and run through
// the servo model itself (loop::ServoModel: from the controller's next tick, interpolated over
// the cycle, a critically damped second order of bandwidth f). The model's step from one row to
// the next is compared with the measured joints' step L rows later (zerog-rt's model assumes
// L = 2: a correction answered at row k moves the joints from row k + 1 to row k + 2), summed
// over the joints and rows; f and L are those of the smallest sum (a grid over L ∈ {1 … 4} and
// f, refined by Ceres on log f).
//
// Honest about what a recording can tell:
//   - the bandwidth is only seen where the commanded rate changes (a push starts, stops): an
//     instant servo (f = ∞) fitting as well means it cannot be told (known = false);
//   - above half the cycle rate (41.7 Hz at 12 ms) the rows cannot tell it from instant;
//   - the recording is cut in quarters and each quarter with excitation is fitted alone: their
//     spread is the uncertainty quoted, and quarters disagreeing by more than kMaxQuarterRatio
//     mean the model does not describe this robot (known = false, the quarters named).
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "zerog/loop/cycle_record.hpp"
#include "zerog/robot/robot_model.hpp"

namespace zerog::ident {

struct ServoFitOptions {
  /// The rig's robot: needed for Cartesian corrections (RKorr), not for AKorr.
  std::optional<robot::RobotModel> robot;
  double configured_hz = 0.0;  ///< [filter] servo_hz now (0: off), compared in the report
};

/// One candidate's joint-step residual.
struct ServoCandidate {
  double hz = 0.0;       ///< 0: the instant servo (f = ∞)
  double rms_rad = 0.0;  ///< RMS over joints and rows of measured − modelled step
};

struct ServoQuarter {
  std::size_t first_row = 0, rows = 0;
  bool excited = false;  ///< the bandwidth lowered its residual by kMinGain against f = ∞
  double hz = 0.0;       ///< its own fit (excited quarters only)
};

struct ServoFit {
  bool known = false;
  std::string note;         ///< why not, or what to mind
  std::size_t records = 0;  ///< read
  std::size_t rows = 0;     ///< steps compared (per joint)
  std::size_t runs = 0;     ///< stretches without a lost or stale datagram
  double cycle_s = 0.0;     ///< the median row period
  int joints = 0;
  double max_command_rad = 0.0;  ///< the largest commanded increment of a cycle (any joint)
  double motion_rms_rad = 0.0;   ///< RMS of the measured joints' steps compared
  int lag_rows = 0;              ///< L of the best fit
  static constexpr int kModelLag = 2;
  double hz = 0.0;                  ///< the fit (NaN when nothing can be told)
  double hz_sigma = 0.0;            ///< from the quarters' spread: their standard deviation / √n
  double hz_lo = 0.0, hz_hi = 0.0;  ///< the excited quarters' smallest and largest fit
  double hz_max = 0.0;              ///< half the cycle rate: what the rows can tell
  ServoCandidate best, instant, configured;
  std::vector<ServoQuarter> quarters;
  std::vector<double> lag_rms_rad;  ///< per L = 1 … 4, at its own refined best f
};

/// An excited stretch lowers the residual by at least this fraction against f = ∞.
inline constexpr double kMinGain = 0.1;
/// The excited quarters' fits may differ by this factor at most.
inline constexpr double kMaxQuarterRatio = 1.5;
/// At least this many rows with a correction sent.
inline constexpr std::size_t kMinServoRows = 250;

/// Throws std::invalid_argument when Cartesian corrections were sent and `options.robot` is
/// empty (the message says what to give).
ServoFit fit_servo(const std::vector<loop::CycleRecord>& records, const ServoFitOptions& options);

std::string format_servo_fit(const ServoFit& fit);
nlohmann::json to_json(const ServoFit& fit);

}  // namespace zerog::ident
