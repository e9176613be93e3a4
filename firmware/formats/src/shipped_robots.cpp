// The robot files built into zerog (robot_toml.hpp, kr210_r2700): their text, generated at
// configure time from calib/robots/ (firmware/formats/CMakeLists.txt).
#include <string_view>

#include "zerog/formats/robot_toml.hpp"

namespace zerog::formats {
namespace {

constexpr std::string_view kKr210R2700Text =
#include "kr210_r2700_toml.inc"
    ;

}  // namespace

robot::RobotModel kr210_r2700(const robot::FrameTransform& flange_sensor) {
  robot::RobotModel model = read_robot_text(kKr210R2700Text, "kr210_r2700.robot.toml (built in)");
  model.flange_sensor = flange_sensor;
  return model;
}

}  // namespace zerog::formats
