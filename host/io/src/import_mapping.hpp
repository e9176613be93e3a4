// The importer's mapping (proto/import_mapping.md): what the user says each file holds, in which
// columns, units and frames. Internal to host/io: read_mapping (import_mapping.cpp) makes it,
// the reading, merging and kinematics phases (import_series.cpp, import.cpp,
// import_kinematics.cpp) consume it.
#pragma once

#include <array>
#include <filesystem>
#include <limits>
#include <numbers>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Geometry>

#include "zerog/formats/detail/rig_toml.hpp"
#include "zerog/io/fused_kinematics.hpp"
#include "zerog/io/import.hpp"
#include "zerog/robot/derive_kinematics.hpp"

namespace zerog::io::importer {

namespace fs = std::filesystem;

using formats::detail::throw_at;
using formats::detail::TomlTable;

// ---------------------------------------------------------------------------------------------
// What a mapping can name, and in which units (proto/import_mapping.md).

enum class Quantity : int {
  force,
  torque,
  position,
  orientation,
  joints,
  specific_force,
  angular_rate,
  angular_accel,
  temperature
};
constexpr int kQuantityCount = 9;

enum class Orientation { quaternion, matrix, kuka_abc };

/// The axes a vector quantity's columns are written in: its own frame (S for force and torque,
/// I for the IMU), the robot base B (rotated into S or I per row with the row's orientation), or
/// a fixed frame D given by its rotation in the own frame and, for the wrench, its origin in S
/// (a torque about D's origin is moved to S's with the force: M_S = R_SD M_D + p_SD × F_S).
enum class VectorFrame { own, base, fixed };

struct Unit {
  std::string_view name;
  double scale;
  double offset = 0.0;  ///< SI value = file value × scale + offset
};

constexpr double kDegree = std::numbers::pi / 180.0;

struct QuantityInfo {
  std::string_view key;      ///< key in a [files.NAME] table
  int width;                 ///< columns in the file (orientation: by type; joints: 1..8)
  int stored;                ///< values kept per row (joints: as many as columns)
  std::vector<Unit> units;   ///< accepted units; empty = unitless
  std::string_view meaning;  ///< for messages
};

const std::array<QuantityInfo, kQuantityCount>& quantity_infos();
const QuantityInfo& info(Quantity q);

std::string num(double v);
std::string where_text(const fs::path& file, const toml::source_region& where);

// ---------------------------------------------------------------------------------------------
// The mapping, read.

struct ColumnRef {
  std::string name;           ///< header name in the data file ("column N" if by number)
  int number = 0;             ///< 1-based column number if the mapping gives a number
  toml::source_region where;  ///< where the mapping names it
  std::string key;            ///< mapping key naming it, e.g. "files.ft.force"
  int cell = -1;              ///< resolved cell index in the data file
};

struct QuantitySpec {
  Quantity what;
  int first_ref = 0;  ///< index of its first column in FileSpec::refs
  int num_refs = 0;
  double scale = 1.0;
  double offset = 0.0;
  Orientation orientation = Orientation::quaternion;
  VectorFrame frame = VectorFrame::own;
  Eigen::Matrix3d R_own_fixed = Eigen::Matrix3d::Identity();  ///< VectorFrame::fixed: D in own
  /// VectorFrame::fixed with p_m: D's origin in S, m (force and torque only; for the force it
  /// changes nothing, for the torque it adds p × F_S).
  std::optional<Eigen::Vector3d> p_own_fixed_m;
  toml::source_region where;
  toml::source_region frame_where;
  toml::source_region lever_where;  ///< where p_m is given
};

struct FileSpec {
  std::string name;
  fs::path path;
  toml::source_region path_where;
  char delimiter = ',';
  char decimal = '.';
  std::string comment = "#";
  int skip_lines = 0;
  bool header = true;    ///< the first data line names the columns
  bool has_time = true;  ///< a time column is mapped (else rows are static samples)
  /// A static file's pose index column is mapped (refs[0]): files are joined by its value.
  bool has_index = false;
  std::string index_name;  ///< the index column's name (header, or "column N")
  toml::source_region where;
  std::string time_unit;
  double time_scale = 1.0;
  double time_offset_s = 0.0;
  double max_gap_s = std::numeric_limits<double>::infinity();
  std::vector<ColumnRef> refs;  ///< refs[0] is the time column if has_time, else the pose index
  std::vector<QuantitySpec> quantities;
};

// ω̇ feeds the rotational inertia as a regressor: a differentiator that cuts into the motion's
// band shrinks it and the fit answers with a larger inertia (errors in variables), while the
// fit's block means average white noise away. So ω̇ gets a wider band than ω
// (robot_kinematics.md, "ω̇ for the fit").
constexpr double kDefaultAccelBandwidthHz = 15.0;

struct Mapping {
  std::vector<FileSpec> files;  ///< master first
  bool pose_of_flange = false;
  std::optional<formats::Rig> rig;  ///< from the [rig] table
  bool rig_has_period = true;       ///< the [rig] table gave sample_period_s
  std::optional<fs::path> rig_file;
  /// `kinematics`: where ω, ω̇ and the specific force come from (proto/import_mapping.md).
  robot::KinematicsMode kinematics = robot::KinematicsMode::imu;
  std::string kinematics_text = "imu";
  toml::source_region kinematics_where;
  double kinematics_bandwidth_hz = 5.0;  ///< the differentiator's bandwidth (choose_sg_window)
  /// The bandwidth of ω̇'s differentiator (the gyro's first or the robot's second derivative).
  double kinematics_accel_bandwidth_hz = kDefaultAccelBandwidthHz;
  /// kinematics = "fused" (fused_kinematics.hpp): the joints and the IMU together; `kinematics`
  /// then stays `imu` for the checks of the logged columns.
  bool fused = false;
  double kinematics_crossover_hz = kFusedCrossoverHz;
};

/// The mapping file at `mapping`, checked; `rig_given`: --rig replaces its rig.
Mapping read_mapping(const fs::path& mapping, bool rig_given);

}  // namespace zerog::io::importer
