#pragma once
// A log turned into the signals the model needs, laid out for fast repeated evaluation.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

#include "zerog/formats/log.hpp"
#include "zerog/model/dictionary.hpp"
#include "zerog/model/predict.hpp"
#include "zerog/model/signals.hpp"

namespace zerog::ident {

using Wrench = Eigen::Matrix<double, 6, 1>;

struct Dataset {
  model::RigGeometry rig;
  io::Columns columns;
  /// Where the IMU columns came from (logged, or derived at import from joints or pose).
  io::KinematicsRecord kinematics;
  double dt_s = 0.012;  ///< mean row period (IMU time shifts interpolate on this grid)
  std::vector<double> t_s;
  std::vector<model::PoseSignals> pose;
  /// n rows of 9: specific force (3), angular rate (3), angular acceleration (3; the log's
  /// imu_dw* columns, or the angular rate differenced), IMU frame.
  /// A group the log lacks is zero (taken as at rest); so is the angular acceleration of a log
  /// without angular rate or without time (columns.static_rows).
  std::vector<double> imu;
  std::vector<Wrench> measured;
  std::vector<std::uint8_t> moving;  ///< 1 while the sensor moves (always 0 for static rows)
  std::vector<std::array<double, 6>> joint_vel_radps;  ///< from differencing the joint angles
  // For the signal dictionary (model/dictionary.hpp): central differences (3-point; one-sided
  // at the ends), so that they carry no delay.
  std::vector<Eigen::Vector3d> p_base_sensor_m;                ///< S origin in B, m
  std::vector<Eigen::Vector3d> v_base_sensor_mps;              ///< velocity of the S origin in B
  std::vector<std::array<double, 6>> joint_vel_central_radps;  ///< A1..A6
  std::vector<std::array<double, 6>> joint_acc_radps2;         ///< A1..A6

  /// Every signal of the dictionary for sample i (the IMU as logged, no time offset).
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

/// Builds the dataset: rotations from quaternions, angular acceleration from the log's
/// imu_dw*_radps2 columns when present (formed at import: the gyro by Savitzky–Golay, or the
/// robot's), else by 5-point central differences of the gyroscope column
/// (model::angular_accel_central), motion flags, joint velocities.
Dataset make_dataset(const io::Log& log);

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
