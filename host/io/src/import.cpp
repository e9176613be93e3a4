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

namespace zerog::io {

using formats::InputError;
using formats::KinematicsOrigin;
using formats::KinematicsRecord;
using formats::Log;
using formats::read_rig;
using formats::Sample;
using formats::throw_at;
using formats::to_string;
using formats::write_log;

using namespace importer;

namespace {

// The reading phase: every file of the mapping read into its series (their rows counted in the
// report), a static table split over files joined row by row or by pose index.
std::vector<Series> read_recordings(Mapping& mapping, const fs::path& mapping_path,
                                    ImportResult& result) {
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
  return series;
}

// The rig: --rig, else the mapping's rig_file or [rig] table (its period, if it gives none, the
// master's median).
void choose_rig(const Mapping& mapping, const std::optional<fs::path>& rig_file,
                const std::vector<Series>& series, ImportResult& result) {
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
}

// Where master row i falls in every other file (brackets[f], found from cursor[f] on); false if
// it lies before, after or in a gap of one of them (counted in that file's report).
bool bracket_row(const Mapping& mapping, const std::vector<Series>& series, std::size_t i,
                 std::vector<Bracket>& brackets, std::vector<std::size_t>& cursor,
                 ImportReport& report) {
  const double t = series.front().t[i];
  bool keep = true;
  brackets[0] = {i, i, 0.0};
  for (std::size_t f = 1; f < mapping.files.size(); ++f) {
    const std::vector<double>& tf = series[f].t;
    ImportFileReport& r = report.files[f];
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
  return keep;
}

// The kinematics phase: where the IMU columns come from (kinematics = "imu", "robot", "auto" or
// "fused"), the rig's [kinematics] record and the report's account of it.
void kinematics_phase(const Mapping& mapping, const fs::path& mapping_path,
                      const std::vector<Series>& series,
                      const std::array<int, kQuantityCount>& source,
                      const std::array<const QuantitySpec*, kQuantityCount>& spec_of,
                      ImportResult& result) {
  Log& log = result.log;
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
    return;
  }
  if (mapping.kinematics == robot::KinematicsMode::imu) {  // the columns as logged
    refuse_accel_without_rate();
    if (log.columns.angular_accel)
      result.report.kinematics =
          "angular acceleration: " + log.rig.kinematics.angular_accel_reason + "\n";
    return;
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
}

// Which file provides each quantity (source[q], -1 if none), and how (spec_of[q]).
void find_sources(const Mapping& mapping, std::array<int, kQuantityCount>& source,
                  std::array<const QuantitySpec*, kQuantityCount>& spec_of) {
  source.fill(-1);
  for (std::size_t f = 0; f < mapping.files.size(); ++f) {
    for (const QuantitySpec& q : mapping.files[f].quantities) {
      source[static_cast<int>(q.what)] = static_cast<int>(f);
      spec_of[static_cast<int>(q.what)] = &q;
    }
  }
}

// The report's line on the joints: how many, where from, what they are used for.
std::string joints_report(const Mapping& mapping, const std::array<int, kQuantityCount>& source,
                          const Log& log, int joint_columns, bool pose_from_joints) {
  return "joints: " + std::to_string(joint_columns) + " columns (" +
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

// The row's vectors in their frames: force and torque logged with base-frame axes rotated into S
// (and the torque moved to S's origin), the joints kept, the IMU columns and the temperature
// interpolated at the row's brackets (merge_rows' last step for each row).
void vectors_of_row(Sample& s, const Log& log, const std::vector<Series>& series,
                    const std::array<int, kQuantityCount>& source,
                    const std::array<const QuantitySpec*, kQuantityCount>& spec_of,
                    const std::vector<Bracket>& brackets,
                    const std::optional<Eigen::Vector3d>& torque_lever_arm_m,
                    const std::array<double, robot::kMaxJoints>& joints_row,
                    const Eigen::Matrix3d& R_sensor_imu) {
  auto values = [&](Quantity q) -> const std::vector<double>& {
    return series[source[static_cast<int>(q)]].values[static_cast<int>(q)];
  };
  auto bracket = [&](Quantity q) -> const Bracket& {
    return brackets[source[static_cast<int>(q)]];
  };
  auto in_base = [&](Quantity q) {
    return source[static_cast<int>(q)] >= 0 &&
           spec_of[static_cast<int>(q)]->frame == VectorFrame::base;
  };
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

}  // namespace

ImportResult import_recordings(const fs::path& mapping_path,
                               const std::optional<fs::path>& rig_file) {
  Mapping mapping = read_mapping(mapping_path, rig_file.has_value());
  ImportResult result;
  result.inputs.push_back(mapping_path);

  std::vector<Series> series = read_recordings(mapping, mapping_path, result);

  Log& log = result.log;
  choose_rig(mapping, rig_file, series, result);

  // Which file provides each quantity, and how.
  std::array<int, kQuantityCount> source;
  std::array<const QuantitySpec*, kQuantityCount> spec_of{};
  find_sources(mapping, source, spec_of);
  auto has = [&](Quantity q) { return source[static_cast<int>(q)] >= 0; };
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
  if (has(Quantity::joints))
    result.report.joints = joints_report(mapping, source, log, joint_columns, pose_from_joints);
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
    if (!bracket_row(mapping, series, i, brackets, cursor, result.report)) continue;

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
    vectors_of_row(s, log, series, source, spec_of, brackets, torque_lever_arm_m, joints_row,
                   R_sensor_imu);
  }
  result.report.rows_out = log.samples.size();
  if (log.samples.empty()) {
    throw std::runtime_error("nothing to import: none of the " + std::to_string(t_master.size()) +
                             " master rows lies within the time span of every file (check "
                             "time units and time_offset_s)\n" +
                             result.report.summary());
  }
  kinematics_phase(mapping, mapping_path, series, source, spec_of, result);
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
