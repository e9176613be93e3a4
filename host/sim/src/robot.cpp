#include "zerog/sim/robot.hpp"

#include <numbers>

#include "zerog/formats/robot_toml.hpp"

namespace zerog::sim {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

}  // namespace

const robot::RobotModel& kr210() {
  static const robot::RobotModel model = formats::kr210_r2700();
  return model;
}

JointLimits kr210_table4_limits() {
  return {{-150 * kDeg, -138 * kDeg, -10 * kDeg, -180 * kDeg, -120 * kDeg, -180 * kDeg},
          {150 * kDeg, -70 * kDeg, 130 * kDeg, 180 * kDeg, 120 * kDeg, 180 * kDeg}};
}

JointVector kr210_home() { return {0.0, -90 * kDeg, 90 * kDeg, 0.0, 0.0, 0.0}; }

}  // namespace zerog::sim
