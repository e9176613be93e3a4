// The importer's reading phase: each data file of the mapping read into SI series (its own time
// base, the mapped quantities per row), and static tables joined by pose index.
#include "import_series.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <string_view>
#include <unordered_map>

#include "zerog/formats/detail/csv_scan.hpp"
#include "zerog/model/rotation.hpp"

namespace zerog::io::importer {

using formats::InputError;
namespace detail = formats::detail;
using formats::throw_at;

bool skippable(std::string_view line, const std::string& comment) {
  const std::string_view s = detail::trim(line);
  return s.empty() || (!comment.empty() && s.substr(0, comment.size()) == comment);
}

std::string_view unquote(std::string_view s) {
  s = detail::trim(s);
  if (s.size() >= 2 && s.front() == '"' && s.back() == '"') s = s.substr(1, s.size() - 2);
  return s;
}

// `line` is the header (or, with header = false, the first data row, which sets the width).
void resolve_columns(FileSpec& spec, const fs::path& mapping, std::string_view line,
                     int header_line) {
  std::vector<detail::Cell> cells;
  detail::split_cells(line, spec.delimiter, cells);
  std::vector<std::string_view> names;
  for (const auto& c : cells) names.push_back(unquote(c.text));
  for (ColumnRef& ref : spec.refs) {
    if (ref.number > 0) {
      if (ref.number > static_cast<int>(cells.size())) {
        throw InputError(spec.path, header_line, detail::char_column(line, line.size()),
                         "column " + std::to_string(ref.number) + " (named by " + ref.key + " at " +
                             where_text(mapping, ref.where) + ") is beyond the " +
                             std::to_string(cells.size()) + " cells of this " +
                             (spec.header ? "header" : "first row") +
                             "; columns are counted from 1 (check the delimiter)");
      }
      ref.cell = ref.number - 1;
      continue;
    }
    for (std::size_t i = 0; i < names.size(); ++i) {
      if (names[i] != ref.name) continue;
      if (ref.cell >= 0) {
        throw InputError(spec.path, header_line, detail::char_column(line, cells[i].offset),
                         "column '" + ref.name + "' appears twice in the header (first at column " +
                             std::to_string(detail::char_column(line, cells[ref.cell].offset)) +
                             "); cannot tell which one " + ref.key + " means");
      }
      ref.cell = static_cast<int>(i);
    }
    if (ref.cell >= 0) continue;
    std::string why = "column '" + ref.name + "' not found in the header (named by " + ref.key +
                      " at " + where_text(mapping, ref.where) + ")";
    const std::string_view near = detail::closest_name(ref.name, names);
    if (!near.empty()) why += "; did you mean '" + std::string(near) + "'?";
    std::string list;
    for (std::string_view n : names) list += (list.empty() ? "" : ", ") + std::string(n);
    why += "; the header has: " + detail::shorten(list, 200);
    throw InputError(spec.path, header_line, 1, why);
  }
}

Eigen::Quaterniond orientation_of_row(const QuantitySpec& q, const double* raw,
                                      const fs::path& path, int line_number, int column) {
  switch (q.orientation) {
    case Orientation::quaternion: {
      const Eigen::Quaterniond quat(raw[0], raw[1], raw[2], raw[3]);
      if (std::abs(quat.norm() - 1.0) > 1e-3) {
        throw InputError(path, line_number, column,
                         "quaternion has norm " + num(quat.norm()) +
                             ", off from 1 by more than 1e-3 (check the column order)");
      }
      return quat.normalized();
    }
    case Orientation::matrix: {
      Eigen::Matrix3d R;
      R << raw[0], raw[1], raw[2], raw[3], raw[4], raw[5], raw[6], raw[7], raw[8];
      const double error = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
      if (error > 1e-3 || R.determinant() < 0.0) {
        throw InputError(path, line_number, column,
                         "rotation matrix r11…r33 is not a rotation (max |RᵀR − I| = " +
                             num(error) + ", det = " + num(R.determinant()) + ")");
      }
      return Eigen::Quaterniond(R).normalized();
    }
    case Orientation::kuka_abc:
      return Eigen::Quaterniond(model::rotation_from_kuka_abc(raw[0] * q.scale, raw[1] * q.scale,
                                                              raw[2] * q.scale))
          .normalized();
  }
  return Eigen::Quaterniond::Identity();
}

// One row's mapped values in SI appended to the series: a fixed frame's vectors rotated into the
// own frame, orientations checked and kept in one hemisphere (`line`, `cells` and `n` place an
// error in the data file).
void store_row(const FileSpec& spec, const double* raw, std::string_view line,
               const std::vector<detail::Cell>& cells, int n, Series& series) {
  for (const QuantitySpec& q : spec.quantities) {
    auto& out = series.values[static_cast<int>(q.what)];
    const double* r = raw + q.first_ref;
    if (q.frame == VectorFrame::fixed) {  // v_own = R_own,D v_D (constant: before merging)
      const Eigen::Vector3d v = q.R_own_fixed * (Eigen::Vector3d(r[0], r[1], r[2]) * q.scale);
      out.insert(out.end(), {v.x(), v.y(), v.z()});
      continue;
    }
    if (q.what != Quantity::orientation) {
      // Without an offset, no addition: −0 + 0 would read a logged −0 as +0.
      for (int k = 0; k < q.num_refs; ++k)
        out.push_back(q.offset == 0.0 ? r[k] * q.scale : r[k] * q.scale + q.offset);
      continue;
    }
    std::size_t leftmost = line.size();
    for (int k = 0; k < q.num_refs; ++k) {
      leftmost = std::min(leftmost, cells[spec.refs[q.first_ref + k].cell].offset);
    }
    Eigen::Quaterniond quat =
        orientation_of_row(q, r, spec.path, n, detail::char_column(line, leftmost));
    const std::size_t size = out.size();
    if (size >= 4) {  // keep neighbours in the same hemisphere
      const Eigen::Quaterniond previous(out[size - 4], out[size - 3], out[size - 2], out[size - 1]);
      if (previous.dot(quat) < 0.0) quat.coeffs() = -quat.coeffs();
    }
    out.insert(out.end(), {quat.w(), quat.x(), quat.y(), quat.z()});
  }
}

Series read_series(FileSpec& spec, const fs::path& mapping) {
  std::error_code ec;
  if (!fs::is_regular_file(spec.path, ec)) {
    throw_at(mapping, spec.path_where, "data file not found: " + spec.path.string());
  }
  const std::string text = detail::read_whole_file(spec.path);
  detail::LineCursor lines(text);
  std::string_view line;
  for (int i = 0; i < spec.skip_lines; ++i) {
    if (!lines.next(line)) {
      throw InputError(
          spec.path, lines.number() + 1, 1,
          "file ends within the first skip_lines = " + std::to_string(spec.skip_lines) + " lines");
    }
  }
  bool have_header = false;
  while (lines.next(line)) {
    if (lines.number() == 1 && line.substr(0, 3) == "\xEF\xBB\xBF") line.remove_prefix(3);
    if (skippable(line, spec.comment)) continue;
    have_header = true;
    break;
  }
  if (!have_header) {
    throw InputError(spec.path, lines.number() + 1, 1,
                     spec.header ? "no header row (column names)" : "no data rows");
  }
  const int header_line = lines.number();
  resolve_columns(spec, mapping, line, header_line);
  std::vector<detail::Cell> cells;
  detail::split_cells(line, spec.delimiter, cells);
  const std::size_t num_cells = cells.size();
  // Without a header the line just read is the first data row.
  bool pending_row = !spec.header;
  std::unordered_map<double, int> index_lines;  // pose index -> its line (has_index)

  Series series;
  std::vector<double> raw(spec.refs.size());
  int previous_line = 0;
  double previous_raw_t = 0.0;
  while (pending_row || lines.next(line)) {
    pending_row = false;
    if (skippable(line, spec.comment)) continue;
    const int n = lines.number();
    detail::split_cells(line, spec.delimiter, cells);
    if (cells.size() != num_cells) {
      const bool extra = cells.size() > num_cells;
      throw InputError(spec.path, n,
                       detail::char_column(line, extra ? cells[num_cells].offset : line.size()),
                       "row has " + std::to_string(cells.size()) + " cells but the " +
                           (spec.header ? "header has " : "first row has ") +
                           std::to_string(num_cells) + " (delimiter: " +
                           (spec.delimiter == ' '    ? std::string("whitespace")
                            : spec.delimiter == '\t' ? std::string("tab")
                                                     : "'" + std::string(1, spec.delimiter) + "'") +
                           ")");
    }
    for (std::size_t j = 0; j < spec.refs.size(); ++j) {
      const detail::Cell& cell = cells[spec.refs[j].cell];
      const auto status = detail::parse_number(unquote(cell.text), raw[j], spec.decimal);
      if (status == detail::NumberStatus::ok) continue;
      const std::string why = detail::number_error(status, unquote(cell.text), spec.refs[j].name);
      throw InputError(spec.path, n, detail::char_column(line, cell.offset), why);
    }
    const double t = spec.has_time    ? raw[0] * spec.time_scale + spec.time_offset_s
                     : spec.has_index ? raw[0]
                                      : static_cast<double>(series.t.size());
    if (spec.has_index) {
      const int column = detail::char_column(line, cells[spec.refs[0].cell].offset);
      if (t != std::floor(t))
        throw InputError(
            spec.path, n, column,
            "pose index " + num(t) + " (column '" + spec.refs[0].name + "') is not a whole number");
      const auto [seen, fresh] = index_lines.emplace(t, n);
      if (!fresh)
        throw InputError(spec.path, n, column,
                         "pose index " + num(t) + " (column '" + spec.refs[0].name +
                             "') is at line " + std::to_string(seen->second) +
                             " already: each pose once per file");
    }
    if (spec.has_time && !series.t.empty() && !(t > series.t.back())) {
      throw InputError(spec.path, n, detail::char_column(line, cells[spec.refs[0].cell].offset),
                       std::string("time ") +
                           (raw[0] < previous_raw_t ? "goes backwards" : "stands still") +
                           " at line " + std::to_string(n) + ": t=" + num(raw[0]) + " after " +
                           num(previous_raw_t) + " (line " + std::to_string(previous_line) +
                           ", column '" + spec.refs[0].name + "', " + spec.time_unit + ")");
    }
    series.t.push_back(t);
    previous_line = n;
    previous_raw_t = raw[0];

    store_row(spec, raw.data(), line, cells, n, series);
  }
  if (series.t.empty()) {
    throw InputError(spec.path, header_line + 1, 1,
                     spec.header ? "no data rows after the header" : "no data rows");
  }
  return series;
}

// Keeps `rows` of a series (in that order), renumbering them 0, 1, … (a static table's time).
void select_rows(Series& s, const std::vector<std::size_t>& rows) {
  const std::size_t old_rows = s.t.size();
  for (auto& v : s.values) {
    if (v.empty()) continue;
    const std::size_t width = v.size() / old_rows;
    std::vector<double> kept;
    kept.reserve(rows.size() * width);
    for (std::size_t r : rows)
      kept.insert(kept.end(), v.begin() + r * width, v.begin() + (r + 1) * width);
    v = std::move(kept);
  }
  s.t.resize(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) s.t[i] = static_cast<double>(i);
}

// Static tables joined by pose index: the master's rows in its order, each other file's row with
// the same index beside it. A master row whose index another file lacks is dropped (counted for
// that file), as are other files' rows whose index the master lacks (counted, not used).
void join_by_pose_index(std::vector<Series>& series, ImportReport& report) {
  std::vector<std::unordered_map<double, std::size_t>> row_of(series.size());
  for (std::size_t f = 1; f < series.size(); ++f)
    for (std::size_t j = 0; j < series[f].t.size(); ++j) row_of[f].emplace(series[f].t[j], j);
  std::vector<std::vector<std::size_t>> keep(series.size());
  for (std::size_t i = 0; i < series.front().t.size(); ++i) {
    bool all = true;
    for (std::size_t f = 1; f < series.size(); ++f) {
      if (row_of[f].count(series.front().t[i]) != 0) continue;
      ++report.files[f].master_rows_unmatched;
      all = false;
    }
    if (!all) continue;
    keep.front().push_back(i);
    for (std::size_t f = 1; f < series.size(); ++f)
      keep[f].push_back(row_of[f].at(series.front().t[i]));
  }
  for (std::size_t f = 0; f < series.size(); ++f) {
    if (f > 0) report.files[f].rows_unused = series[f].t.size() - keep[f].size();
    select_rows(series[f], keep[f]);
  }
}
}  // namespace zerog::io::importer
