#include "zerog/io/import.hpp"

#include "import_kinematics.hpp"
#include "import_mapping.hpp"
#include "import_series.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numbers>
#include <optional>
#include <span>
#include <string_view>
#include <unordered_map>

#include "zerog/formats/detail/csv_scan.hpp"
#include "zerog/formats/detail/rig_toml.hpp"
#include "zerog/formats/robot_toml.hpp"
#include "zerog/io/fused_kinematics.hpp"
#include "zerog/model/effects.hpp"
#include "zerog/model/rotation.hpp"
#include "zerog/robot/derive_kinematics.hpp"
#include "zerog/robot/forward_kinematics.hpp"

namespace zerog::io::importer {

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
  return m;
}

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

    for (const QuantitySpec& q : spec.quantities) {
      auto& out = series.values[static_cast<int>(q.what)];
      const double* r = raw.data() + q.first_ref;
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
        const Eigen::Quaterniond previous(out[size - 4], out[size - 3], out[size - 2],
                                          out[size - 1]);
        if (previous.dot(quat) < 0.0) quat.coeffs() = -quat.coeffs();
      }
      out.insert(out.end(), {quat.w(), quat.x(), quat.y(), quat.z()});
    }
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

namespace zerog::io {

using namespace importer;

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
  // A static table split over files: row i of each file is pose i, or the rows with the same
  // pose index.
  if (!mapping.files.front().has_time && mapping.files.front().has_index)
    join_by_pose_index(series, result.report);
  else if (!mapping.files.front().has_time) {
    for (std::size_t f = 1; f < series.size(); ++f) {
      if (series[f].t.size() == series.front().t.size()) continue;
      throw InputError(mapping.files[f].path, 0, 0,
                       "files." + mapping.files[f].name + " has " +
                           std::to_string(series[f].t.size()) + " rows and files." +
                           mapping.files.front().name + " (" +
                           mapping.files.front().path.filename().string() + ") " +
                           std::to_string(series.front().t.size()) +
                           ": a static table split over files without time is joined row by row, "
                           "so every file needs one row per pose, in the same order (or give "
                           "each file pose_index = { column = … } to join by a pose number)");
    }
  }
  if (!mapping.files.front().has_time && mapping.files.front().has_index)
    result.report.pose_index = mapping.files.front().refs[0].name;

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
      // Static rows count 0, 1, …: their "period" is 1 (the rig needs a positive value).
      log.rig.sample_period_s = median_period(series.front().t);
      if (!(log.rig.sample_period_s > 0.0)) log.rig.sample_period_s = 1.0;
      result.report.rig_source +=
          ", sample_period_s = " + num(log.rig.sample_period_s) + " s (median of the master)";
    }
  }

  // Which file provides each quantity, and how.
  std::array<int, kQuantityCount> source;
  std::array<const QuantitySpec*, kQuantityCount> spec_of{};
  source.fill(-1);
  for (std::size_t f = 0; f < mapping.files.size(); ++f) {
    for (const QuantitySpec& q : mapping.files[f].quantities) {
      source[static_cast<int>(q.what)] = static_cast<int>(f);
      spec_of[static_cast<int>(q.what)] = &q;
    }
  }
  auto has = [&](Quantity q) { return source[static_cast<int>(q)] >= 0; };
  auto in_base = [&](Quantity q) {
    return has(q) && spec_of[static_cast<int>(q)]->frame == VectorFrame::base;
  };
  // Joints: any number drive the robot's forward kinematics; the log holds q1_rad..q6_rad
  // (proto/log_format.md), so they are written to it only when there are 6.
  const int joint_columns =
      has(Quantity::joints) ? spec_of[static_cast<int>(Quantity::joints)]->num_refs : 0;
  log.columns.joints = joint_columns == 6;
  // No orientation mapped (read_mapping then allows no position either): the pose of S from the
  // joints, p_BS and R_BS = sensor_pose(robot, q) with the rig's flange_sensor.
  const bool pose_from_joints = !has(Quantity::orientation);
  std::optional<robot::RobotModel> pose_model;
  if (pose_from_joints) {
    const std::string joints_key = quantity_file(mapping, source, Quantity::joints);
    if (!log.rig.robot_model)
      throw_at(mapping_path, spec_of[static_cast<int>(Quantity::joints)]->where,
               "no 'orientation' is mapped, so the sensor's pose must come from '" + joints_key +
                   "' through the robot, but the rig (" + result.report.rig_source +
                   ") does not describe it: give the rig robot_file = \"…/calib/robots/"
                   "NAME.robot.toml\" or a [robot] table (proto/log_format.md), or map "
                   "'orientation'");
    pose_model = robot_for_joints(mapping, mapping_path, log, source,
                                  "compute the sensor's pose (no 'orientation' is mapped)");
  }
  if (has(Quantity::joints)) {
    result.report.joints =
        "joints: " + std::to_string(joint_columns) + " columns (" +
        quantity_file(mapping, source, Quantity::joints) + ")" +
        (pose_from_joints ? "; the sensor's pose from them through " + log.rig.robot +
                                "'s forward kinematics (no orientation mapped)"
                          : std::string()) +
        (joint_columns == 6 ? "; written to the log as q1_rad..q6_rad"
                            : "; not written to the log (it holds q1_rad..q6_rad, 6 joints): "
                              "they feed the robot's kinematics only, and effects that read "
                              "joints (cable) cannot be fitted") +
        "\n";
  }
  log.columns.specific_force = has(Quantity::specific_force);
  log.columns.angular_rate = has(Quantity::angular_rate);
  log.columns.angular_accel = has(Quantity::angular_accel);
  log.columns.temperature = has(Quantity::temperature);
  log.columns.position = has(Quantity::position) || pose_from_joints;
  log.columns.static_rows = !mapping.files.front().has_time;
  result.report.static_rows = log.columns.static_rows;
  const std::optional<Eigen::Vector3d> torque_lever_arm_m =
      spec_of[static_cast<int>(Quantity::torque)]->p_own_fixed_m;
  // IMU axes in the sensor frame, for IMU quantities given in the base frame.
  const Eigen::Matrix3d R_sensor_imu = log.rig.sensor_imu.q.normalized().toRotationMatrix();

  const std::vector<double>& t_master = series.front().t;
  result.report.master_rows = result.report.files.front().rows_read;  // before a pose join
  std::vector<Bracket> brackets(mapping.files.size());
  std::vector<std::size_t> cursor(mapping.files.size(), 0);
  log.samples.reserve(t_master.size());
  std::array<double, robot::kMaxJoints> joints_row{};  // the row's joints, interpolated
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
      // A master row at one of this file's samples takes that sample as it is: a + 1 · (c − a)
      // is c only to an ulp of the larger of the two (a 1e-21 rate came back as 7e-21, a −0
      // as 0), so the bracket starts at the sample, never ends on it.
      while (k + 1 < tf.size() && tf[k + 1] <= t) ++k;
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
    if (joint_columns > 0) {
      const std::vector<double>& q = values(Quantity::joints);
      const Bracket& b = bracket(Quantity::joints);
      const auto n = static_cast<std::size_t>(joint_columns);
      for (std::size_t j = 0; j < n; ++j)
        joints_row[j] = b.alpha == 0.0
                            ? q[b.k0 * n + j]
                            : q[b.k0 * n + j] + b.alpha * (q[b.k1 * n + j] - q[b.k0 * n + j]);
    }
    if (pose_from_joints) {
      const robot::Pose pose = robot::sensor_pose(
          *pose_model,
          std::span<const double>(joints_row.data(), static_cast<std::size_t>(joint_columns)));
      s.p_base_sensor_m = pose.p_m;
      s.q_base_sensor = Eigen::Quaterniond(pose.R).normalized();
      // keep neighbours in the same hemisphere, as read_series does for logged quaternions
      if (log.samples.size() >= 2 &&
          log.samples[log.samples.size() - 2].q_base_sensor.dot(s.q_base_sensor) < 0.0)
        s.q_base_sensor.coeffs() = -s.q_base_sensor.coeffs();
    } else {
      if (log.columns.position)
        s.p_base_sensor_m = at<3>(values(Quantity::position), bracket(Quantity::position));
      s.q_base_sensor =
          quaternion_at(values(Quantity::orientation), bracket(Quantity::orientation));
    }
    if (mapping.pose_of_flange && !pose_from_joints) {
      // p_BS = p_BF + R_BF p_FS, R_BS = R_BF R_FS (frames.md)
      if (log.columns.position) s.p_base_sensor_m += s.q_base_sensor * log.rig.flange_sensor.p_m;
      s.q_base_sensor = (s.q_base_sensor * log.rig.flange_sensor.q).normalized();
    }
    // Vectors logged with base-frame axes: v_S = R_BSᵀ v_B (torque stays about the S origin);
    // IMU quantities v_I = R_SIᵀ R_BSᵀ v_B (frames.md).
    const Eigen::Matrix3d R_sensor_base = s.q_base_sensor.toRotationMatrix().transpose();
    if (in_base(Quantity::force)) s.force_sensor_N = R_sensor_base * s.force_sensor_N;
    if (in_base(Quantity::torque)) s.torque_sensor_Nm = R_sensor_base * s.torque_sensor_Nm;
    // A torque about the origin of a fixed frame D at p_SD (its rotation already applied):
    // M_S = R_SD M_D + p_SD × F_S, with the row's force in S (moment transfer).
    if (torque_lever_arm_m) s.torque_sensor_Nm += torque_lever_arm_m->cross(s.force_sensor_N);
    if (log.columns.joints) std::copy_n(joints_row.begin(), 6, s.joints_rad.begin());
    if (log.columns.specific_force) {
      s.specific_force_imu_mps2 =
          at<3>(values(Quantity::specific_force), bracket(Quantity::specific_force));
      if (in_base(Quantity::specific_force))
        s.specific_force_imu_mps2 =
            R_sensor_imu.transpose() * R_sensor_base * s.specific_force_imu_mps2;
    }
    if (log.columns.angular_rate) {
      s.angular_rate_imu_radps =
          at<3>(values(Quantity::angular_rate), bracket(Quantity::angular_rate));
      if (in_base(Quantity::angular_rate))
        s.angular_rate_imu_radps =
            R_sensor_imu.transpose() * R_sensor_base * s.angular_rate_imu_radps;
    }
    // ω̇ in B: ω̇_S = R_BSᵀ ω̇_B, as d/dt(R_BSᵀ) ω_B = −ω_S × ω_S = 0 (see differentiate_gyro).
    if (log.columns.angular_accel) {
      s.angular_accel_imu_radps2 =
          at<3>(values(Quantity::angular_accel), bracket(Quantity::angular_accel));
      if (in_base(Quantity::angular_accel))
        s.angular_accel_imu_radps2 =
            R_sensor_imu.transpose() * R_sensor_base * s.angular_accel_imu_radps2;
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
  log.rig.kinematics = {};  // whatever a rig file says: this import's columns decide
  // A logged ω̇ goes to imu_dw*_radps2, which log format 2 holds only beside imu_w*_radps: the
  // gyro's, or under "auto" the robot's ω.
  const auto refuse_accel_without_rate = [&] {
    if (!log.columns.angular_accel || log.columns.angular_rate) return;
    const std::string key = quantity_file(mapping, source, Quantity::angular_accel);
    throw_at(mapping_path, spec_of[static_cast<int>(Quantity::angular_accel)]->where,
             "'" + key +
                 "' needs the angular rate beside it (the log holds ω̇, imu_dw*_radps2, only "
                 "with imu_w*_radps; proto/log_format.md): map the gyro as 'angular_rate' (in "
                 "this file or another)" +
                 (mapping.kinematics == robot::KinematicsMode::imu
                      ? std::string(", or set kinematics = \"auto\" to derive ω from the joints "
                                    "(with the rig's robot) or the orientation")
                      : std::string(log.columns.static_rows
                                        ? ", or record time (rows without time give no ω)"
                                        : "")) +
                 ", or remove '" + std::string(info(Quantity::angular_accel).key) + "'");
  };
  if (log.columns.angular_accel) {
    log.rig.kinematics.angular_accel = KinematicsOrigin::logged;
    log.rig.kinematics.angular_accel_reason =
        "logged in " + quantity_file(mapping, source, Quantity::angular_accel) +
        " (used as logged)";
  }
  if (mapping.fused) {
    fuse_joints_and_imu(mapping, mapping_path, series, source, result);
    return result;
  }
  if (mapping.kinematics == robot::KinematicsMode::imu) {  // the columns as logged
    refuse_accel_without_rate();
    if (log.columns.angular_accel)
      result.report.kinematics =
          "angular acceleration: " + log.rig.kinematics.angular_accel_reason + "\n";
    return result;
  }
  derive_from_robot(mapping, mapping_path, series, source, result);
  refuse_accel_without_rate();
  const KinematicsRecord& k = log.rig.kinematics;
  result.report.kinematics =
      "kinematics = \"" + k.mode + "\": angular rate " +
      (log.columns.angular_rate ? std::string("from ") + to_string(k.angular_rate) : "none") +
      (k.angular_rate_reason.empty() ? "" : " (" + k.angular_rate_reason + ")") +
      "; specific force " +
      (log.columns.specific_force ? std::string("from ") + to_string(k.specific_force) : "none") +
      (k.specific_force_reason.empty() ? "" : " (" + k.specific_force_reason + ")") +
      "; angular acceleration " +
      (log.columns.angular_accel && k.angular_accel == KinematicsOrigin::logged
           ? k.angular_accel_reason
       : log.columns.angular_accel
           ? std::string("from ") + to_string(k.angular_accel) +
                 (k.angular_accel == KinematicsOrigin::imu ? " (Savitzky-Golay)" : "")
       : log.columns.angular_rate && !log.columns.static_rows
           ? std::string("by host/ident's 5-point difference of the angular rate")
           : std::string("none")) +
      "\n" + result.report.kinematics;
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
  if (static_rows) {
    std::snprintf(buffer, sizeof buffer,
                  "static table '%s' (%s): %zu rows without time, each an independent held "
                  "pose\n",
                  master.c_str(), files.empty() ? "?" : files.front().path.filename().c_str(),
                  rows_out);
    out += buffer;
    for (std::size_t f = 1; f < files.size(); ++f) {
      if (pose_index.empty()) {
        std::snprintf(buffer, sizeof buffer, "  joined row by row with '%s' (%s, %zu rows)\n",
                      files[f].name.c_str(), files[f].path.filename().c_str(), files[f].rows_read);
      } else {
        std::snprintf(buffer, sizeof buffer,
                      "  joined by pose index ('%s') with '%s' (%s, %zu rows): %zu master rows "
                      "dropped (their pose not in it), %zu of its rows not used (their pose not "
                      "in the master)\n",
                      pose_index.c_str(), files[f].name.c_str(), files[f].path.filename().c_str(),
                      files[f].rows_read, files[f].master_rows_unmatched, files[f].rows_unused);
      }
      out += buffer;
    }
    if (!pose_index.empty()) {
      std::snprintf(buffer, sizeof buffer,
                    "rows out: %zu of %zu master rows, in the master's order (log row i is its "
                    "i-th kept pose)\n",
                    rows_out, master_rows);
      out += buffer;
    }
    if (!rig_source.empty()) out += "rig: " + rig_source + "\n";
    out += joints;
    return out;
  }
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
  out += joints;
  out += kinematics;
  return out;
}

}  // namespace zerog::io
