#include "zerog/robot/robot_model.hpp"

#include <Eigen/LU>
#include <cmath>
#include <string>
#include <utility>

namespace zerog::robot {
namespace {

bool is_rotation(const Eigen::Matrix3d& R) {
  return (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-9 &&
         std::abs(R.determinant() - 1.0) < 1e-9;
}

}  // namespace

zerog::Status validate(const RobotModel& model) {
  using zerog::Status;
  if (model.joint_count < 1 || model.joint_count > kMaxJoints)
    return Status::invalid("joint_count", "a robot has 1 to " + std::to_string(kMaxJoints) +
                                              " joints, this one " +
                                              std::to_string(model.joint_count));
  std::array<bool, kMaxJoints> used{};
  for (int i = 0; i < model.joint_count; ++i) {
    const DhJoint& j = model.joints[i];
    // Messages are built on failure only: the check itself does not allocate.
    const auto row = [i] { return "joints[" + std::to_string(i) + "]"; };
    if (!std::isfinite(j.a_m) || !std::isfinite(j.alpha_rad) || !std::isfinite(j.d_m) ||
        !std::isfinite(j.theta_offset_rad))
      return Status::invalid(row(), "has a value that is not a finite number");
    if (j.sign != 1.0 && j.sign != -1.0)
      return Status::invalid(row() + ".sign", "must be +1 or -1");
    const int k = model.input_index[i];
    if (k < 0 || k >= model.joint_count || used[k])
      return Status::invalid("input_index[" + std::to_string(i) + "]",
                             "the joint order must name each of the " +
                                 std::to_string(model.joint_count) + " recorded joints once");
    used[k] = true;
  }
  const std::pair<const FrameTransform*, const char*> frames[] = {
      {&model.last_flange, "last_flange"}, {&model.flange_sensor, "flange_sensor"}};
  for (const auto& [f, name] : frames) {
    if (!f->R.allFinite() || !f->p_m.allFinite())
      return Status::invalid(name, "has a value that is not a finite number");
    if (!is_rotation(f->R))
      return Status::invalid(std::string(name) + ".R",
                             "is not a rotation (orthonormal, determinant +1)");
  }
  return {};
}

}  // namespace zerog::robot
