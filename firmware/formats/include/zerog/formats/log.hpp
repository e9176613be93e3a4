#pragma once
// The zerog log format (proto/log_format.md): a versioned CSV of synchronized samples plus a
// TOML rig description beside it. SI units throughout; every vector names its frame.
// zerog::formats: written by zerog-rt's recorder and by the host tools, read by both (read_rig at
// zerog-rt's start-up). Allocates and throws; never called from the cycle.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "zerog/robot/robot_model.hpp"

namespace zerog::formats {

/// The newest log CSV format version this build reads and writes (proto/log_format.md). A log
/// that fits version 1 (time, position and both or no IMU groups) is still written as version 1.
inline constexpr int kLogFormatVersion = 2;
/// The rig sidecar's format version.
inline constexpr int kRigFormatVersion = 1;

/// A rigid transform: the pose of a child frame in a parent frame.
struct Transform {
  Eigen::Vector3d p_m = Eigen::Vector3d::Zero();          ///< child origin in parent, m
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();  ///< child axes in parent, unit
};

/// Where a log's IMU columns came from (proto/log_format.md, the rig's `[kinematics]`):
/// logged by an IMU, or derived by `zerog import` (kinematics = "robot" | "auto") from the joint
/// stream through the rig's robot, or from the pose stream (robot::derive_kinematics). For the
/// angular acceleration `imu` is the gyro differenced at import, and `logged` a ω̇ the recording
/// itself held (the import mapping's `angular_accel`), used as logged.
/// fused: the joints and the IMU together (zerog import's kinematics = "fused", issue 28).
enum class KinematicsOrigin : std::uint8_t { imu, joints, pose, logged, fused };
const char* to_string(KinematicsOrigin origin);

/// The rig's `[kinematics]` table: per IMU group its origin, and the differentiator that derived
/// it (zero when nothing is derived). host/ident reads it to say which source fed which effect.
struct KinematicsRecord {
  /// the import mapping's `kinematics`: "imu", "robot", "auto" or "fused"
  std::string mode = "imu";
  /// "fused": below it the IMU, above it the joints (Hz; 0 for the other modes).
  double crossover_hz = 0.0;
  KinematicsOrigin angular_rate = KinematicsOrigin::imu;    ///< of imu_w*_radps, if present
  KinematicsOrigin specific_force = KinematicsOrigin::imu;  ///< of imu_f*_mps2, if present
  std::string angular_rate_reason;    ///< why (robot::choose_sources' sentence)
  std::string specific_force_reason;  ///< why
  // The Savitzky–Golay differentiator (proto/robot_kinematics.md) of the derived stream:
  int sg_half_width = 0;                 ///< M: 2M+1 samples a window
  int sg_order = 0;                      ///< polynomial order
  double period_s = 0.0;                 ///< median sample period of the differentiated stream, s
  double bandwidth_hz = 0.0;             ///< the bandwidth asked for (choose_sg_window), Hz
  double lag_s = 0.0;                    ///< 0: centred window
  double noise_gain_rate_per_s = 0.0;    ///< σ(ω) per σ(angle): 1st derivative, 1/s
  double noise_gain_accel_per_s2 = 0.0;  ///< σ(ω̇, a) per σ(angle or m): 2nd derivative, 1/s²
  double cutoff_rate_hz = 0.0;           ///< −3 dB of the 1st derivative, Hz
  double cutoff_accel_hz = 0.0;          ///< −3 dB of the 2nd derivative, Hz
  /// Of the angular-acceleration columns imu_dw*_radps2, if the log has them: the gyro
  /// differenced by Savitzky–Golay at import (imu), the robot's second derivative (joints,
  /// pose; the differentiator above), or the recording's own (logged). Without them
  /// host/ident differences imu_w*_radps.
  KinematicsOrigin angular_accel = KinematicsOrigin::imu;
  std::string angular_accel_reason;  ///< why (robot::choose_sources' sentence)
  // ω̇'s own Savitzky–Golay differentiator (with the columns; 0 without): the gyro's first
  // derivative (angular_accel == imu) or the robot stream's second (joints, pose), on a window
  // chosen for the mapping's kinematics_accel_bandwidth_hz, wider than ω's.
  int accel_sg_half_width = 0;      ///< M
  int accel_sg_order = 0;           ///< polynomial order
  double accel_period_s = 0.0;      ///< median sample period of the differentiated stream, s
  double accel_bandwidth_hz = 0.0;  ///< the bandwidth asked for, Hz
  /// σ(ω̇) per σ of the input: 1/s per rad/s (gyro) or 1/s² per rad (robot)
  double accel_noise_gain = 0.0;
  double accel_cutoff_hz = 0.0;  ///< −3 dB of the derivative, Hz
  /// True when imu_w* or imu_f* was derived from the robot (not logged by an IMU).
  bool derived() const {
    return angular_rate != KinematicsOrigin::imu || specific_force != KinematicsOrigin::imu;
  }
};

/// How each row's IMU reading was formed (proto/log_format.md, the rig's `[imu_sampling]`):
/// `point`, one IMU sample at the row time (as many loggers write them); `mean`, the mean of the
/// IMU's native samples over the row period; `unknown` when the rig does not say (every log before
/// the table). host/ident corrects the fit for the IMU's noise by default on `point` rows
/// (ident::FitOptions::errors_in_variables).
enum class ImuRows : std::uint8_t { unknown, mean, point };
const char* to_string(ImuRows rows);

/// The rig's `[imu_sampling]` table: how the IMU rows were formed and, if known, the white noise
/// of one logged row (standard deviation per axis, IMU frame I; 0 = not given).
struct ImuSampling {
  ImuRows rows = ImuRows::unknown;
  double gyro_noise_radps = 0.0;  ///< σ of one row of imu_w*_radps, rad/s (0: unknown)
  double accel_noise_mps2 = 0.0;  ///< σ of one row of imu_f*_mps2, m/s² (0: unknown)
  bool operator==(const ImuSampling&) const = default;
};

/// The rig description (the `.rig.toml` sidecar).
struct Rig {
  std::string name = "unnamed";
  std::string robot = "KR 210 R2700";  ///< the robot's name
  /// The arm's kinematics (DH chain, proto/robot_kinematics.md), if the rig describes it: a
  /// `[robot]` table or `robot_file`. Its flange_sensor is this rig's flange_sensor.
  std::optional<robot::RobotModel> robot_model;
  KinematicsRecord kinematics;     ///< where the IMU columns came from
  ImuSampling imu_sampling;        ///< how the IMU rows were formed (and their noise)
  Transform flange_sensor;         ///< F/T sensor frame S in the flange frame F
  Transform sensor_imu;            ///< IMU frame I in the sensor frame S
  double sample_period_s = 0.012;  ///< log row period (rows need not be exactly uniform)
  double ft_rate_hz = 0.0;         ///< native F/T rate, 0 if unknown
  double imu_rate_hz = 0.0;        ///< native IMU rate, 0 if unknown
  double floor_z_m = 0.0;          ///< floor height in the base frame (for designs), m
  /// A table's rows (no t_s) are in the order they were recorded (`row_order = "recorded"`, the
  /// default: the row index is their time order), or not (`"unknown"`: sorted, merged, shuffled;
  /// then nothing may drift over them).
  bool rows_in_recorded_order = true;
};

/// Which optional column groups the log has. Initialise by name (`Columns{.joints = true}`).
struct Columns {
  bool joints = false;          ///< q1_rad..q6_rad
  bool specific_force = false;  ///< imu_fx_mps2..imu_fz_mps2 (accelerometer)
  bool angular_rate = false;    ///< imu_wx_radps..imu_wz_radps (gyroscope)
  /// imu_dwx_radps2..imu_dwz_radps2: ω̇ formed at import (version 2, only with angular_rate);
  /// without it host/ident differences the angular-rate column.
  bool angular_accel = false;
  bool temperature = false;  ///< temp_C
  bool position = true;      ///< px_m..pz_m; false: the pose is the orientation alone
  /// No t_s column: every row is an independent static sample (a pose held still; a static
  /// calibration table). Nothing is differenced across rows; Sample::t_s holds the row index.
  bool static_rows = false;
  /// Both IMU groups (what the version-1 format called "the IMU columns").
  bool full_imu() const { return specific_force && angular_rate; }
  /// At least one IMU group.
  bool any_imu() const { return specific_force || angular_rate; }
  bool operator==(const Columns&) const = default;
};

/// One synchronized sample (one CSV row).
struct Sample {
  double t_s = 0.0;  ///< time, s (strictly increasing); the row index 0, 1, … if static_rows
  std::array<double, 6> joints_rad{};  ///< A1..A6, rad (if Columns::joints)
  Eigen::Vector3d p_base_sensor_m =
      Eigen::Vector3d::Zero();  ///< sensor origin in base, m (if position)
  Eigen::Quaterniond q_base_sensor = Eigen::Quaterniond::Identity();   ///< sensor axes in base
  Eigen::Vector3d specific_force_imu_mps2 = Eigen::Vector3d::Zero();   ///< IMU frame, a − g
  Eigen::Vector3d angular_rate_imu_radps = Eigen::Vector3d::Zero();    ///< IMU frame
  Eigen::Vector3d angular_accel_imu_radps2 = Eigen::Vector3d::Zero();  ///< IMU frame (if logged)
  // (each IMU vector only if its Columns flag is set; zero otherwise)
  Eigen::Vector3d force_sensor_N = Eigen::Vector3d::Zero();    ///< sensor frame
  Eigen::Vector3d torque_sensor_Nm = Eigen::Vector3d::Zero();  ///< sensor frame, about S
  double temperature_C = 25.0;                                 ///< sensor temperature (if present)
};

struct Log {
  Rig rig;
  Columns columns;
  std::vector<Sample> samples;
};

/// An error in an input file, naming where: file, line and column (1-based; 0 = unknown).
/// what() reads `FILE:LINE:COLUMN: why` (`FILE:LINE: why` or `FILE: why` when unknown).
/// The column counts characters (UTF-8 code points) and points at the start of the cell.
class InputError : public std::runtime_error {
 public:
  InputError(std::filesystem::path file, int line, int column, const std::string& why);
  const std::filesystem::path& file() const { return file_; }
  int line() const { return line_; }
  int column() const { return column_; }

 private:
  std::filesystem::path file_;
  int line_;
  int column_;
};

/// The sidecar path of a log: `run.csv` → `run.rig.toml`.
std::filesystem::path rig_path_for(const std::filesystem::path& csv);

/// A tool's default output beside its input (proto/paths.md): `dir/run.csv` with `.discovered.toml`
/// → `dir/run.discovered.toml`; with `.report` → `dir/run.report`. Never the current folder unless
/// the input is there.
std::filesystem::path beside_input(const std::filesystem::path& input, const std::string& suffix);

/// Reads a log and its rig sidecar (format version 1 or 2). Throws InputError naming file, line
/// and column. Quaternions are returned normalised. Holds every row: a long log is better read
/// with LogReader, chunk by chunk.
Log read_log(const std::filesystem::path& csv);
Rig read_rig(const std::filesystem::path& toml);

/// Reads a log CSV row by row, a chunk of rows at a time, so that a long log is never held whole
/// (neither its text nor its samples): read_log is this reader run to the end, so both give the
/// same samples and throw the same InputErrors (file, line, column). The version line and the
/// header are read and checked at construction; a row's errors when read() reaches it.
class LogReader {
 public:
  /// Opens `csv` and reads its version and header lines. `buffer_bytes`: the text read from the
  /// file at a time (a line longer than that grows the buffer).
  explicit LogReader(const std::filesystem::path& csv, std::size_t buffer_bytes = 1 << 20);
  ~LogReader();
  LogReader(LogReader&&) noexcept;
  LogReader& operator=(LogReader&&) noexcept;
  LogReader(const LogReader&) = delete;
  LogReader& operator=(const LogReader&) = delete;

  /// The column groups the header names.
  const Columns& columns() const;
  /// The format version of line 1.
  int version() const;
  /// Appends the next rows, at most `max_rows`, to `out` (which is not cleared). Returns how many
  /// it appended: 0 at the end of the file.
  std::size_t read(std::vector<Sample>& out, std::size_t max_rows);
  /// Rows read so far.
  std::size_t rows() const;
  /// The log's rig sidecar (read_rig(rig_path_for(csv))).
  Rig read_rig() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

/// Writes a log and its sidecar atomically (temporary files, then rename); never half-written.
/// Throws std::invalid_argument for a non-finite value or a t_s that does not increase, and
/// std::runtime_error if `csv` or its sidecar is one of `inputs` or cannot be written.
void write_log(const Log& log, const std::filesystem::path& csv,
               const std::vector<std::filesystem::path>& inputs = {});
void write_rig(const Rig& rig, const std::filesystem::path& toml,
               const std::vector<std::filesystem::path>& inputs = {}, unsigned mode = 0644);

/// Streaming writer of the log CSV, for recorders that write rows as they come (zerog-rt):
/// exactly the text write_log produces (version line, header, then one row per sample, same
/// number formatting). The caller owns the file; write the rig with write_rig.
class LogCsvWriter {
 public:
  explicit LogCsvWriter(const Columns& columns) : columns_(columns) {}
  /// Appends the version line and the header line to `out`.
  void append_header(std::string& out) const;
  /// Appends one row to `out`. Throws std::invalid_argument (naming the row and the column) for
  /// a non-finite value or a t_s that does not increase; `out` is unchanged then.
  void append_row(const Sample& sample, std::string& out);
  /// Rows appended so far.
  std::size_t rows() const { return rows_; }

 private:
  Columns columns_;
  std::size_t rows_ = 0;
  double previous_t_ = 0.0;
};

/// Writes `text` to `path` atomically (temporary file in the same folder, created 0600, set to
/// `mode` before any byte is written, fsync, rename). Refuses (std::runtime_error) if `path` is
/// one of `inputs` (same file after resolving symbolic links, `..` and hard links) — inputs are
/// never overwritten. On failure no temporary file is left behind. zerog-rt writes its files
/// with rt::kRecordFileMode (0640).
void write_file_atomic(const std::filesystem::path& path, const std::string& text,
                       const std::vector<std::filesystem::path>& inputs = {}, unsigned mode = 0644);

}  // namespace zerog::formats
