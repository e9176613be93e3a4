// The importer's first phase: the mapping file read and checked (proto/import_mapping.md), the
// quantities each [files.NAME] table maps, their columns, units and frames.
#include "import_mapping.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <string_view>

#include "zerog/formats/detail/csv_scan.hpp"
#include "zerog/model/effects.hpp"

namespace zerog::io::importer {

using formats::NumberRange;
using formats::TomlTable;
using formats::Transform;
namespace detail = formats::detail;
using formats::throw_at;

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
      {"joints", 0, 0, {{"rad", 1.0}, {"deg", kDegree}}, "joint angles A1, A2, …"},
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
      {"angular_accel",
       3,
       3,
       {{"rad/s^2", 1.0}, {"rad/s2", 1.0}, {"deg/s^2", kDegree}, {"deg/s2", kDegree}},
       "angular acceleration, IMU frame"},
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

const Unit& find_unit(const TomlTable& t, const std::vector<Unit>& units) {
  const std::string unit = t.string("unit");
  for (const Unit& u : units) {
    if (u.name == unit) return u;
  }
  throw_at(t.file(), t.require("unit").source(),
           "unknown unit \"" + unit + "\" for '" + t.name("unit") + "' (use one of " +
               unit_list(units) + ")");
}

// One column of the data file named by `node` (an element of `key` or its value): a header name
// (string) or a 1-based column number (integer); only numbers when the file has no header.
void add_ref(FileSpec& file, const TomlTable& t, std::string_view key, const toml::node& node) {
  ColumnRef ref;
  ref.where = node.source();
  ref.key = t.name(key);
  if (node.is_integer()) {
    const std::int64_t n = *node.value<std::int64_t>();
    if (n < 1 || n > 100000) {
      throw_at(t.file(), node.source(),
               "'" + t.name(key) + "': column number " + std::to_string(n) +
                   " is out of range (columns are counted from 1)");
    }
    ref.number = static_cast<int>(n);
    ref.name = "column " + std::to_string(n);
  } else if (node.is_string()) {
    if (!file.header) {
      throw_at(t.file(), node.source(),
               "'" + t.name(key) + "' names column '" +
                   std::string(*node.value<std::string_view>()) + "', but files." + file.name +
                   " has header = false: give the 1-based column number instead, e.g. 2");
    }
    ref.name = *node.value<std::string_view>();
  } else {
    throw_at(t.file(), node.source(),
             "'" + t.name(key) +
                 "' must name a column: its header name (a string) or its 1-based number");
  }
  file.refs.push_back(std::move(ref));
}

// `count` columns listed under `key`, by header name or 1-based number.
void add_refs(FileSpec& file, const TomlTable& t, std::string_view key, std::size_t count) {
  const toml::node& node = t.require(key);
  const toml::array* array = node.as_array();
  if (array == nullptr || array->size() != count) {
    throw_at(t.file(), node.source(),
             "'" + t.name(key) + "' must be a list of " + std::to_string(count) +
                 " columns (header names, or 1-based column numbers)");
  }
  for (const toml::node& element : *array) add_ref(file, t, key, element);
}

bool is_imu(Quantity q) {
  return q == Quantity::specific_force || q == Quantity::angular_rate ||
         q == Quantity::angular_accel;
}

bool is_vector(Quantity q) { return q == Quantity::force || q == Quantity::torque || is_imu(q); }

// The optional `frame` of a vector quantity: "sensor"/"imu" (its own frame), "base", or
// { q_wxyz = [w, x, y, z] } (a fixed frame D: its axes in the own frame), for force and torque
// optionally with p_m = [x, y, z] (D's origin in S, m; detail::transform_of's convention).
void read_frame(QuantitySpec& q, const TomlTable& t) {
  const toml::node* node = t.find("frame");
  if (node == nullptr) return;
  q.frame_where = node->source();
  const bool imu = is_imu(q.what);
  const std::string own = imu ? "imu" : "sensor";
  if (node->is_string()) {
    const std::string f = t.string("frame");
    if (f == own) return;
    if (f == "base") {
      q.frame = VectorFrame::base;
      return;
    }
    throw_at(t.file(), node->source(),
             "'" + t.name("frame") + "' must be \"" + own + "\" (the default), \"base\" or " +
                 "{ q_wxyz = [w, x, y, z] } (a fixed frame's axes in the " +
                 (imu ? "IMU" : "sensor") + " frame), is \"" + f + "\"");
  }
  const TomlTable ft(t.table("frame"), t.file(), t.name("frame") + ".", {"q_wxyz", "p_m"});
  q.frame = VectorFrame::fixed;
  if (ft.find("p_m") == nullptr) {
    const auto v = ft.numbers("q_wxyz", 4);
    const Eigen::Quaterniond quat(v[0], v[1], v[2], v[3]);
    if (std::abs(quat.norm() - 1.0) > 1e-3)
      ft.fail("q_wxyz", "has norm " + num(quat.norm()) + ", off from 1 by more than 1e-3");
    q.R_own_fixed = quat.normalized().toRotationMatrix();
    return;
  }
  const Transform transform = detail::transform_of(ft);
  q.R_own_fixed = transform.q.toRotationMatrix();
  if (imu && !transform.p_m.isZero())
    ft.fail("p_m",
            "an IMU reads at its own position, so its frame takes a rotation only: give the "
            "IMU's offset from the sensor origin as the rig's [sensor_imu] p_m (the model's "
            "lever-arm terms use it) and remove p_m here");
  if (!imu) {
    q.p_own_fixed_m = transform.p_m;
    q.lever_where = ft.where("p_m");
  }
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
    add_ref(file, t, "column", t.require("column"));
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
      add_refs(file, t, "columns", 4);
      if (order == "xyzw") {
        const auto first = file.refs.begin() + q.first_ref;
        std::rotate(first, first + 3, first + 4);
      }
    } else if (type == "matrix") {
      q.orientation = Orientation::matrix;
      add_refs(file, t, "columns", 9);
    } else if (type == "kuka_abc") {
      q.orientation = Orientation::kuka_abc;
      add_refs(file, t, "columns", 3);
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
  } else if (what == Quantity::joints) {
    // Any number of joints, A1 first: the rig's robot says how many it has (7 for an iiwa).
    const TomlTable t(*node.as_table(), parent.file(), prefix, {"columns", "unit"});
    const toml::node& columns = t.require("columns");
    const toml::array* array = columns.as_array();
    if (array == nullptr || array->empty() || array->size() > robot::kMaxJoints) {
      throw_at(t.file(), columns.source(),
               "'" + t.name("columns") + "' must be a list of 1 to " +
                   std::to_string(robot::kMaxJoints) +
                   " joint columns, A1 first (header names, or 1-based column numbers)");
    }
    add_refs(file, t, "columns", array->size());
    q.scale = find_unit(t, qi.units).scale;
  } else {
    std::vector<std::string_view> keys = {"columns", "unit"};
    if (is_vector(what)) keys.push_back("frame");
    const TomlTable t(*node.as_table(), parent.file(), prefix, keys);
    add_refs(file, t, "columns", static_cast<std::size_t>(qi.width));
    read_frame(q, t);
    const Unit& u = find_unit(t, qi.units);
    q.scale = u.scale;
    q.offset = u.offset;
  }
  q.num_refs = static_cast<int>(file.refs.size()) - q.first_ref;
  file.quantities.push_back(q);
}

char read_delimiter(const TomlTable& t) {
  const std::string given = t.optional_string("delimiter", "comma");
  // Blanks around a separator (", ", " ; ") are the same separator: cells are trimmed anyway.
  const std::string_view core = detail::trim(given);
  const std::string d = core.empty() && !given.empty() ? std::string(" ") : std::string(core);
  if (d == "comma" || d == ",") return ',';
  if (d == "semicolon" || d == ";") return ';';
  if (d == "tab" || d == "\t") return '\t';
  if (d == "whitespace" || d == " ") return ' ';
  throw_at(t.file(), t.require("delimiter").source(),
           "'" + t.name("delimiter") +
               "' must be \"comma\", \"semicolon\", \"tab\" or \"whitespace\" (or \",\", \";\", " +
               "blanks around them allowed), is \"" + given + "\"");
}

FileSpec read_file_spec(const std::string& name, const toml::node& node, const fs::path& mapping) {
  const std::string prefix = "files." + name + ".";
  if (!node.is_table()) throw_at(mapping, node.source(), "'files." + name + "' must be a table");
  std::vector<std::string_view> known = {"path",       "delimiter", "decimal", "comment",
                                         "skip_lines", "header",    "time",    "time_offset_s",
                                         "max_gap_s",  "pose_index"};
  for (const auto& qi : quantity_infos()) known.push_back(qi.key);
  const TomlTable t(*node.as_table(), mapping, prefix, known);

  FileSpec file;
  file.name = name;
  file.where = node.source();
  file.header = t.optional_boolean("header", true);
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

  const toml::node* time_node = t.find("time");
  file.has_time = time_node != nullptr;
  if (time_node != nullptr) {
    if (!time_node->is_table()) {
      throw_at(mapping, time_node->source(),
               "'" + t.name("time") + "' must be a table, e.g. { column = \"t\", unit = \"s\" }");
    }
    const TomlTable time(*time_node->as_table(), mapping, prefix + "time.", {"column", "unit"});
    add_ref(file, time, "column", time.require("column"));
    const Unit& time_unit = find_unit(time, kTimeUnits);
    file.time_unit = time_unit.name;
    file.time_scale = time_unit.scale;
  } else {
    for (std::string_view key : {"time_offset_s", "max_gap_s"}) {
      if (t.find(key) != nullptr) {
        throw_at(mapping, t.require(key).source(),
                 "'" + t.name(key) + "' needs a time column: add time = { column = …, unit = … }");
      }
    }
  }
  if (const toml::node* index = t.find("pose_index")) {
    if (file.has_time)
      throw_at(mapping, index->source(),
               "'" + t.name("pose_index") +
                   "' joins the rows of static tables (files without time); this file has "
                   "time, and is merged by it");
    if (!index->is_table())
      throw_at(mapping, index->source(),
               "'" + t.name("pose_index") + "' must be a table, e.g. { column = \"pose\" }");
    const TomlTable idx(*index->as_table(), mapping, prefix + "pose_index.", {"column"});
    add_ref(file, idx, "column", idx.require("column"));
    file.has_index = true;
  }
  if (t.find("time_offset_s") != nullptr) {
    file.time_offset_s = t.number(t.require("time_offset_s"), "time_offset_s");
  }
  if (t.find("max_gap_s") != nullptr) file.max_gap_s = t.number("max_gap_s", 0.0, true);

  for (int q = 0; q < kQuantityCount; ++q) {
    if (t.find(quantity_infos()[q].key) != nullptr) read_quantity(file, Quantity(q), t);
  }
  return file;
}

// The mapping as a whole: every quantity from exactly one file, the required ones present,
// the files' time bases compatible (read_mapping's last phase).
void check_sources(const Mapping& m, const fs::path& mapping, const toml::table& files) {
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
  // A torque about another point needs the force to move it to the sensor origin.
  for (const FileSpec& f : m.files) {
    for (const QuantitySpec& q : f.quantities) {
      if (q.what != Quantity::torque || !q.p_own_fixed_m ||
          source[static_cast<int>(Quantity::force)] != nullptr)
        continue;
      throw_at(mapping, q.lever_where,
               "'files." + f.name +
                   ".torque.frame.p_m' moves the torque from the recording frame's origin to "
                   "the sensor origin, M_S = R M + p × F_S, which needs the force: map 'force' "
                   "(in this file or another), or remove p_m if the torque is already about the "
                   "sensor origin");
    }
  }
  const bool joints_mapped = source[static_cast<int>(Quantity::joints)] != nullptr;
  for (Quantity q : {Quantity::force, Quantity::torque, Quantity::orientation}) {
    // Without an orientation the pose comes from the joints through the rig's robot (checked
    // once the rig is known).
    if (q == Quantity::orientation && joints_mapped) continue;
    if (source[static_cast<int>(q)] == nullptr) {
      throw_at(mapping, files.source(),
               "no file maps '" + std::string(info(q).key) + "' (" + std::string(info(q).meaning) +
                   "); a log needs force, torque and orientation, or 'joints' with a rig that "
                   "describes the robot (position, the IMU and temperature are optional)");
    }
  }
  // Without an orientation the whole pose comes from the joints: a position alone is no pose.
  if (source[static_cast<int>(Quantity::orientation)] == nullptr &&
      source[static_cast<int>(Quantity::position)] != nullptr) {
    throw_at(mapping, where[static_cast<int>(Quantity::position)],
             "'position' is mapped without 'orientation': map the orientation too, or remove "
             "'position' to take the whole pose from the joints through the rig's robot");
  }
  // A logged ω̇ (imu_dw*_radps2) is used as logged; "robot" takes every signal from the robot.
  if (source[static_cast<int>(Quantity::angular_accel)] != nullptr &&
      m.kinematics == robot::KinematicsMode::robot) {
    throw_at(mapping, where[static_cast<int>(Quantity::angular_accel)],
             "'files." + source[static_cast<int>(Quantity::angular_accel)]->name +
                 ".angular_accel' is a logged angular acceleration, but kinematics = \"robot\" "
                 "takes ω̇ from the robot: use kinematics = \"auto\" to keep the logged ω̇ "
                 "(and take what the IMU lacks from the robot), or remove 'angular_accel'");
  }
  // Rows without time are static samples: they cannot be put on another file's time base. A
  // static table split over files (poses in one, wrenches in another) joins row by row: every
  // file without time, the same number of rows (checked when they are read).
  const FileSpec* timed = nullptr;
  for (const FileSpec& file : m.files)
    if (file.has_time) timed = &file;
  for (const FileSpec& file : m.files) {
    if (file.has_index == m.files.front().has_index || file.has_time) continue;
    const FileSpec& with = file.has_index ? file : m.files.front();
    const FileSpec& without = file.has_index ? m.files.front() : file;
    throw_at(mapping, without.where,
             "files." + with.name + " has a pose_index and files." + without.name +
                 " has none: static tables are joined by pose index (every file names its "
                 "pose column) or row by row (none does)");
  }
  for (const FileSpec& file : m.files) {
    if (file.has_time || timed == nullptr) continue;
    throw_at(mapping, file.where,
             "files." + file.name + " has no 'time' but files." + timed->name +
                 " has: a file without time holds static samples (one row per pose) and cannot "
                 "be put on another file's time base; give every file time = { column = …, "
                 "unit = … }, or none (a static table split over files is joined row by row)");
  }
}

Mapping read_mapping(const fs::path& mapping, bool rig_given) {
  const toml::table root = detail::parse_toml_file(mapping);
  const TomlTable top(
      root, mapping, "",
      {"format", "version", "master", "pose_of", "rig_file", "rig", "files", "kinematics",
       "kinematics_bandwidth_hz", "kinematics_accel_bandwidth_hz", "kinematics_crossover_hz"});
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

  m.kinematics_text = top.optional_string("kinematics", "imu");
  m.kinematics_where = top.where("kinematics");
  if (m.kinematics_text == "robot")
    m.kinematics = robot::KinematicsMode::robot;
  else if (m.kinematics_text == "auto")
    m.kinematics = robot::KinematicsMode::automatic;
  else if (m.kinematics_text == "fused")
    m.fused = true;
  else if (m.kinematics_text != "imu")
    top.fail("kinematics",
             "must be \"imu\" (the default: the IMU columns as logged), \"robot\" (ω, ω̇ and "
             "the specific force derived from the joints with the rig's robot, or from the "
             "pose), \"auto\" (each from the IMU where it has it, else from the robot) or "
             "\"fused\" (the joints and the IMU together), is \"" +
                 m.kinematics_text + "\"");
  m.kinematics_bandwidth_hz = top.optional_number(
      "kinematics_bandwidth_hz", m.fused ? kFusedBandwidthHz : 5.0, NumberRange{0.0, true});
  if (!m.fused && top.find("kinematics_crossover_hz") != nullptr)
    top.fail("kinematics_crossover_hz", "is for kinematics = \"fused\" only");
  m.kinematics_crossover_hz =
      top.optional_number("kinematics_crossover_hz", kFusedCrossoverHz, NumberRange{0.0, true});
  m.kinematics_accel_bandwidth_hz = top.optional_number(
      "kinematics_accel_bandwidth_hz", kDefaultAccelBandwidthHz, NumberRange{0.0, true});

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

  check_sources(m, mapping, files);
  return m;
}
}  // namespace zerog::io::importer
