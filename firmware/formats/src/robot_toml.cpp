#include "zerog/formats/robot_toml.hpp"

#include <cmath>
#include <numbers>
#include <string>

#include "zerog/formats/detail/rig_toml.hpp"

namespace zerog::formats {
namespace {

constexpr double kRadPerDeg = std::numbers::pi / 180.0;

// The keys of a [[robot.joint]] row (proto/robot_kinematics.md; the elasticity: sim_robot.md).
const std::vector<std::string_view> kJointKeys = {"name",
                                                  "a_m",
                                                  "alpha_deg",
                                                  "d_m",
                                                  "theta_offset_deg",
                                                  "sign",
                                                  "column",
                                                  "ros_name",
                                                  "stiffness_Nm_per_rad",
                                                  "mode_hz",
                                                  "damping_ratio"};

}  // namespace

robot::FrameTransform to_frame_transform(const Transform& t) {
  return {t.q.normalized().toRotationMatrix(), t.p_m};
}

robot::RobotModel robot_from_toml(const toml::table& table, const std::filesystem::path& file,
                                  const Transform& flange_sensor, const std::string& prefix) {
  const TomlTable t(table, file, prefix,
                    {"name", "convention", "joint", "flange", "source", "ros_flange"},
                    "proto/robot_kinematics.md");
  // ROS names (for zerog import --bag, which reads them itself): strings, checked here.
  (void)t.optional_string("ros_flange", {});
  robot::RobotModel m;
  const std::string convention = t.string("convention");
  if (convention == "dh")
    m.convention = robot::DhConvention::dh;
  else if (convention == "mdh")
    m.convention = robot::DhConvention::mdh;
  else
    t.fail("convention",
           "must be \"dh\" (standard) or \"mdh\" (modified), is \"" + convention + "\"");
  const toml::array* rows = t.require("joint").as_array();
  if (rows == nullptr || rows->empty() || rows->size() > robot::kMaxJoints)
    t.fail("joint", "must be 1 to " + std::to_string(robot::kMaxJoints) +
                        " [[robot.joint]] tables, one per joint from the base outwards");
  m.joint_count = static_cast<int>(rows->size());
  std::array<bool, robot::kMaxJoints> column_used{};
  int first_rigid = -1, elastic_rows = 0;  // the elasticity: every joint or none
  for (int i = 0; i < m.joint_count; ++i) {
    const std::string key = "joint[" + std::to_string(i + 1) + "]";
    const toml::table* row = (*rows)[static_cast<std::size_t>(i)].as_table();
    if (row == nullptr) t.fail("joint", key + " must be a table");
    const TomlTable j(*row, t.file(), t.name(key) + ".", kJointKeys);
    (void)j.optional_string("name", {});
    (void)j.optional_string("ros_name", {});
    // The elasticity (proto/sim_robot.md): all three keys or none.
    if (j.find("stiffness_Nm_per_rad") != nullptr || j.find("mode_hz") != nullptr ||
        j.find("damping_ratio") != nullptr) {
      m.elasticity[static_cast<std::size_t>(i)] = {j.number("stiffness_Nm_per_rad", 0.0, true),
                                                   j.number("mode_hz", 0.0, true),
                                                   j.number("damping_ratio", 0.0, false)};
      ++elastic_rows;
    } else if (first_rigid < 0) {
      first_rigid = i;
    }
    robot::DhJoint& dh = m.joints[static_cast<std::size_t>(i)];
    dh.a_m = j.number("a_m", NumberRange{});
    dh.alpha_rad = j.number("alpha_deg", NumberRange{}) * kRadPerDeg;
    dh.d_m = j.number("d_m", NumberRange{});
    dh.theta_offset_rad = j.optional_number("theta_offset_deg", 0.0) * kRadPerDeg;
    const std::int64_t sign = j.optional_integer("sign", 1, -1, 1);
    if (sign == 0) j.fail("sign", "must be 1 or -1 (the joint's direction against the DH z axis)");
    dh.sign = static_cast<double>(sign);
    const std::int64_t column = j.optional_integer("column", i + 1, 1, m.joint_count);
    if (column_used[static_cast<std::size_t>(column - 1)])
      j.fail("column", "names recorded joint " + std::to_string(column) +
                           " a second time (each joint column once)");
    column_used[static_cast<std::size_t>(column - 1)] = true;
    m.input_index[static_cast<std::size_t>(i)] = static_cast<int>(column - 1);
  }
  if (elastic_rows > 0 && first_rigid >= 0) {
    const std::string key = "joint[" + std::to_string(first_rigid + 1) + "]";
    const TomlTable j(*(*rows)[static_cast<std::size_t>(first_rigid)].as_table(), t.file(),
                      t.name(key) + ".", kJointKeys);
    j.fail("stiffness_Nm_per_rad",
           "is missing: give the elasticity of every joint or of none (proto/sim_robot.md)");
  }
  if (t.find("flange") != nullptr) {
    const TomlTable f(t.table("flange"), t.file(), t.name("flange") + ".", {"p_m", "q_wxyz"});
    m.last_flange = to_frame_transform(detail::transform_of(f));
  }
  m.flange_sensor = to_frame_transform(flange_sensor);
  if (const zerog::Status status = robot::validate(m); !status.ok())
    throw_at(t.file(), t.where(), status.text());
  return m;
}

namespace {

// A robot file already parsed (`file`, read from `toml`); `rig_flange_sensor`, if given,
// replaces the file's [flange_sensor].
RobotDescription robot_of_file(const toml::table& file, const std::filesystem::path& toml,
                               const Transform* rig_flange_sensor) {
  const TomlTable top(file, toml, "", {"format", "version", "robot", "flange_sensor"});
  const std::string format = top.string("format");
  if (format != "zerog-robot") top.fail("format", "must be \"zerog-robot\", is \"" + format + "\"");
  if (top.integer("version") != 1) top.fail("version", "must be 1");
  Transform flange_sensor;
  if (top.find("flange_sensor") != nullptr)
    flange_sensor = detail::transform_of(
        TomlTable(top.table("flange_sensor"), toml, "flange_sensor.", {"p_m", "q_wxyz"}));
  if (rig_flange_sensor != nullptr) flange_sensor = *rig_flange_sensor;
  const toml::table& robot = top.table("robot");
  RobotDescription out;
  out.name = robot["name"].value_or(std::string());
  out.model = robot_from_toml(robot, toml, flange_sensor);
  return out;
}

// Reads a robot file (robot_of_file).
RobotDescription read_robot(const std::filesystem::path& toml, const Transform* rig_flange_sensor) {
  return robot_of_file(parse_toml_file(toml), toml, rig_flange_sensor);
}

// Shortest text that reads back exactly, always with a '.' or an exponent (a TOML float).
std::string float_text(double v) {
  std::string s = number_text(v);
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
  return s;
}

std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

}  // namespace

robot::RobotModel read_robot_file(const std::filesystem::path& toml) {
  return read_robot(toml, nullptr).model;
}

RobotDescription read_robot_file(const std::filesystem::path& toml,
                                 const Transform& flange_sensor) {
  return read_robot(toml, &flange_sensor);
}

robot::RobotModel read_robot_text(std::string_view text, const std::filesystem::path& file) {
  return robot_of_file(parse_toml(text, file), file, nullptr).model;
}

std::string robot_toml_text(const std::string& table, const std::string& name,
                            const robot::RobotModel& model) {
  std::string out = "\n[" + table + "]  # the arm (proto/robot_kinematics.md)\n";
  out += "name = " + quoted(name) + "\n";
  out += std::string("convention = \"") +
         (model.convention == robot::DhConvention::mdh ? "mdh" : "dh") + "\"\n";
  for (int i = 0; i < model.joint_count; ++i) {
    const robot::DhJoint& j = model.joints[static_cast<std::size_t>(i)];
    out += "\n[[" + table + ".joint]]\n";
    out += "a_m = " + float_text(j.a_m) + "\n";
    out += "alpha_deg = " + float_text(j.alpha_rad / kRadPerDeg) + "\n";
    out += "d_m = " + float_text(j.d_m) + "\n";
    out += "theta_offset_deg = " + float_text(j.theta_offset_rad / kRadPerDeg) + "\n";
    out += "sign = " + std::string(j.sign < 0.0 ? "-1" : "1") + "\n";
    out += "column = " + std::to_string(model.input_index[static_cast<std::size_t>(i)] + 1) + "\n";
    const robot::JointElasticity& e = model.elasticity[static_cast<std::size_t>(i)];
    if (!e.rigid())
      out += "stiffness_Nm_per_rad = " + float_text(e.stiffness_Nm_per_rad) +
             "\nmode_hz = " + float_text(e.mode_hz) +
             "\ndamping_ratio = " + float_text(e.damping_ratio) + "\n";
  }
  const robot::FrameTransform& f = model.last_flange;
  if (!f.R.isIdentity(0.0) || !f.p_m.isZero(0.0)) {
    const Eigen::Quaterniond q(f.R);
    out += "\n[" + table + ".flange]  # flange F in the last DH frame\n";
    out += "p_m = [" + float_text(f.p_m.x()) + ", " + float_text(f.p_m.y()) + ", " +
           float_text(f.p_m.z()) + "]\n";
    out += "q_wxyz = [" + float_text(q.w()) + ", " + float_text(q.x()) + ", " + float_text(q.y()) +
           ", " + float_text(q.z()) + "]\n";
  }
  return out;
}

}  // namespace zerog::formats
