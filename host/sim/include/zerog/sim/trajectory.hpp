#pragma once
// The simulator moves its robot along the firmware's PTP trajectory
// (zerog/robot/ptp_trajectory.hpp, which zerog-rt's collection mode drives the real robot with):
// the same names in zerog::sim.
#include <type_traits>

#include "zerog/robot/ptp_trajectory.hpp"
#include "zerog/sim/robot.hpp"

namespace zerog::sim {

static_assert(std::is_same_v<JointVector, robot::JointVector6>);

using robot::JointState;
using robot::kKr210MaxSpeedDegps;
using robot::kr210_ptp_limits;
using robot::MoveProfile;
using robot::plan_move;
using robot::PtpLimits;
using robot::PtpTrajectory;

}  // namespace zerog::sim
