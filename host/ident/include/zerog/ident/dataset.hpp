#pragma once
// A log turned into the signals the model needs, laid out for fast repeated evaluation.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "zerog/formats/log.hpp"
#include "zerog/ident/spill.hpp"
#include "zerog/model/dictionary.hpp"
#include "zerog/model/predict.hpp"
#include "zerog/model/signals.hpp"

namespace zerog::ident {

using Wrench = Eigen::Matrix<double, 6, 1>;

/// A per-sample column of the Dataset: a std::vector whose storage is spilled to a memory-mapped
/// file once it is large (spill.hpp: a long log's columns do not stay resident; a short one's are
/// ordinary heap memory).
template <typename T>
using Column = std::vector<T, spill::Allocator<T>>;

/// The per-sample columns below are Column<T> (spill.hpp): past spill::settings().min_bytes a
/// column lives in an unlinked, memory-mapped file ($ZEROG_SPILL_DIR, else $TMPDIR unless tmpfs,
/// else /var/tmp), and a pass over the samples walks them with a ResidentWindow, which releases
/// the rows behind it, so that the memory of a fit does not grow with the log. Values never
/// depend on where the columns live.
struct Dataset {
  model::RigGeometry rig;
  formats::Columns columns;
  /// Where the IMU columns came from (logged, or derived at import from joints or pose).
  formats::KinematicsRecord kinematics;
  /// How the IMU rows were formed and their noise, as the rig says (point samples or means;
  /// FitOptions::errors_in_variables).
  formats::ImuSampling imu_sampling;
  /// The rig's row_order: a table's rows in the order recorded (their index is their time).
  bool rows_in_recorded_order = true;
  double dt_s = 0.012;  ///< mean row period (IMU time shifts interpolate on this grid)
  Column<double> t_s;
  /// Sensor attitude in base, the logged quaternion normalised. Stored rather than the matrix
  /// (issue 16: 32 bytes a sample instead of 72); pose(i) forms the matrix with the same call
  /// (toRotationMatrix of the normalised quaternion) that filled it before, so bit for bit.
  Column<Eigen::Quaterniond> q_base_sensor;
  /// Sensor temperature, °C; empty for a log without temp_C (then model::kTemperatureReferenceC).
  Column<double> temperature_C;
  Column<std::array<double, 6>> joints_rad;  ///< robot joint angles A1..A6, rad
  /// n rows of 9: specific force (3), angular rate (3), angular acceleration (3; the log's
  /// imu_dw* columns, or the angular rate differenced), IMU frame.
  /// A group the log lacks is zero (taken as at rest); so is the angular acceleration of a log
  /// without angular rate or without time (columns.static_rows).
  Column<double> imu;
  Column<Wrench> measured;
  Column<std::uint8_t> moving;              ///< 1 while the sensor moves (always 0 for static rows)
  Column<Eigen::Vector3d> p_base_sensor_m;  ///< S origin in B, m (zero without position)

  /// The model's pose signals of sample i, formed from the rows above rather than stored (issue
  /// 16: the matrix and t_rel_s took 80 bytes a sample): the same values make_dataset stored.
  model::PoseSignals pose(std::size_t i) const {
    model::PoseSignals p;
    p.R_base_sensor = q_base_sensor[i].toRotationMatrix();
    // A table's rows count 0, 1, … (proto/log_format.md): its row index is its time order, so
    // that a drift over the rows (bias_drift, per row) can be fitted.
    p.t_rel_s = t_s[i] - t_s.front();
    if (!temperature_C.empty()) p.temperature_C = temperature_C[i];
    p.joints_rad = joints_rad[i];
    return p;
  }
  /// Joint velocities of sample i, rad/s: the backward difference of the joint angles with the
  /// previous row (row 0: that of row 1), zero for static rows or a log without joints. Formed
  /// here from the neighbouring rows rather than stored (issue 16: 48 bytes a sample).
  std::array<double, 6> joint_vel_radps(std::size_t i) const {
    std::array<double, 6> v{};
    if (columns.static_rows || !columns.joints || size() < 2) return v;
    const std::size_t r = i == 0 ? 1 : i;
    const double dt = t_s[r] - t_s[r - 1];
    for (std::size_t j = 0; j < 6; ++j) v[j] = (joints_rad[r][j] - joints_rad[r - 1][j]) / dt;
    return v;
  }
  /// Bytes the per-sample vectors hold (their capacity), the dataset's memory beyond a few
  /// hundred bytes of its own.
  std::size_t bytes() const;
  /// True when the columns are spilled to a file (spill.hpp; the largest, imu, spills first).
  bool spilled() const { return spill::spilled(imu.data()); }
  /// Releases rows [first, last) of every column from the process where they are spilled (the
  /// pages they touch: spill::release); the values stay, a later read faults them back in.
  void release_rows(std::size_t first, std::size_t last) const;

  /// Every signal of the dictionary for sample i (the IMU as logged, no time offset). Its
  /// velocities and accelerations (sensor origin, joints) are 3-point central differences
  /// (model::central_differences; at the first and last row those of their neighbour), so that
  /// they carry no delay, formed here from the neighbouring rows rather than stored (issue 16:
  /// 120 bytes a sample that only user terms and discovery read); none across static rows.
  model::DictionarySignals dictionary(std::size_t i) const;

  std::size_t size() const { return t_s.size(); }
  /// IMU signals of sample i, read at t_i + tau when tau is given (imu_time_offset).
  template <typename T>
  model::ImuSignals<T> imu_at(std::size_t i, const T* tau) const {
    model::ImuSignals<T> s;
    if (!columns.any_imu()) return s;
    if (tau == nullptr) {
      const double* row = &imu[i * 9];
      for (int k = 0; k < 3; ++k) {
        s.specific_force_imu[k] = T(row[k]);
        s.angular_rate_imu[k] = T(row[3 + k]);
        s.angular_accel_imu[k] = T(row[6 + k]);
      }
      return s;
    }
    const T index = T(static_cast<double>(i)) + *tau / T(dt_s);
    const Eigen::Matrix<T, 9, 1> v =
        model::interpolate_uniform<9>(imu.data(), static_cast<std::ptrdiff_t>(size()), index);
    s.specific_force_imu = v.template segment<3>(0);
    s.angular_rate_imu = v.template segment<3>(3);
    s.angular_accel_imu = v.template segment<3>(6);
    return s;
  }
};

/// A pass's walk over the rows of a Dataset, front to back (spill.hpp): advance(i) before reading
/// row i releases the rows more than a window (spill::settings().window_rows) behind the
/// furthest row it was given, a window at a time, so that at most two windows of rows stay
/// resident; the destructor releases the rest of what it passed. Reading behind the window (a
/// neighbouring row, an interpolation, another thread's rows) stays correct: the row faults back
/// in. Does nothing for a dataset on the heap. One per thread.
class ResidentWindow {
 public:
  explicit ResidentWindow(const Dataset& data, std::size_t first = 0)
      : data_(&data),
        window_(spill::settings().window_rows),
        released_(first),
        end_(first),
        active_(data.spilled()) {}
  ~ResidentWindow();
  ResidentWindow(const ResidentWindow&) = delete;
  ResidentWindow& operator=(const ResidentWindow&) = delete;

  void advance(std::size_t i) {
    if (!active_) return;
    if (i >= end_) end_ = i + 1;
    if (end_ - released_ > 2 * window_) release_behind();
  }

 private:
  void release_behind();
  const Dataset* data_;
  std::size_t window_;
  std::size_t released_;  ///< rows before this one are released
  std::size_t end_;       ///< one past the furthest row given
  bool active_;
};

/// Builds the dataset: rotations from quaternions, angular acceleration from the log's
/// imu_dw*_radps2 columns when present (formed at import: the gyro by Savitzky–Golay, or the
/// robot's), else by 5-point central differences of the gyroscope column
/// (model::angular_accel_central), motion flags; joint velocities are formed on demand
/// (Dataset::joint_vel_radps). (DatasetBuilder fed every sample.)
Dataset make_dataset(const formats::Log& log);

/// make_dataset sample by sample, so that a log read in chunks (formats::LogReader) becomes a
/// Dataset without the parsed log ever held whole: it keeps the previous sample, differences across
/// rows as they come and finishes the rest (ω̇ from the gyro, motion dilation) in finish().
/// The Dataset is the one make_dataset builds from the same samples, bit for bit.
class DatasetBuilder {
 public:
  /// `columns`: the log's column groups; `expected_samples`: capacity to reserve (0: none). An
  /// estimate above the count costs address space, not resident memory.
  explicit DatasetBuilder(const formats::Columns& columns, std::size_t expected_samples = 0);
  /// Appends the next sample (times as the log reader checked them: strictly increasing).
  void add(const formats::Sample& sample);
  /// The dataset, with the rig's IMU mount and kinematics record. Throws std::runtime_error for a
  /// log of fewer than 3 samples. Call once.
  Dataset finish(const formats::Rig& rig);

 private:
  Dataset d_;
  std::size_t n_ = 0;
  std::size_t released_ = 0;  ///< rows before this one released (a spilled dataset, spill.hpp)
  formats::Sample previous_;  ///< sample n − 1
  std::vector<std::uint8_t> raw_moving_;
};

/// Reads a log CSV (formats::LogReader, `chunk_rows` rows at a time) straight into a Dataset: the
/// same Dataset as make_dataset(formats::read_log(csv)) and the same InputErrors, without the log's
/// text or its parsed rows held whole. `rig`, if given, receives the log's rig.
Dataset read_dataset(const std::filesystem::path& csv, formats::Rig* rig = nullptr,
                     std::size_t chunk_rows = 4096, std::size_t buffer_bytes = 1 << 20);

/// True when make_dataset forms the angular acceleration from the angular-rate column (the log
/// has time and the rate, and no imu_dw*_radps2 columns).
bool differences_angular_rate(const Dataset& data);
/// Overwrites the angular acceleration of every row (Dataset::imu) with the 5-point central
/// differences of the angular rate (model::angular_accel_central; 3-point one row from the ends,
/// zero on the first and last row), as make_dataset does.
void angular_accel_from_rate(Dataset& data);

/// Predicted wrench of sample i with the given parameters (double evaluation of the model).
Wrench predict(const model::ModelParams& params, const Dataset& data, std::size_t i);

/// Time-blocked split: blocks of `block_s` seconds; block k is held out when k mod `every` ==
/// `offset` (default every − 1). Returns 1 for held-out samples. Static rows (no time) are
/// independent samples: each row is its own block, `block_s` does not apply.
std::vector<std::uint8_t> heldout_mask(const Dataset& data, double block_s = 60.0, int every = 4,
                                       int offset = -1);

/// Throws std::runtime_error if the log lacks a signal an effect needs (names both, and the
/// column or import-mapping key that would make it work).
void check_signals(const model::EffectSet& effects, const Dataset& data);
/// The same for user terms (names the term and the missing columns).
void check_signals(const model::UserEffects& user, const Dataset& data);
/// The dictionary's signal sources the log has (bit mask of 1 << model::SignalSource).
unsigned available_sources(const Dataset& data);

}  // namespace zerog::ident
