#pragma once
// Start-up of zerog-rt before any device is opened: the configuration, the running rig, the
// deployed model (checked against that rig at the robot's cycle) and the loop's configuration,
// and for collection mode the design path. Everything here may allocate and throws
// std::runtime_error whose message names the file and why. Not real-time safe.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "zerog/formats/log.hpp"
#include "zerog/infer/deploy_model.hpp"
#include "zerog/loop/cycle.hpp"
#include "zerog/robot/ptp_trajectory.hpp"
#include "zerog/rt/config.hpp"

namespace zerog::rt {

/// The rig as the model loader compares it: the running rig's name, robot and poses, with the
/// row period of the rows the cycle makes — one robot cycle (a model fitted at 12 ms rows runs
/// only with a 12 ms RSI cycle).
infer::RigDescription running_rig(const formats::Rig& rig, double cycle_period_s);

struct Setup {
  RtConfig config;
  formats::Rig rig;  ///< the running rig, sample_period_s = the robot cycle (what a recording gets)
  infer::DeployedModel model;
  std::uint32_t model_file_crc32 = 0;  ///< CRC-32 of the deploy file's bytes: its identity
  loop::CycleConfig cycle;
};

/// Reads the rig and the model the configuration names and checks them with the loop's
/// configuration (loop::Cycle::configure). Throws std::runtime_error naming the file and why.
Setup load_setup(const RtConfig& config);

/// Collection mode: a `zerog design` path (proto/design_format.md) as a PTP trajectory
/// (robot::kr210_ptp_limits(speed_fraction), dwell_s at each point) behind loop::JointPath.
/// at() evaluates the analytic profile: no allocation (a binary search over the moves).
class PtpJointPath final : public loop::JointPath {
 public:
  PtpJointPath(std::vector<robot::JointVector6> points_rad, double speed_fraction, double dwell_s);
  double duration_s() const override { return trajectory_.duration_s(); }
  std::array<double, 6> at(double t_s) const override { return trajectory_.at(t_s).q_rad; }
  std::size_t num_points() const { return trajectory_.num_points(); }

 private:
  robot::PtpTrajectory trajectory_;
};

/// Reads a design CSV and builds its path with the configuration's [collection] settings.
/// Throws (formats::InputError naming file, line and column) on a bad design.
std::unique_ptr<PtpJointPath> load_collection_path(const std::filesystem::path& design,
                                                   const CollectionSection& settings);

}  // namespace zerog::rt
