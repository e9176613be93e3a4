#pragma once
// Comparisons of the log format's values for the round-trip properties of the io fuzz targets.
#include <Eigen/Core>
#include <Eigen/Geometry>

#include "fuzz_util.hpp"
#include "zerog/formats/log.hpp"

namespace zerog::fuzz {

/// `rel` of the larger magnitude apart (plus a tiny absolute slack for values near zero).
inline bool near_vec(const Eigen::Vector3d& a, const Eigen::Vector3d& b, double rel) {
  for (int i = 0; i < 3; ++i)
    if (!near(a[i], b[i], 1e-300, rel)) return false;
  return true;
}

/// The same rotation (q and −q are), to `tol` per component.
inline bool near_rotation(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b, double tol) {
  const double sign = a.dot(b) < 0.0 ? -1.0 : 1.0;
  return (a.coeffs() - sign * b.coeffs()).cwiseAbs().maxCoeff() <= tol;
}

inline bool same_rig(const formats::Rig& a, const formats::Rig& b) {
  constexpr double kExact = 1e-15;  // the rig is written in shortest round-trip form
  return a.name == b.name && a.robot == b.robot &&
         near_vec(a.flange_sensor.p_m, b.flange_sensor.p_m, kExact) &&
         near_rotation(a.flange_sensor.q, b.flange_sensor.q, 1e-15) &&
         near_vec(a.sensor_imu.p_m, b.sensor_imu.p_m, kExact) &&
         near_rotation(a.sensor_imu.q, b.sensor_imu.q, 1e-15) &&
         near(a.sample_period_s, b.sample_period_s, 0.0, kExact) &&
         near(a.ft_rate_hz, b.ft_rate_hz, 0.0, kExact) &&
         near(a.imu_rate_hz, b.imu_rate_hz, 0.0, kExact) &&
         near(a.floor_z_m, b.floor_z_m, 0.0, kExact);
}

}  // namespace zerog::fuzz
