#include "zerog/io/import.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <string_view>

#include "csv_scan.hpp"
#include "toml_table.hpp"
#include "zerog/model/effects.hpp"
#include "zerog/model/rotation.hpp"

namespace zerog::io {

namespace fs = std::filesystem;

namespace {

using detail::throw_at;
using detail::TomlTable;

// ---------------------------------------------------------------------------------------------
// What a mapping can name, and in which units (proto/import_mapping.md).

enum class Quantity : int {
  force,
  torque,
  position,
  orientation,
  joints,
  specific_force,
  angular_rate,
  temperature
};
constexpr int kQuantityCount = 8;

enum class Orientation { quaternion, matrix, kuka_abc };

struct Unit {
  std::string_view name;
  double scale;
  double offset = 0.0;  ///< SI value = file value × scale + offset
};

constexpr double kDegree = std::numbers::pi / 180.0;

struct QuantityInfo {
  std::string_view key;      ///< key in a [files.NAME] table
  int width;                 ///< columns in the file (orientation: by type)
  int stored;                ///< values kept per row
  std::vector<Unit> units;   ///< accepted units; empty = unitless
  std::string_view meaning;  ///< for messages
};

const std::array<QuantityInfo, kQuantityCount>& quantity_infos() {
  static const std::array<QuantityInfo, kQuantityCount> infos = {{
      {"force", 3, 3, {{"N", 1.0}, {"kN", 1e3}}, "force on the sensor, sensor frame"},
      {"torque",
       3,
       3,
       {{"N*m", 1.0}, {"Nm", 1.0}, {"N*mm", 1e-3}, {"Nmm", 1e-3}},
       "torque about the sensor origin, sensor frame"},
      {"position", 3, 3, {{"m", 1.0}, {"mm", 1e-3}}, "sensor (or flange) origin in the base frame"},
      {"orientation",
       0,
       4,
       {{"rad", 1.0}, {"deg", kDegree}},
       "sensor (or flange) axes in the base"},
      {"joints", 6, 6, {{"rad", 1.0}, {"deg", kDegree}}, "joint angles A1..A6"},
      {"specific_force",
       3,
       3,
       {{"m/s^2", 1.0}, {"m/s2", 1.0}, {"g", model::kStandardGravity}},
       "IMU specific force (accelerometer), IMU frame"},
      {"angular_rate",
       3,
       3,
       {{"rad/s", 1.0}, {"deg/s", kDegree}},
       "IMU angular rate (gyroscope), IMU frame"},
      {"temperature", 1, 1, {{"C", 1.0}, {"degC", 1.0}, {"K", 1.0, -273.15}}, "temperature"},
  }};
  return infos;
}

const QuantityInfo& info(Quantity q) { return quantity_infos()[static_cast<int>(q)]; }

const std::vector<Unit> kTimeUnits = {
    {"s", 1.0}, {"ms", 1e-3}, {"us", 1e-6}, {"µs", 1e-6}, {"ns", 1e-9}};

std::string unit_list(const std::vector<Unit>& units) {
  std::string out;
  for (const Unit& u : units) out += (out.empty() ? "\"" : ", \"") + std::string(u.name) + "\"";
  return out;
}

std::string num(double v) { return detail::number_text(v); }

std::string where_text(const fs::path& file, const toml::source_region& where) {
  return file.filename().string() + ":" + std::to_string(where.begin.line) + ":" +
         std::to_string(where.begin.column);
}

// ---------------------------------------------------------------------------------------------
// The mapping, read.

struct ColumnRef {
  std::string name;           ///< header name in the data file
  toml::source_region where;  ///< where the mapping names it
  std::string key;            ///< mapping key naming it, e.g. "files.ft.force"
  int cell = -1;              ///< resolved cell index in the data file
};

struct QuantitySpec {
  Quantity what;
  int first_ref = 0;  ///< index of its first column in FileSpec::refs
  int num_refs = 0;
  double scale = 1.0;
  double offset = 0.0;
  Orientation orientation = Orientation::quaternion;
  toml::source_region where;
};

struct FileSpec {
  std::string name;
  fs::path path;
  toml::source_region path_where;
  char delimiter = ',';
  char decimal = '.';
  std::string comment = "#";
  int skip_lines = 0;
  std::string time_unit;
  double time_scale = 1.0;
  double time_offset_s = 0.0;
  double max_gap_s = std::numeric_limits<double>::infinity();
  std::vector<ColumnRef> refs;  ///< refs[0] is the time column
  std::vector<QuantitySpec> quantities;
};

struct Mapping {
  std::vector<FileSpec> files;  ///< master first
  bool pose_of_flange = false;
  std::optional<Rig> rig;      ///< from the [rig] table
  bool rig_has_period = true;  ///< the [rig] table gave sample_period_s
  std::optional<fs::path> rig_file;
};

const Unit& find_unit(const TomlTable& t, const std::vector<Unit>& units) {
  const std::string unit = t.string("unit");
  for (const Unit& u : units) {
    if (u.name == unit) return u;
  }
  throw_at(t.file(), t.require("unit").source(),
           "unknown unit \"" + unit + "\" for '" + t.name("unit") + "' (use one of " +
               unit_list(units) + ")");
}

void add_ref(FileSpec& file, const TomlTable& t, std::string_view key, std::string name) {
  ColumnRef ref;
  ref.name = std::move(name);
  ref.where = t.require(key).source();
  ref.key = t.name(key);
  file.refs.push_back(std::move(ref));
}

void read_quantity(FileSpec& file, Quantity what, const TomlTable& parent) {
  const QuantityInfo& qi = info(what);
  const toml::node& node = parent.require(qi.key);
  if (!node.is_table()) {
    throw_at(parent.file(), node.source(),
             "'" + parent.name(qi.key) + "' must be a table, e.g. { columns = [...], unit = ... }");
  }
  const std::string prefix = parent.name(qi.key) + ".";
  QuantitySpec q;
  q.what = what;
  q.where = node.source();
  q.first_ref = static_cast<int>(file.refs.size());
  if (what == Quantity::temperature) {
    const TomlTable t(*node.as_table(), parent.file(), prefix, {"column", "unit"});
    add_ref(file, t, "column", t.string("column"));
    const Unit& u = find_unit(t, qi.units);
    q.scale = u.scale;
    q.offset = u.offset;
  } else if (what == Quantity::orientation) {
    const TomlTable t(*node.as_table(), parent.file(), prefix,
                      {"type", "columns", "order", "unit"});
    const std::string type = t.string("type");
    const auto& type_where = t.require("type").source();
    if (type == "quaternion") {
      q.orientation = Orientation::quaternion;
      const std::string order = t.optional_string("order", "wxyz");
      if (order != "wxyz" && order != "xyzw") {
        throw_at(t.file(), t.require("order").source(),
                 "'" + t.name("order") + "' must be \"wxyz\" or \"xyzw\"");
      }
      auto names = t.strings("columns", 4);
      if (order == "xyzw") std::rotate(names.begin(), names.begin() + 3, names.end());
      for (auto& n : names) add_ref(file, t, "columns", n);
    } else if (type == "matrix") {
      q.orientation = Orientation::matrix;
      for (auto& n : t.strings("columns", 9)) add_ref(file, t, "columns", n);
    } else if (type == "kuka_abc") {
      q.orientation = Orientation::kuka_abc;
      for (auto& n : t.strings("columns", 3)) add_ref(file, t, "columns", n);
      q.scale = find_unit(t, qi.units).scale;
    } else {
      throw_at(t.file(), type_where,
               "'" + t.name("type") + "' must be \"quaternion\", \"matrix\" or \"kuka_abc\"");
    }
    if (q.orientation != Orientation::kuka_abc && t.find("unit") != nullptr) {
      throw_at(t.file(), t.require("unit").source(),
               "'" + t.name("unit") + "': a " + type + " has no unit");
    }
    if (q.orientation != Orientation::quaternion && t.find("order") != nullptr) {
      throw_at(t.file(), t.require("order").source(),
               "'" + t.name("order") + "' applies to type = \"quaternion\" only");
    }
  } else {
    const TomlTable t(*node.as_table(), parent.file(), prefix, {"columns", "unit"});
    for (auto& n : t.strings("columns", static_cast<std::size_t>(qi.width))) {
      add_ref(file, t, "columns", n);
    }
    const Unit& u = find_unit(t, qi.units);
    q.scale = u.scale;
    q.offset = u.offset;
  }
  q.num_refs = static_cast<int>(file.refs.size()) - q.first_ref;
  file.quantities.push_back(q);
}

char read_delimiter(const TomlTable& t) {
  const std::string d = t.optional_string("delimiter", "comma");
  if (d == "comma" || d == ",") return ',';
  if (d == "semicolon" || d == ";") return ';';
  if (d == "tab" || d == "\t") return '\t';
  if (d == "whitespace" || d == " ") return ' ';
  throw_at(t.file(), t.require("delimiter").source(),
           "'" + t.name("delimiter") +
               "' must be \"comma\", \"semicolon\", \"tab\" or \"whitespace\", is \"" + d + "\"");
}

FileSpec read_file_spec(const std::string& name, const toml::node& node, const fs::path& mapping) {
  const std::string prefix = "files." + name + ".";
  if (!node.is_table()) throw_at(mapping, node.source(), "'files." + name + "' must be a table");
  std::vector<std::string_view> known = {"path",       "delimiter", "decimal",       "comment",
                                         "skip_lines", "time",      "time_offset_s", "max_gap_s"};
  for (const auto& qi : quantity_infos()) known.push_back(qi.key);
  const TomlTable t(*node.as_table(), mapping, prefix, known);

  FileSpec file;
  file.name = name;
  fs::path path = t.string("path");
  file.path = path.is_absolute() ? path : mapping.parent_path() / path;
  file.path_where = t.require("path").source();
  file.delimiter = read_delimiter(t);
  const std::string decimal = t.optional_string("decimal", ".");
  if (decimal != "." && decimal != ",") {
    throw_at(mapping, t.require("decimal").source(),
             "'" + t.name("decimal") + "' must be \".\" or \",\"");
  }
  file.decimal = decimal[0];
  if (file.decimal == ',' && file.delimiter == ',') {
    throw_at(mapping, t.require("decimal").source(),
             "a decimal comma needs another delimiter (semicolon, tab or whitespace)");
  }
  file.comment = t.optional_string("comment", "#");
  if (const toml::node* skip = t.find("skip_lines")) {
    const std::int64_t n = t.integer("skip_lines");
    if (n < 0 || n > 1000000)
      throw_at(mapping, skip->source(), "'" + t.name("skip_lines") + "' must be >= 0");
    file.skip_lines = static_cast<int>(n);
  }

  const toml::node& time_node = t.require("time");
  if (!time_node.is_table()) {
    throw_at(mapping, time_node.source(),
             "'" + t.name("time") + "' must be a table, e.g. { column = \"t\", unit = \"s\" }");
  }
  const TomlTable time(*time_node.as_table(), mapping, prefix + "time.", {"column", "unit"});
  add_ref(file, time, "column", time.string("column"));
  const Unit& time_unit = find_unit(time, kTimeUnits);
  file.time_unit = time_unit.name;
  file.time_scale = time_unit.scale;
  if (t.find("time_offset_s") != nullptr) {
    file.time_offset_s = t.number(t.require("time_offset_s"), "time_offset_s");
  }
  if (t.find("max_gap_s") != nullptr) file.max_gap_s = t.number("max_gap_s", 0.0, true);

  for (int q = 0; q < kQuantityCount; ++q) {
    if (t.find(quantity_infos()[q].key) != nullptr) read_quantity(file, Quantity(q), t);
  }
  return file;
}

Mapping read_mapping(const fs::path& mapping, bool rig_given) {
  const toml::table root = detail::parse_toml_file(mapping);
  const TomlTable top(root, mapping, "",
                      {"format", "version", "master", "pose_of", "rig_file", "rig", "files"});
  if (top.string("format") != "zerog-import") {
    throw_at(mapping, top.require("format").source(),
             "'format' must be \"zerog-import\" (this is not an import mapping)");
  }
  if (top.integer("version") != kImportMappingVersion) {
    throw_at(mapping, top.require("version").source(),
             "mapping version " + std::to_string(top.integer("version")) +
                 " is not supported (this zerog reads version " +
                 std::to_string(kImportMappingVersion) + ")");
  }

  Mapping m;
  const toml::table& files = top.table("files");
  for (const auto& [key, node] : files) {
    m.files.push_back(read_file_spec(std::string(key.str()), node, mapping));
  }
  if (m.files.empty()) {
    throw_at(mapping, files.source(), "'files' is empty: name at least one [files.NAME] table");
  }

  std::string names;
  for (const FileSpec& f : m.files) names += (names.empty() ? "'" : "', '") + f.name;
  names += "'";
  std::size_t master = 0;
  if (top.find("master") != nullptr) {
    const std::string wanted = top.string("master");
    while (master < m.files.size() && m.files[master].name != wanted) ++master;
    if (master == m.files.size()) {
      throw_at(mapping, top.require("master").source(),
               "master '" + wanted + "' is not one of the files (" + names + ")");
    }
  } else if (m.files.size() > 1) {
    throw_at(mapping, root.source(),
             "missing key 'master': which file's time stamps become the log rows? (one of " +
                 names + ")");
  }
  std::rotate(m.files.begin(), m.files.begin() + static_cast<std::ptrdiff_t>(master),
              m.files.begin() + static_cast<std::ptrdiff_t>(master) + 1);

  const std::string pose_of = top.optional_string("pose_of", "sensor");
  if (pose_of != "sensor" && pose_of != "flange") {
    throw_at(mapping, top.require("pose_of").source(),
             "'pose_of' must be \"sensor\" or \"flange\"");
  }
  m.pose_of_flange = pose_of == "flange";

  if (top.find("rig") != nullptr && top.find("rig_file") != nullptr) {
    throw_at(mapping, top.require("rig_file").source(),
             "give either 'rig_file' or a [rig] table, not both");
  }
  if (top.find("rig") != nullptr) {
    m.rig = detail::rig_from_toml(top.table("rig"), mapping, true, "rig.", &m.rig_has_period);
  } else if (top.find("rig_file") != nullptr) {
    const fs::path p = top.string("rig_file");
    m.rig_file = p.is_absolute() ? p : mapping.parent_path() / p;
  } else if (!rig_given) {
    throw_at(mapping, root.source(),
             "no rig: give a [rig] table or rig_file = \"NAME.rig.toml\" in the mapping, or --rig");
  }

  // Every quantity from exactly one file; the required ones present; the IMU pair together.
  std::array<const FileSpec*, kQuantityCount> source{};
  std::array<toml::source_region, kQuantityCount> where{};
  for (const FileSpec& f : m.files) {
    for (const QuantitySpec& q : f.quantities) {
      const int i = static_cast<int>(q.what);
      if (source[i] != nullptr) {
        throw_at(mapping, q.where,
                 "'" + std::string(info(q.what).key) + "' is mapped twice: here and in files." +
                     source[i]->name + " (line " + std::to_string(where[i].begin.line) + ")");
      }
      source[i] = &f;
      where[i] = q.where;
    }
  }
  for (Quantity q :
       {Quantity::force, Quantity::torque, Quantity::position, Quantity::orientation}) {
    if (source[static_cast<int>(q)] == nullptr) {
      throw_at(mapping, files.source(),
               "no file maps '" + std::string(info(q).key) + "' (" + std::string(info(q).meaning) +
                   "); a log needs force, torque, position and orientation");
    }
  }
  const int f = static_cast<int>(Quantity::specific_force);
  const int w = static_cast<int>(Quantity::angular_rate);
  if ((source[f] == nullptr) != (source[w] == nullptr)) {
    const int given = source[f] != nullptr ? f : w;
    throw_at(mapping, where[given],
             "'" + std::string(info(Quantity(given)).key) + "' needs '" +
                 std::string(info(Quantity(given == f ? w : f)).key) +
                 "' too (the IMU columns go together)");
  }
  return m;
}

// ---------------------------------------------------------------------------------------------
// Data files, read into SI series.

struct Series {
  std::vector<double> t;
  std::array<std::vector<double>, kQuantityCount> values;  ///< `stored` values per row
};

bool skippable(std::string_view line, const std::string& comment) {
  const std::string_view s = detail::trim(line);
  return s.empty() || (!comment.empty() && s.substr(0, comment.size()) == comment);
}

std::string_view unquote(std::string_view s) {
  s = detail::trim(s);
  if (s.size() >= 2 && s.front() == '"' && s.back() == '"') s = s.substr(1, s.size() - 2);
  return s;
}

void resolve_columns(FileSpec& spec, const fs::path& mapping, std::string_view line,
                     int header_line) {
  std::vector<detail::Cell> cells;
  detail::split_cells(line, spec.delimiter, cells);
  std::vector<std::string_view> names;
  for (const auto& c : cells) names.push_back(unquote(c.text));
  for (ColumnRef& ref : spec.refs) {
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
    throw InputError(spec.path, lines.number() + 1, 1, "no header row (column names)");
  }
  const int header_line = lines.number();
  resolve_columns(spec, mapping, line, header_line);
  std::vector<detail::Cell> cells;
  detail::split_cells(line, spec.delimiter, cells);
  const std::size_t num_cells = cells.size();

  Series series;
  std::vector<double> raw(spec.refs.size());
  int previous_line = 0;
  double previous_raw_t = 0.0;
  while (lines.next(line)) {
    if (skippable(line, spec.comment)) continue;
    const int n = lines.number();
    detail::split_cells(line, spec.delimiter, cells);
    if (cells.size() != num_cells) {
      const bool extra = cells.size() > num_cells;
      throw InputError(spec.path, n,
                       detail::char_column(line, extra ? cells[num_cells].offset : line.size()),
                       "row has " + std::to_string(cells.size()) + " cells but the header has " +
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
    const double t = raw[0] * spec.time_scale + spec.time_offset_s;
    if (!series.t.empty() && !(t > series.t.back())) {
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

    for (const QuantitySpec& q : spec.quantities) {
      auto& out = series.values[static_cast<int>(q.what)];
      const double* r = raw.data() + q.first_ref;
      if (q.what != Quantity::orientation) {
        for (int k = 0; k < q.num_refs; ++k) out.push_back(r[k] * q.scale + q.offset);
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
        const Eigen::Quaterniond previous(out[size - 4], out[size - 3], out[size - 2],
                                          out[size - 1]);
        if (previous.dot(quat) < 0.0) quat.coeffs() = -quat.coeffs();
      }
      out.insert(out.end(), {quat.w(), quat.x(), quat.y(), quat.z()});
    }
  }
  if (series.t.empty()) {
    throw InputError(spec.path, header_line + 1, 1, "no data rows after the header");
  }
  return series;
}

// ---------------------------------------------------------------------------------------------
// Merging onto the master's time base.

/// Where a master time falls in another file: between rows k0 and k1, fraction alpha.
struct Bracket {
  std::size_t k0 = 0;
  std::size_t k1 = 0;
  double alpha = 0.0;
};

template <int N>
Eigen::Matrix<double, N, 1> at(const std::vector<double>& v, const Bracket& b) {
  const Eigen::Map<const Eigen::Matrix<double, N, 1>> a(v.data() + b.k0 * N);
  const Eigen::Map<const Eigen::Matrix<double, N, 1>> c(v.data() + b.k1 * N);
  return a + b.alpha * (c - a);
}

Eigen::Quaterniond quaternion_at(const std::vector<double>& v, const Bracket& b) {
  const Eigen::Quaterniond a(v[b.k0 * 4], v[b.k0 * 4 + 1], v[b.k0 * 4 + 2], v[b.k0 * 4 + 3]);
  const Eigen::Quaterniond c(v[b.k1 * 4], v[b.k1 * 4 + 1], v[b.k1 * 4 + 2], v[b.k1 * 4 + 3]);
  return b.alpha == 0.0 ? a : a.slerp(b.alpha, c).normalized();
}

double median_period(const std::vector<double>& t) {
  if (t.size() < 2) return 0.0;
  std::vector<double> dt(t.size() - 1);
  for (std::size_t i = 1; i < t.size(); ++i) dt[i - 1] = t[i] - t[i - 1];
  std::nth_element(dt.begin(), dt.begin() + static_cast<std::ptrdiff_t>(dt.size() / 2), dt.end());
  return dt[dt.size() / 2];
}

}  // namespace

// -------------------------------------------------------------------------------------------------

ImportResult import_recordings(const fs::path& mapping_path,
                               const std::optional<fs::path>& rig_file) {
  Mapping mapping = read_mapping(mapping_path, rig_file.has_value());
  ImportResult result;
  result.inputs.push_back(mapping_path);

  std::vector<Series> series;
  for (FileSpec& f : mapping.files) {
    series.push_back(read_series(f, mapping_path));
    result.inputs.push_back(f.path);
    ImportFileReport r;
    r.name = f.name;
    r.path = f.path;
    r.master = result.report.files.empty();
    r.rows_read = series.back().t.size();
    r.t_first_s = series.back().t.front();
    r.t_last_s = series.back().t.back();
    r.time_offset_s = f.time_offset_s;
    result.report.files.push_back(r);
  }

  // The rig.
  Log& log = result.log;
  if (rig_file) {
    log.rig = read_rig(*rig_file);
    result.inputs.push_back(*rig_file);
    result.report.rig_source =
        rig_file->string() +
        (mapping.rig || mapping.rig_file ? " (--rig, replacing the mapping's rig)" : " (--rig)");
  } else if (mapping.rig_file) {
    log.rig = read_rig(*mapping.rig_file);
    result.inputs.push_back(*mapping.rig_file);
    result.report.rig_source = mapping.rig_file->string() + " (the mapping's rig_file)";
  } else {
    log.rig = *mapping.rig;
    result.report.rig_source = "the mapping's [rig] table";
    if (!mapping.rig_has_period) {
      log.rig.sample_period_s = median_period(series.front().t);
      if (!(log.rig.sample_period_s > 0.0)) log.rig.sample_period_s = 1.0;
      result.report.rig_source +=
          ", sample_period_s = " + num(log.rig.sample_period_s) + " s (median of the master)";
    }
  }

  // Which file provides each quantity.
  std::array<int, kQuantityCount> source;
  source.fill(-1);
  for (std::size_t f = 0; f < mapping.files.size(); ++f) {
    for (const QuantitySpec& q : mapping.files[f].quantities) {
      source[static_cast<int>(q.what)] = static_cast<int>(f);
    }
  }
  auto has = [&](Quantity q) { return source[static_cast<int>(q)] >= 0; };
  log.columns.joints = has(Quantity::joints);
  log.columns.imu = has(Quantity::specific_force);
  log.columns.temperature = has(Quantity::temperature);

  const std::vector<double>& t_master = series.front().t;
  result.report.master_rows = t_master.size();
  std::vector<Bracket> brackets(mapping.files.size());
  std::vector<std::size_t> cursor(mapping.files.size(), 0);
  log.samples.reserve(t_master.size());
  for (std::size_t i = 0; i < t_master.size(); ++i) {
    const double t = t_master[i];
    bool keep = true;
    brackets[0] = {i, i, 0.0};
    for (std::size_t f = 1; f < mapping.files.size(); ++f) {
      const std::vector<double>& tf = series[f].t;
      ImportFileReport& r = result.report.files[f];
      if (t < tf.front()) {
        ++r.master_rows_before;
        keep = false;
        continue;
      }
      if (t > tf.back()) {
        ++r.master_rows_after;
        keep = false;
        continue;
      }
      std::size_t& k = cursor[f];
      while (k + 1 < tf.size() && tf[k + 1] < t) ++k;
      Bracket& b = brackets[f];
      if (k + 1 == tf.size() || tf[k] == t) {
        b = {k, k, 0.0};
      } else {
        b = {k, k + 1, (t - tf[k]) / (tf[k + 1] - tf[k])};
        if (b.alpha < 1.0 && tf[k + 1] - tf[k] > mapping.files[f].max_gap_s) {
          ++r.master_rows_in_gap;
          keep = false;
        }
      }
    }
    if (!keep) continue;

    Sample& s = log.samples.emplace_back();
    s.t_s = t;
    auto values = [&](Quantity q) -> const std::vector<double>& {
      return series[source[static_cast<int>(q)]].values[static_cast<int>(q)];
    };
    auto bracket = [&](Quantity q) -> const Bracket& {
      return brackets[source[static_cast<int>(q)]];
    };
    s.force_sensor_N = at<3>(values(Quantity::force), bracket(Quantity::force));
    s.torque_sensor_Nm = at<3>(values(Quantity::torque), bracket(Quantity::torque));
    s.p_base_sensor_m = at<3>(values(Quantity::position), bracket(Quantity::position));
    s.q_base_sensor = quaternion_at(values(Quantity::orientation), bracket(Quantity::orientation));
    if (mapping.pose_of_flange) {  // p_BS = p_BF + R_BF p_FS, R_BS = R_BF R_FS (frames.md)
      s.p_base_sensor_m += s.q_base_sensor * log.rig.flange_sensor.p_m;
      s.q_base_sensor = (s.q_base_sensor * log.rig.flange_sensor.q).normalized();
    }
    if (log.columns.joints) {
      const Eigen::Matrix<double, 6, 1> q =
          at<6>(values(Quantity::joints), bracket(Quantity::joints));
      for (int j = 0; j < 6; ++j) s.joints_rad[j] = q[j];
    }
    if (log.columns.imu) {
      s.specific_force_imu_mps2 =
          at<3>(values(Quantity::specific_force), bracket(Quantity::specific_force));
      s.angular_rate_imu_radps =
          at<3>(values(Quantity::angular_rate), bracket(Quantity::angular_rate));
    }
    if (log.columns.temperature) {
      s.temperature_C = at<1>(values(Quantity::temperature), bracket(Quantity::temperature))[0];
    }
  }
  result.report.rows_out = log.samples.size();
  if (log.samples.empty()) {
    throw std::runtime_error("nothing to import: none of the " + std::to_string(t_master.size()) +
                             " master rows lies within the time span of every file (check "
                             "time units and time_offset_s)\n" +
                             result.report.summary());
  }
  return result;
}

ImportReport import_to_log(const fs::path& mapping, const fs::path& out_csv,
                           const std::optional<fs::path>& rig_file) {
  ImportResult result = import_recordings(mapping, rig_file);
  write_log(result.log, out_csv, result.inputs);
  return result.report;
}

std::string ImportReport::summary() const {
  std::string out;
  char buffer[512];
  const std::string master = files.empty() ? std::string("?") : files.front().name;
  std::snprintf(buffer, sizeof buffer, "%zu file%s merged onto the time base of '%s':\n",
                files.size(), files.size() == 1 ? "" : "s", master.c_str());
  out += buffer;
  std::size_t width = 4;
  for (const auto& f : files) width = std::max(width, f.name.size());
  for (const auto& f : files) {
    const double span = f.t_last_s - f.t_first_s;
    const double rate = span > 0.0 ? static_cast<double>(f.rows_read - 1) / span : 0.0;
    std::snprintf(buffer, sizeof buffer, "  %-*s %9zu rows  %10.4f … %10.4f s  %8.1f Hz  %s",
                  static_cast<int>(width), f.name.c_str(), f.rows_read, f.t_first_s, f.t_last_s,
                  rate, f.path.filename().string().c_str());
    out += buffer;
    if (f.master) out += "  (master)";
    if (f.time_offset_s != 0.0) out += "  (time offset " + num(f.time_offset_s) + " s)";
    out += '\n';
  }
  const std::size_t dropped = master_rows - rows_out;
  std::snprintf(buffer, sizeof buffer, "rows out: %zu of %zu master rows (%zu dropped)\n", rows_out,
                master_rows, dropped);
  out += buffer;
  for (const auto& f : files) {
    if (f.master) continue;
    const std::pair<std::size_t, const char*> reasons[] = {
        {f.master_rows_before, "before the first sample"},
        {f.master_rows_after, "after the last sample"},
        {f.master_rows_in_gap, "in a gap longer than max_gap_s"}};
    for (const auto& [count, why] : reasons) {
      if (count == 0) continue;
      std::snprintf(buffer, sizeof buffer, "  %zu master rows %s of '%s'\n", count, why,
                    f.name.c_str());
      out += buffer;
    }
  }
  if (!rig_source.empty()) out += "rig: " + rig_source + "\n";
  return out;
}

}  // namespace zerog::io
