// The importer's kinematics phase (proto/import_mapping.md "kinematics",
// proto/robot_kinematics.md): once the series are merged into the log's rows, the IMU columns
// derived from the robot's joints or the pose, or fused with the IMU (fused_kinematics.hpp).
#include "import_kinematics.hpp"

#include <algorithm>
#include <array>
#include <cstdio>
#include <string>
#include <vector>

#include "zerog/formats/robot_toml.hpp"
#include "zerog/io/fused_kinematics.hpp"
#include "zerog/robot/derive_kinematics.hpp"
#include "zerog/robot/forward_kinematics.hpp"

namespace zerog::io::importer {

using formats::KinematicsOrigin;
using formats::KinematicsRecord;
using formats::Log;
using formats::Sample;
using formats::throw_at;
using formats::to_frame_transform;

// ---------------------------------------------------------------------------------------------
// Kinematics from the robot (proto/import_mapping.md "kinematics", proto/robot_kinematics.md):
// ω, ω̇ and the specific force of S derived from the joint stream (forward kinematics through
// the rig's robot) or the pose stream, at that stream's own samples, then interpolated onto the
// log's rows and expressed at the IMU (the rig's sensor_imu), so that fit and diagnose read them
// as IMU columns. The rig's [kinematics] records which column came from where.

std::string quantity_file(const Mapping& m, const std::array<int, kQuantityCount>& source,
                          Quantity q) {
  return "files." + m.files[static_cast<std::size_t>(source[static_cast<int>(q)])].name + "." +
         std::string(info(q).key);
}

const QuantitySpec& spec_in(const Mapping& m, const std::array<int, kQuantityCount>& source,
                            Quantity q) {
  const FileSpec& file = m.files[static_cast<std::size_t>(source[static_cast<int>(q)])];
  return *std::find_if(file.quantities.begin(), file.quantities.end(),
                       [&](const QuantitySpec& s) { return s.what == q; });
}

// The rig's robot with the rig's flange_sensor, for the mapped joints: one column per joint of
// the robot, in the recording's order (RobotModel::input_index maps them to DH rows). `use` says
// what the joints are needed for.
robot::RobotModel robot_for_joints(const Mapping& m, const fs::path& mapping_path, const Log& log,
                                   const std::array<int, kQuantityCount>& source,
                                   const std::string& use) {
  const QuantitySpec& joints = spec_in(m, source, Quantity::joints);
  robot::RobotModel model = *log.rig.robot_model;
  model.flange_sensor = to_frame_transform(log.rig.flange_sensor);
  if (model.joint_count != joints.num_refs)
    throw_at(mapping_path, joints.where,
             "'" + quantity_file(m, source, Quantity::joints) + "' maps " +
                 std::to_string(joints.num_refs) + " columns, but the rig's robot (" +
                 log.rig.robot + ") has " + std::to_string(model.joint_count) +
                 " joints: map one column per joint, A1 first, to " + use);
  return model;
}

// ω̇ from the gyro: the Savitzky–Golay first derivative of the angular-rate stream at its own
// samples (order 3, the widest window that passes kinematics_bandwidth_hz), interpolated onto
// the log's rows and written as imu_dw*_radps2. A gyro given in the base frame is differenced
// there and rotated per row like ω: for an angular velocity d/dt(R_BSᵀ ω_B) = R_BSᵀ ω̇_B, as
// Ṙ_BSᵀ ω_B = −ω_S × ω_S = 0. Too short a stream leaves ω̇ to host/ident (said in the report).
void differentiate_gyro(const Mapping& m, const std::vector<Series>& series,
                        const std::array<int, kQuantityCount>& source, ImportResult& result) {
  Log& log = result.log;
  KinematicsRecord& record = log.rig.kinematics;
  const std::size_t f = static_cast<std::size_t>(source[static_cast<int>(Quantity::angular_rate)]);
  const QuantitySpec& spec = spec_in(m, source, Quantity::angular_rate);
  const std::vector<double>& t = series[f].t;
  const std::vector<double>& w = series[f].values[static_cast<int>(Quantity::angular_rate)];
  const double period_s = median_period(t);
  const robot::SgSettings sg =
      robot::choose_sg_window(period_s, m.kinematics_accel_bandwidth_hz, robot::kMaxSgOrder, 1);
  const std::size_t window = static_cast<std::size_t>(2 * sg.half_width + 1);
  if (t.size() < window) {
    record.angular_accel_reason +=
        "; but " + quantity_file(m, source, Quantity::angular_rate) + " has " +
        std::to_string(t.size()) + " rows, fewer than the differentiator's " +
        std::to_string(window) + ": host/ident's 5-point difference of the angular rate instead";
    result.report.kinematics += "angular acceleration: " + record.angular_accel_reason + "\n";
    return;
  }
  std::vector<Eigen::Vector3d> rate(t.size()), accel(t.size());
  for (std::size_t i = 0; i < t.size(); ++i) rate[i] = {w[3 * i], w[3 * i + 1], w[3 * i + 2]};
  if (!robot::sg_differentiate(t, rate, sg, 1, accel)) return;  // checked above: cannot happen
  const Eigen::Matrix3d R_sensor_imu = log.rig.sensor_imu.q.normalized().toRotationMatrix();
  std::size_t k = 0;
  for (Sample& s : log.samples) {
    while (k + 1 < t.size() && t[k + 1] <= s.t_s) ++k;
    const std::size_t k1 = std::min(k + 1, t.size() - 1);
    const double alpha = k1 == k ? 0.0 : std::clamp((s.t_s - t[k]) / (t[k1] - t[k]), 0.0, 1.0);
    Eigen::Vector3d v = accel[k] + alpha * (accel[k1] - accel[k]);
    if (spec.frame == VectorFrame::base)
      v = R_sensor_imu.transpose() * s.q_base_sensor.toRotationMatrix().transpose() * v;
    s.angular_accel_imu_radps2 = v;
  }
  log.columns.angular_accel = true;
  record.angular_accel = KinematicsOrigin::imu;
  record.accel_sg_half_width = sg.half_width;
  record.accel_sg_order = sg.order;
  record.accel_period_s = period_s;
  record.accel_bandwidth_hz = m.kinematics_accel_bandwidth_hz;
  record.accel_noise_gain = robot::sg_noise_gain(sg, 1, period_s);
  record.accel_cutoff_hz = robot::sg_cutoff_hz(sg, 1, period_s);
  char buffer[300];
  std::snprintf(buffer, sizeof buffer,
                "angular acceleration from the gyro of files.%s (%zu rows, median period %.4g s): "
                "Savitzky-Golay derivative M = %d, order %d, lag 0, -3 dB %.3g Hz, noise gain "
                "%.3g 1/s\n",
                m.files[f].name.c_str(), t.size(), period_s, sg.half_width, sg.order,
                record.accel_cutoff_hz, record.accel_noise_gain);
  result.report.kinematics += buffer;
}

// The record of the pose's differentiator (ω and the specific force) and of ω̇'s, as the rig's
// [kinematics] keeps them (log_format.md).
void record_differentiator(KinematicsRecord& r, const robot::SgSettings& sg, double period_s,
                           double bandwidth_hz) {
  r.sg_half_width = sg.half_width;
  r.sg_order = sg.order;
  r.period_s = period_s;
  r.bandwidth_hz = bandwidth_hz;
  r.lag_s = 0.0;  // centred window
  r.noise_gain_rate_per_s = robot::sg_noise_gain(sg, 1, period_s);
  r.noise_gain_accel_per_s2 = robot::sg_noise_gain(sg, 2, period_s);
  r.cutoff_rate_hz = robot::sg_cutoff_hz(sg, 1, period_s);
  r.cutoff_accel_hz = robot::sg_cutoff_hz(sg, 2, period_s);
}

void record_accel_differentiator(KinematicsRecord& r, const robot::SgSettings& sg, double period_s,
                                 double bandwidth_hz) {
  r.accel_sg_half_width = sg.half_width;
  r.accel_sg_order = sg.order;
  r.accel_period_s = period_s;
  r.accel_bandwidth_hz = bandwidth_hz;
  r.accel_noise_gain = robot::sg_noise_gain(sg, 2, period_s);
  r.accel_cutoff_hz = robot::sg_cutoff_hz(sg, 2, period_s);
}

/// What derive_from_robot derives, and from which stream (choose_derivation's answer).
struct Derivation {
  bool joints_mapped = false;
  bool joints_ok = false;      ///< from the joints through the rig's robot, else from the pose
  bool pose_position = false;  ///< the pose stream has the position beside the orientation
  bool derive_rate = false;
  bool derive_force = false;
  bool derive_accel = false;
};

// derive_from_robot's first phase: which IMU signals come from the robot (robot::choose_sources),
// the mode's refusals, and ω̇ from the gyro under "auto"; the reasons go to the rig's record.
Derivation choose_derivation(const Mapping& m, const fs::path& mapping_path,
                             const std::vector<Series>& series,
                             const std::array<int, kQuantityCount>& source, ImportResult& result) {
  Log& log = result.log;
  const auto has = [&](Quantity q) { return source[static_cast<int>(q)] >= 0; };
  const auto file_of = [&](Quantity q) {
    return static_cast<std::size_t>(source[static_cast<int>(q)]);
  };
  const auto refuse = [&](const std::string& why) {
    throw_at(mapping_path, m.kinematics_where,
             "'kinematics = \"" + m.kinematics_text + "\"': " + why);
  };
  KinematicsRecord& record = log.rig.kinematics;
  record.mode = m.kinematics_text;
  const bool timed = !log.columns.static_rows;
  const bool joints_mapped = has(Quantity::joints);
  const bool joints_ok = timed && joints_mapped && log.rig.robot_model.has_value();
  const bool pose_position = has(Quantity::position) && has(Quantity::orientation) &&
                             file_of(Quantity::position) == file_of(Quantity::orientation);
  // Without an orientation the import took the pose from the joints (the rig has the robot).
  const bool robot_motion = joints_ok || (timed && has(Quantity::orientation));
  const bool robot_linear = joints_ok || (timed && pose_position);
  const bool robot_mode = m.kinematics == robot::KinematicsMode::robot;

  if (robot_mode && !timed)
    refuse(
        "rows without time (a static table) have no motion to differentiate; use kinematics "
        "= \"imu\" (the default) or record time");
  if (robot_mode && joints_mapped && !log.rig.robot_model)
    refuse(quantity_file(m, source, Quantity::joints) + " is mapped, but the rig (" +
           result.report.rig_source +
           ") does not describe the robot: give it robot_file = \"…/calib/robots/"
           "kr210_r2700.robot.toml\" or a [robot] table with the DH chain (proto/log_format.md), "
           "or remove 'joints' to derive from the pose");
  if (robot_mode && !robot_linear)
    refuse(
        "the sensor's linear acceleration needs the joints (with the rig's robot) or the "
        "position beside the orientation (" +
        quantity_file(m, source, Quantity::orientation) +
        "); the orientation alone gives ω and ω̇ only: map 'joints' or 'position', or use "
        "kinematics = \"auto\" to take ω and ω̇ from the orientation and the specific force "
        "from the accelerometer");

  robot::SourceChoices choice =
      robot::choose_sources(m.kinematics, {.gyro = log.columns.angular_rate,
                                           .accelerometer = log.columns.specific_force,
                                           .robot = robot_motion});
  if (choice.specific_force.source == robot::KinematicSource::robot && !robot_linear)
    choice.specific_force = {robot::KinematicSource::none,
                             "the orientation alone gives ω and ω̇, not the linear acceleration "
                             "(map 'position' beside it, or 'joints' with the rig's robot)"};
  record.angular_rate_reason = choice.omega.reason;
  record.specific_force_reason = choice.specific_force.reason;
  // A logged ω̇ is the IMU's own signal: "auto" keeps it, as it keeps a logged gyro.
  const bool accel_logged = log.columns.angular_accel;
  if (accel_logged) {
    choice.omega_dot = {robot::KinematicSource::imu, record.angular_accel_reason};
  } else {
    record.angular_accel_reason = choice.omega_dot.reason;
  }
  const bool derive_rate = choice.omega.source == robot::KinematicSource::robot;
  const bool derive_force = choice.specific_force.source == robot::KinematicSource::robot;
  const bool derive_accel = choice.omega_dot.source == robot::KinematicSource::robot;
  // ω̇ from the gyro under "auto": its Savitzky–Golay derivative, as measured best
  // (robot_kinematics.md "Choosing the source"); "imu" leaves it to host/ident's 5-point
  // difference, as before.
  if (choice.omega_dot.source == robot::KinematicSource::imu && !accel_logged &&
      m.kinematics == robot::KinematicsMode::automatic && timed && log.columns.angular_rate)
    differentiate_gyro(m, series, source, result);
  if (!timed && log.columns.angular_rate && !accel_logged)
    record.angular_accel_reason = "rows without time (static samples): no angular acceleration";
  return {joints_mapped, joints_ok, pose_position, derive_rate, derive_force, derive_accel};
}

// derive_from_robot's last step on the samples: the derived motion (at the stream's times t) onto
// the log's rows.
void motion_onto_rows(Log& log, const std::vector<double>& t,
                      const std::vector<robot::SensorKinematics>& motion,
                      const std::vector<robot::SensorKinematics>& accel_motion, bool derive_rate,
                      bool derive_force, bool derive_accel) {
  // Onto the log's rows (linear interpolation; every row lies within the stream's span), at
  // the IMU: ω_I = R_SIᵀ ω_S, f_I = R_SIᵀ (f_S + ω̇ × r + ω × (ω × r)), r = p_SI.
  const Eigen::Matrix3d R_sensor_imu = log.rig.sensor_imu.q.normalized().toRotationMatrix();
  const Eigen::Vector3d p_sensor_imu = log.rig.sensor_imu.p_m;
  std::size_t k = 0;
  for (Sample& s : log.samples) {
    while (k + 1 < t.size() && t[k + 1] <= s.t_s) ++k;
    const std::size_t k1 = std::min(k + 1, t.size() - 1);
    const double alpha = k1 == k ? 0.0 : std::clamp((s.t_s - t[k]) / (t[k1] - t[k]), 0.0, 1.0);
    robot::SensorKinematics at;
    const robot::SensorKinematics& a = motion[k];
    const robot::SensorKinematics& b = motion[k1];
    at.omega_sensor_radps =
        a.omega_sensor_radps + alpha * (b.omega_sensor_radps - a.omega_sensor_radps);
    at.omega_dot_sensor_radps2 =
        a.omega_dot_sensor_radps2 + alpha * (b.omega_dot_sensor_radps2 - a.omega_dot_sensor_radps2);
    at.specific_force_sensor_mps2 =
        a.specific_force_sensor_mps2 +
        alpha * (b.specific_force_sensor_mps2 - a.specific_force_sensor_mps2);
    if (derive_rate) s.angular_rate_imu_radps = R_sensor_imu.transpose() * at.omega_sensor_radps;
    // ω̇ of a rigid body is the same vector at every point: ω̇_I = R_SIᵀ ω̇_S.
    if (derive_accel)
      s.angular_accel_imu_radps2 =
          R_sensor_imu.transpose() * (accel_motion[k].omega_dot_sensor_radps2 +
                                      alpha * (accel_motion[k1].omega_dot_sensor_radps2 -
                                               accel_motion[k].omega_dot_sensor_radps2));
    if (derive_force)
      s.specific_force_imu_mps2 =
          R_sensor_imu.transpose() * robot::specific_force_at_point(at, p_sensor_imu);
  }
}

// The derived columns marked in the log, the differentiators in the rig's record and the report.
void record_derivation(Log& log, const Mapping& m, KinematicsOrigin origin, const Derivation& d,
                       const robot::SgSettings& sg, const robot::SgSettings& accel_sg,
                       double period_s, std::size_t f, std::size_t rows, ImportReport& report) {
  KinematicsRecord& record = log.rig.kinematics;
  const bool derive_rate = d.derive_rate;
  const bool derive_force = d.derive_force;
  const bool derive_accel = d.derive_accel;
  const bool joints_ok = d.joints_ok;
  const bool joints_mapped = d.joints_mapped;
  if (derive_rate) {
    log.columns.angular_rate = true;
    record.angular_rate = origin;
  }
  if (derive_force) {
    log.columns.specific_force = true;
    record.specific_force = origin;
  }
  if (derive_accel) {
    log.columns.angular_accel = true;
    record.angular_accel = origin;
    record_accel_differentiator(record, accel_sg, period_s, m.kinematics_accel_bandwidth_hz);
    char line[200];
    std::snprintf(line, sizeof line,
                  "angular acceleration: its own Savitzky-Golay second derivative M = %d, order "
                  "%d (kinematics_accel_bandwidth_hz %.3g Hz), -3 dB %.3g Hz, noise gain %.3g "
                  "1/s^2\n",
                  record.accel_sg_half_width, record.accel_sg_order, record.accel_bandwidth_hz,
                  record.accel_cutoff_hz, record.accel_noise_gain);
    report.kinematics += line;
  }
  record_differentiator(record, sg, period_s, m.kinematics_bandwidth_hz);

  char buffer[400];
  std::snprintf(buffer, sizeof buffer,
                "%s from the %s of files.%s (%zu rows, median period %.4g s%s): Savitzky-Golay "
                "M = %d, order %d, lag 0, -3 dB %.3g Hz (rate) / %.3g Hz (acceleration), noise "
                "gain %.3g 1/s (rate) / %.3g 1/s^2 (acceleration)\n",
                derive_rate && derive_force ? "angular rate and specific force"
                : derive_rate               ? "angular rate"
                                            : "specific force",
                joints_ok ? "joints" : "pose", m.files[f].name.c_str(), rows, period_s,
                joints_ok ? (", through " + log.rig.robot + "'s forward kinematics").c_str() : "",
                sg.half_width, sg.order, record.cutoff_rate_hz, record.cutoff_accel_hz,
                record.noise_gain_rate_per_s, record.noise_gain_accel_per_s2);
  report.kinematics += buffer;
  if (!joints_ok && joints_mapped)
    report.kinematics +=
        "  (the joints are mapped but the rig describes no robot: give it robot_file or a "
        "[robot] table to derive from them)\n";
}

void derive_from_robot(const Mapping& m, const fs::path& mapping_path,
                       const std::vector<Series>& series,
                       const std::array<int, kQuantityCount>& source, ImportResult& result) {
  const Derivation d = choose_derivation(m, mapping_path, series, source, result);
  if (!d.derive_rate && !d.derive_force && !d.derive_accel) return;
  Log& log = result.log;
  const auto file_of = [&](Quantity q) {
    return static_cast<std::size_t>(source[static_cast<int>(q)]);
  };
  const auto refuse = [&](const std::string& why) {
    throw_at(mapping_path, m.kinematics_where,
             "'kinematics = \"" + m.kinematics_text + "\"': " + why);
  };
  const bool joints_ok = d.joints_ok;
  const bool pose_position = d.pose_position;
  const bool derive_accel = d.derive_accel;

  // The stream: the joints through the robot if possible, else the pose.
  const KinematicsOrigin origin = joints_ok ? KinematicsOrigin::joints : KinematicsOrigin::pose;
  const Quantity stream_quantity = joints_ok ? Quantity::joints : Quantity::orientation;
  const std::size_t f = file_of(stream_quantity);
  const std::vector<double>& t = series[f].t;
  const double period_s = median_period(t);
  const robot::SgSettings sg =
      robot::choose_sg_window(period_s, m.kinematics_bandwidth_hz, robot::kMaxSgOrder, 2);
  const std::size_t window = static_cast<std::size_t>(2 * sg.half_width + 1);
  if (t.size() < window)
    refuse(quantity_file(m, source, stream_quantity) + " has " + std::to_string(t.size()) +
           " rows; the differentiator needs at least " + std::to_string(window) + " (2M+1 at " +
           num(period_s) + " s, " + num(m.kinematics_bandwidth_hz) +
           " Hz): record longer or raise kinematics_bandwidth_hz");
  robot::DifferentiatorSettings settings;
  settings.sg = sg;
  std::vector<robot::SensorKinematics> motion(t.size());
  auto derive = [&](const robot::DifferentiatorSettings& with,
                    std::vector<robot::SensorKinematics>& into) {
    robot::DeriveStatus status;
    if (joints_ok) {
      const robot::RobotModel model = robot_for_joints(
          m, mapping_path, log, source,
          "derive the sensor's motion (kinematics = \"" + m.kinematics_text + "\")");
      status =
          robot::derive_kinematics(model, t, series[f].values[static_cast<int>(Quantity::joints)],
                                   static_cast<std::size_t>(model.joint_count), with, into);
    } else {
      const std::vector<double>& q = series[f].values[static_cast<int>(Quantity::orientation)];
      const std::vector<double>* p =
          pose_position ? &series[f].values[static_cast<int>(Quantity::position)] : nullptr;
      std::vector<robot::Pose> poses(t.size());
      for (std::size_t i = 0; i < t.size(); ++i) {
        Eigen::Quaterniond R(q[4 * i], q[4 * i + 1], q[4 * i + 2], q[4 * i + 3]);
        Eigen::Vector3d position =
            p ? Eigen::Vector3d((*p)[3 * i], (*p)[3 * i + 1], (*p)[3 * i + 2]) : Eigen::Vector3d();
        if (p == nullptr) position.setZero();
        if (m.pose_of_flange) {  // p_BS = p_BF + R_BF p_FS, R_BS = R_BF R_FS (frames.md)
          position += R * log.rig.flange_sensor.p_m;
          R = R * log.rig.flange_sensor.q;
        }
        poses[i].R = R.normalized().toRotationMatrix();
        poses[i].p_m = position;
      }
      status = robot::derive_kinematics(t, poses, with, into);
    }
    if (!status.ok())  // the reader checked times and sizes: only a broken model remains
      refuse("deriving the motion failed (code " + std::to_string(static_cast<int>(status.code)) +
             ", sample " + std::to_string(status.sample) + ")");
  };
  derive(settings, motion);
  // ω̇ with its own, wider window (kinematics_accel_bandwidth_hz), if the stream allows it.
  robot::DifferentiatorSettings accel_settings;
  accel_settings.sg =
      robot::choose_sg_window(period_s, m.kinematics_accel_bandwidth_hz, robot::kMaxSgOrder, 2);
  std::vector<robot::SensorKinematics> accel_motion;
  if (derive_accel) {
    accel_motion.resize(t.size());
    derive(accel_settings, accel_motion);
  }

  motion_onto_rows(log, t, motion, accel_motion, d.derive_rate, d.derive_force, derive_accel);
  record_derivation(log, m, origin, d, sg, accel_settings.sg, period_s, f, t.size(), result.report);
}

// -------------------------------------------------------------------------------------------------

// kinematics = "fused" (fused_kinematics.hpp): every IMU column from the joints and the IMU
// together. Needs time, the joints with the rig's robot, the accelerometer and the gyro.
void fuse_joints_and_imu(const Mapping& m, const fs::path& mapping_path,
                         const std::vector<Series>& series,
                         const std::array<int, kQuantityCount>& source, ImportResult& result) {
  Log& log = result.log;
  const auto refuse = [&](const std::string& why) {
    throw_at(mapping_path, m.kinematics_where, "'kinematics = \"fused\"': " + why);
  };
  const int joints_file = source[static_cast<int>(Quantity::joints)];
  if (log.columns.static_rows)
    refuse("rows without time (a static table) have no motion to fuse; use kinematics = \"imu\"");
  if (joints_file < 0)
    refuse(
        "the joints are not mapped: map 'joints' (and give the rig its robot) to fuse them "
        "with the IMU, or use kinematics = \"imu\"");
  if (!log.rig.robot_model)
    refuse(quantity_file(m, source, Quantity::joints) + " is mapped, but the rig (" +
           result.report.rig_source +
           ") does not describe the robot: give it robot_file = \"…/calib/robots/"
           "kr210_r2700.robot.toml\" or a [robot] table (proto/log_format.md)");
  if (!log.columns.specific_force || !log.columns.angular_rate)
    refuse(std::string("the IMU's ") +
           (log.columns.specific_force ? "angular_rate" : "specific_force") +
           " is not mapped; the fusion needs the accelerometer and the gyro: map both, or use "
           "kinematics = \"auto\" (each signal from the IMU where it is logged, else the robot)");
  if (log.columns.angular_accel)
    refuse(quantity_file(m, source, Quantity::angular_accel) +
           " is a logged angular acceleration, which the fusion would replace: use "
           "kinematics = \"auto\" to keep it, or remove 'angular_accel'");
  const robot::RobotModel model =
      robot_for_joints(m, mapping_path, log, source, "fuse them with the IMU");
  const std::vector<double>& t = series[static_cast<std::size_t>(joints_file)].t;
  const double period_s = median_period(t);
  const FusionSettings settings =
      fusion_settings(period_s, m.kinematics_bandwidth_hz, m.kinematics_accel_bandwidth_hz,
                      m.kinematics_crossover_hz);
  // The widest of the fusion's three Savitzky–Golay windows.
  const std::size_t window =
      static_cast<std::size_t>(2 * std::max({settings.sg.half_width, settings.accel_sg.half_width,
                                             settings.excitation_sg.half_width}) +
                               1);
  if (t.size() < window)
    refuse(quantity_file(m, source, Quantity::joints) + " has " + std::to_string(t.size()) +
           " rows; the fusion's widest Savitzky-Golay window needs at least " +
           std::to_string(window) +
           " (the motor's acceleration at 5 Hz, or kinematics_bandwidth_hz and "
           "kinematics_accel_bandwidth_hz): record longer, or use kinematics = \"imu\"");
  const std::size_t rows = log.samples.size();
  const RowSignals signals = row_signals(log);
  FusionInput in = fusion_input(signals);
  in.robot = &model;
  in.joint_t_s = t;
  in.joints_rad =
      series[static_cast<std::size_t>(joints_file)].values[static_cast<int>(Quantity::joints)];
  in.R_sensor_imu = log.rig.sensor_imu.q.normalized().toRotationMatrix();
  in.p_sensor_imu_m = log.rig.sensor_imu.p_m;
  const FusionResult fused = fuse_kinematics(in, settings);
  for (std::size_t r = 0; r < rows; ++r) {
    Sample& s = log.samples[r];
    s.specific_force_imu_mps2 = fused.specific_force_mps2[r];
    s.angular_rate_imu_radps = fused.angular_rate_radps[r];
    s.angular_accel_imu_radps2 = fused.angular_accel_radps2[r];
  }
  log.columns.angular_accel = true;
  KinematicsRecord& k = log.rig.kinematics;
  k.mode = "fused";
  k.crossover_hz = settings.crossover_hz;
  k.angular_rate = k.specific_force = k.angular_accel = KinematicsOrigin::fused;
  const std::string why = "the joints (" + log.rig.robot + (fused.elastic ? ", elastic" : "") +
                          ") above " + num(settings.crossover_hz) + " Hz, the IMU below";
  k.angular_rate_reason = k.specific_force_reason = k.angular_accel_reason = why;
  record_differentiator(k, settings.sg, period_s, m.kinematics_bandwidth_hz);
  record_accel_differentiator(k, settings.accel_sg, period_s, m.kinematics_accel_bandwidth_hz);
  std::string text =
      "kinematics = \"fused\": angular rate, specific force and angular "
      "acceleration from " +
      why + " (zero phase)\n";
  char line[400];
  std::snprintf(line, sizeof line,
                "  joints of files.%s (%zu rows, median period %.4g s): Savitzky-Golay M = %d "
                "(-3 dB %.3g Hz rate / %.3g Hz acceleration), omega_dot M = %d (-3 dB %.3g Hz); "
                "the IMU corrected %.3g m/s^2 and %.3g rad/s RMS\n",
                m.files[static_cast<std::size_t>(joints_file)].name.c_str(), t.size(), period_s,
                settings.sg.half_width, k.cutoff_rate_hz, k.cutoff_accel_hz,
                settings.accel_sg.half_width, k.accel_cutoff_hz,
                fused.correction_specific_force_mps2, fused.correction_angular_rate_radps);
  text += line;
  if (fused.elastic) {
    text += "  the link's deflection from the robot file's elasticity (mean / RMS about it, mrad):";
    for (std::size_t j = 0; j < fused.deflection_rms_rad.size(); ++j) {
      std::snprintf(line, sizeof line, " A%zu %.3g/%.3g", j + 1, 1e3 * fused.deflection_mean_rad[j],
                    1e3 * fused.deflection_rms_rad[j]);
      text += line;
    }
    text += "\n";
  } else {
    text +=
        "  the robot file gives no elasticity: the joints are taken as the link's (a rigid "
        "arm); the IMU corrects only below the crossover\n";
  }
  result.report.kinematics = text;
}

}  // namespace zerog::io::importer
