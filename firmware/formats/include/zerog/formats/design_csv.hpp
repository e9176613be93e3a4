#pragma once
// The design CSV (proto/design_format.md): the path points of a calibration run, A1..A6 in rad,
// written by `zerog design` (host/sim makes the design) and read by `zerog sim --design` and by
// zerog-rt's collection mode. Writer and reader live together. Host and start-up code: allocates
// and throws; not real-time safe.
#include <array>
#include <filesystem>
#include <iosfwd>
#include <string>
#include <string_view>
#include <vector>

namespace zerog::formats {

/// Line 1 of every design CSV: the format version.
inline constexpr std::string_view kDesignMagic = "# zerog-design 1";

/// One path point: the KUKA joint angles A1..A6, rad, as the controller reports them.
using DesignPoint = std::array<double, 6>;

/// The whole CSV text: the magic line, `# <comment>` (the writer's note on how the design was
/// made; none if empty), the header and one row per point (C locale, `%.12g`).
std::string design_csv_text(const std::string& comment, const std::vector<DesignPoint>& points_rad);

/// Reads the next line of a design or attitude CSV that is neither blank nor a `#` comment (a
/// trailing CR dropped) and splits it at commas: the cells, and the 1-based column where each
/// starts (for InputError). `line_no` counts every line read. False at the end of `in`.
bool read_design_line(std::istream& in, int& line_no, std::vector<std::string>& cells,
                      std::vector<int>& columns);

/// Reads a design CSV; throws formats::InputError naming file, line and column
/// (proto/design_format.md).
std::vector<DesignPoint> read_design(const std::filesystem::path& path);

}  // namespace zerog::formats
