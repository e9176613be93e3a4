#pragma once
// The robot description of a rig file (proto/robot_kinematics.md, "The [robot] table"): a DH
// table read into zerog::robot::RobotModel (firmware/robot, which does not parse). Strict like
// every zerog TOML file (toml_table.hpp): unknown keys, wrong types and bad values are errors
// naming file, line, column and the dotted key. Host and start-up code: allocates and throws.
#include <filesystem>
#include <string_view>
#include <vector>

#include "zerog/formats/log.hpp"
#include "zerog/formats/toml_table.hpp"
#include "zerog/robot/robot_model.hpp"

namespace zerog::formats {

/// Reads a `[robot]` table of `file` (keys named `prefix` + key in messages) and combines it
/// with the rig's sensor frame S in the flange (`flange_sensor`, the rig's `[flange_sensor]`).
/// Keys: name, source (strings, for people), convention ("dh" | "mdh"), [[robot.joint]] (a_m,
/// alpha_deg, d_m, theta_offset_deg = 0, sign = ±1 (1), column = 1-based recorded joint (its
/// row number), name), [robot.flange] (p_m, q_wxyz: F in the last DH frame; identity). Angles in
/// the file are in degrees (`alpha_deg`, `theta_offset_deg`) as every DH table is printed,
/// converted to rad here; lengths in m. Throws TomlError.
robot::RobotModel robot_from_toml(const toml::table& robot, const std::filesystem::path& file,
                                  const Transform& flange_sensor,
                                  const std::string& prefix = "robot.");

/// Reads a robot file (calib/robots/*.robot.toml): a `[robot]` table and an optional
/// `[flange_sensor]` (p_m, q_wxyz; identity if absent). Throws InputError / TomlError.
robot::RobotModel read_robot_file(const std::filesystem::path& toml);

/// A robot file's arm with its name, read with a rig's sensor frame in place of the file's own
/// `[flange_sensor]` (the rig is the authority on where the sensor sits; the robot file on the
/// arm). For a rig's `robot_file` (proto/log_format.md). Throws InputError / TomlError.
struct RobotDescription {
  std::string name;  ///< [robot].name ("" if absent)
  robot::RobotModel model;
};
RobotDescription read_robot_file(const std::filesystem::path& toml, const Transform& flange_sensor);

/// Reads a robot file's text (`file` names it in messages). As read_robot_file.
robot::RobotModel read_robot_text(std::string_view text, const std::filesystem::path& file);

/// The KUKA KR 210 R2700: calib/robots/kr210_r2700.robot.toml, whose text is built into this
/// library (firmware/formats/CMakeLists.txt) and read as any robot file, with `flange_sensor` in
/// place of the file's own. The arm of the simulator, the emulator and the tests, so that the
/// file is the one description of it; a rig names its robot file instead. Reads the text on each
/// call (host and start-up code: allocates and throws).
robot::RobotModel kr210_r2700(const robot::FrameTransform& flange_sensor = {});

/// The `[<table>]` TOML text of `model` (name, convention, [[<table>.joint]], [<table>.flange];
/// angles in degrees), which robot_from_toml reads back to the same model (1e-15). The
/// flange_sensor is not written (the rig writes its own).
std::string robot_toml_text(const std::string& table, const std::string& name,
                            const robot::RobotModel& model);

/// `t` as a rotation matrix and offset (R_parent_child, p_parent_child).
robot::FrameTransform to_frame_transform(const Transform& t);

}  // namespace zerog::formats
