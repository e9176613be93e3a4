#pragma once
// The simulated robot, a KUKA KR 210 R2700: the arm of its robot file
// (calib/robots/kr210_r2700.robot.toml, read through formats::kr210_r2700), moved by zerog::robot's
// kinematics (zerog/robot/forward_kinematics.hpp) as every other caller's arm, with the
// experiment's joint ranges and home pose.
//
// Frames (proto/frames.md): B robot base, F flange (z out of the flange).
#include <array>

#include "zerog/robot/forward_kinematics.hpp"
#include "zerog/robot/robot_model.hpp"

namespace zerog::sim {

using JointVector = std::array<double, 6>;  ///< A1..A6, rad (or rad/s, rad/s²)

/// The simulated arm: the shipped KR 210 R2700 robot file, read once (on first use). Its
/// flange_sensor is the identity: the simulator mounts its sensor itself (SimConfig).
const robot::RobotModel& kr210();

/// Joint ranges of the experiment (paper 000_…, Table 4), rad.
struct JointLimits {
  JointVector lower_rad;
  JointVector upper_rad;
};
JointLimits kr210_table4_limits();

/// Home pose A1..A6 = (0, −90°, +90°, 0, 0, 0), rad: the flange centre at (1.765, 0, 1.784) m in
/// B, flange z along +x_B (the robot file's comment; tests/unit/robot/kr210_file_test.cpp).
JointVector kr210_home();

}  // namespace zerog::sim
