#pragma once
// The zerog log format (proto/log_format.md): a versioned CSV of synchronized samples plus a
// TOML rig description beside it. SI units throughout; every vector names its frame.
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace zerog::io {

inline constexpr int kLogFormatVersion = 1;

/// A rigid transform: the pose of a child frame in a parent frame.
struct Transform {
  Eigen::Vector3d p_m = Eigen::Vector3d::Zero();          ///< child origin in parent, m
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();  ///< child axes in parent, unit
};

/// The rig description (the `.rig.toml` sidecar).
struct Rig {
  std::string name = "unnamed";
  std::string robot = "KR 210 R2700";
  Transform flange_sensor;         ///< F/T sensor frame S in the flange frame F
  Transform sensor_imu;            ///< IMU frame I in the sensor frame S
  double sample_period_s = 0.012;  ///< log row period (rows need not be exactly uniform)
  double ft_rate_hz = 0.0;         ///< native F/T rate, 0 if unknown
  double imu_rate_hz = 0.0;        ///< native IMU rate, 0 if unknown
  double floor_z_m = 0.0;          ///< floor height in the base frame (for designs), m
};

/// Which optional column groups the log has.
struct Columns {
  bool joints = false;
  bool imu = false;
  bool temperature = false;
  bool operator==(const Columns&) const = default;
};

/// One synchronized sample (one CSV row).
struct Sample {
  double t_s = 0.0;                                           ///< time, s (strictly increasing)
  std::array<double, 6> joints_rad{};                         ///< A1..A6, rad (if Columns::joints)
  Eigen::Vector3d p_base_sensor_m = Eigen::Vector3d::Zero();  ///< sensor origin in base, m
  Eigen::Quaterniond q_base_sensor = Eigen::Quaterniond::Identity();  ///< sensor axes in base
  Eigen::Vector3d specific_force_imu_mps2 = Eigen::Vector3d::Zero();  ///< IMU frame, a − g
  Eigen::Vector3d angular_rate_imu_radps = Eigen::Vector3d::Zero();   ///< IMU frame
  Eigen::Vector3d force_sensor_N = Eigen::Vector3d::Zero();           ///< sensor frame
  Eigen::Vector3d torque_sensor_Nm = Eigen::Vector3d::Zero();         ///< sensor frame, about S
  double temperature_C = 25.0;  ///< sensor temperature (if present)
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

/// Reads a log and its rig sidecar. Throws InputError naming file, line and column.
/// Quaternions are returned normalised.
Log read_log(const std::filesystem::path& csv);
Rig read_rig(const std::filesystem::path& toml);

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

}  // namespace zerog::io
