#pragma once
// Where the error happens in time, and which spans of a log are events (a contact, a collision,
// a snag) rather than payload physics (docs/insight-loop.md, "Events are not physics").
//
// The detector looks at the residual (measured − predicted, S) for steps: the difference of its
// means over a window after and a window before each row, per axis, against that difference's
// own spread over the log (a robust scale: the median absolute deviation, so that coloured noise
// and smooth structure set the scale, and the few steps do not). Rows where the largest
// per-axis step stands out are change points; between them the residual sits at a level. An
// excursion is a run of levels that leaves the level before it and comes back to it (the levels
// before and after agree): a wrench that came and went, which the payload's physics, a function
// of the motion, does not do at a change point of its own. A log that holds a single change
// point gives its shorter side (a touch at the start or the end of a recording).
#include <array>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "zerog/ident/dataset.hpp"

namespace zerog::ident {

struct EventOptions {
  double window_s = 0.2;  ///< the step detector's window on each side of a row, s
  /// Threshold of the step statistic in its scale's units; 0: sqrt(2 ln(6 n / window)) + 3
  /// (the largest of n / window independent normal windows on six axes stays below it).
  double z_step = 0.0;
  /// The levels before and after a span agree within this many scale units on every axis.
  double z_agree = 4.0;
  /// More spans than this, or spans covering more than max_coverage of the rows: the pattern
  /// recurs through the log, which is physics (or a model error), not events.
  int max_events = 5;
  double max_coverage = 0.6;
  /// A span starts (ends) with motion when the robot starts or stops moving within this of it.
  double motion_tolerance_s = 0.15;
};

/// A span of rows where the residual left its level and came back.
struct Span {
  std::size_t first = 0, last = 0;  ///< rows [first, last], 0-based sample indices
  double t0_s = 0.0, t1_s = 0.0;    ///< their log times
  /// Mean of the residual in the span minus the level around it, S: the wrench the span carried
  /// (N, N·m about the S origin).
  std::array<double, 6> mean{};
  std::array<double, 6> peak{};    ///< largest deviation of a short-window mean, signed, S
  std::array<double, 6> mean_z{};  ///< `mean` in step-scale units per axis
  double z = 0.0;                  ///< largest deviation in step-scale units
  bool starts_with_motion = false, ends_with_motion = false;
  double duration_s() const { return t1_s - t0_s; }
  /// Both ends at a start or stop of the robot's motion: may be physics of the motion.
  bool tied_to_motion() const { return starts_with_motion && ends_with_motion; }
};

struct SpanScan {
  bool possible = true;
  std::string note;  ///< why there is no scan (a table without time), or empty
  double window_s = 0.0;
  std::size_t window_rows = 0;
  double z_step = 0.0;
  std::array<double, 6> scale{};  ///< spread of the step statistic per axis, N and N·m
  std::size_t change_points = 0;
  std::vector<Span> spans;  ///< in time order
  double coverage = 0.0;    ///< share of the scanned rows inside spans
  /// Too many or too long spans (EventOptions::max_events, max_coverage): not events.
  bool recurring = false;
};

/// Spans of `residuals` (one per row of `data`) that stand out. `exclude` (optional, 1 =
/// excluded) rows are neither scanned nor part of a window. A table without time (static rows)
/// gives possible = false with a note.
SpanScan find_spans(const std::vector<Wrench>& residuals, const Dataset& data,
                    const std::vector<std::uint8_t>* exclude, const EventOptions& o = {});

/// `base` (or zeros) with the rows of `spans` set to 1; n = data.size().
std::vector<std::uint8_t> span_mask(const Dataset& data, const std::vector<Span>& spans,
                                    std::vector<std::uint8_t> base = {});

/// What --exclude leaves out of a fit, compare, diagnose or ladder: log-time spans "A:B" (s, the
/// log's own time, both ends included) and data-row ranges "rows:A-B" or "row:A" (1-based, the
/// first data row of the file is 1), comma separated.
struct ExcludeSpec {
  std::vector<std::pair<double, double>> times;
  std::vector<std::pair<std::size_t, std::size_t>> rows;  ///< 1-based, inclusive
  std::string text;                                       ///< as given
  bool empty() const { return times.empty() && rows.empty(); }
};
/// Throws std::invalid_argument naming the item that is wrong.
ExcludeSpec parse_exclude(const std::string& text);
/// 1 for the rows `spec` excludes. Throws std::runtime_error when an item selects no row (naming
/// the log's time range or row count) or when nothing would be left.
std::vector<std::uint8_t> exclude_mask(const Dataset& data, const ExcludeSpec& spec,
                                       const std::string& log_name = "the log");
/// "12.34:15.67,300.00:301.20": the spans as --exclude takes them (times widened to whole
/// centiseconds outward, so that the printed span covers every row of the span).
std::string exclude_text(const std::vector<Span>& spans);

/// The residual over time: the log cut into `bins` equal spans of time (rows for a table without
/// time), the RMS per axis in each.
struct TimelineBin {
  double t0_s = 0.0, t1_s = 0.0;
  std::size_t first = 0, last = 0, count = 0;  ///< rows [first, last]; rows counted (not excluded)
  std::array<double, 6> rms{};
};
std::vector<TimelineBin> timeline(const std::vector<Wrench>& residuals, const Dataset& data,
                                  const std::vector<std::uint8_t>* exclude, int bins = 60);

nlohmann::json to_json(const Span& s);
nlohmann::json to_json(const SpanScan& s);
nlohmann::json to_json(const std::vector<TimelineBin>& t);
/// One line per span: "  312.40 - 315.46 s (3.06 s): Fx +10.1 N, ... [starts with motion]".
std::string format_spans(const std::vector<Span>& spans, const std::string& indent = "  ");

}  // namespace zerog::ident
