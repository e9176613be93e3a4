#pragma once
// The F/T-only floor (issue 28, item 4): the white noise of one logged wrench row, estimated from
// the log itself, with no truth model: the contact wrench (measured − predicted) cannot be
// quieter than the sensor that measures it, so compare, ladder and the HIL report quote their
// error against it. Unlike the sensor floor (compare --truth: the true model on a simulator's
// noise-free signals) it needs no simulator and works on a real recording.
//
// Method: in runs of consecutive rows at rest (Dataset::moving == 0), the second difference
// d_i = w_{i+1} − 2 w_i + w_{i−1} of each wrench axis removes the slowly varying load (gravity,
// drift) and leaves 6 σ² of white noise; σ = 1.4826 · median|d| / √6 (the median absolute value,
// robust to the occasional step). Coloured noise (a sensor's own filter, AR(1)) reads low: the
// floor is then optimistic, never pessimistic.
#include <array>
#include <cstddef>
#include <string>

#include <nlohmann/json.hpp>

#include "zerog/ident/dataset.hpp"

namespace zerog::ident {

struct FtFloor {
  bool known = false;
  std::string note;               ///< why it is not known; empty when it is
  std::array<double, 6> sigma{};  ///< per axis, N and N·m (the wrench's order)
  double force_rms = 0.0;         ///< sqrt of the mean of the three force axes' σ², N
  double torque_rms = 0.0;        ///< the same for the torque, N·m
  std::size_t differences = 0;    ///< second differences used
};

/// At least this many second differences at rest, else not known (a few seconds at rest).
inline constexpr std::size_t kMinFloorDifferences = 30;

FtFloor ft_floor(const Dataset& data);

/// An error to hold against the floor, at rest and moving (RMS over the three axes).
struct ErrorVsFloor {
  double force_rest = 0.0, torque_rest = 0.0, force_moving = 0.0, torque_moving = 0.0;
};

/// "F/T-only floor (…): force 0.27 N, torque 0.032 N*m" and, with `error`, the error's ratio to
/// it at rest and moving; one or two lines.
std::string format_ft_floor(const FtFloor& f, const ErrorVsFloor* error);

nlohmann::json to_json(const FtFloor& f, const ErrorVsFloor* error);

}  // namespace zerog::ident
