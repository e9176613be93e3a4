#pragma once
// The force model: predicts the wrench the payload alone exerts on the F/T sensor.
// One implementation, templated on the scalar so Ceres autodiff (host) and the firmware (double)
// evaluate the same code. Formulas: proto/effects.md; paper 000_… eq. 1–5, paper 001_… eq. 5–8.
//
// Real-time safe: no allocation, no exceptions, no I/O, bounded time.
#include <Eigen/Core>
#include <array>
#include <cmath>

#include "zerog/model/effects.hpp"
#include "zerog/model/rotation.hpp"

namespace zerog::model {

template <typename T>
using Vec3 = Eigen::Matrix<T, 3, 1>;
template <typename T>
using Mat3 = Eigen::Matrix<T, 3, 3>;

/// Wrench in the sensor frame: force (N) then torque about the sensor origin (N·m).
template <typename T>
using Wrench = Eigen::Matrix<T, 6, 1>;

/// Rig geometry that the model takes as known (from the rig description, proto/log_format.md).
struct RigGeometry {
  Eigen::Matrix3d R_sensor_imu = Eigen::Matrix3d::Identity();  ///< IMU axes in the sensor frame
  Eigen::Vector3d p_sensor_imu_m = Eigen::Vector3d::Zero();    ///< IMU origin in the sensor frame
};

/// Signals of one sample that do not depend on model parameters.
struct PoseSignals {
  Eigen::Matrix3d R_base_sensor = Eigen::Matrix3d::Identity();  ///< nominal sensor attitude in base
  double t_rel_s = 0.0;                           ///< time since the start of the log, s
  double temperature_C = kTemperatureReferenceC;  ///< sensor temperature, °C
  std::array<double, 6> joints_rad{};             ///< robot joint angles A1..A6, rad
};

/// IMU signals of one sample, in the IMU frame. Templated because the IMU time offset makes
/// them depend on a parameter (they are interpolated at t + tau).
template <typename T>
struct ImuSignals {
  Vec3<T> specific_force_imu = Vec3<T>::Zero();  ///< accelerometer: a − g, m/s²
  Vec3<T> angular_rate_imu = Vec3<T>::Zero();    ///< gyroscope, rad/s
  Vec3<T> angular_accel_imu = Vec3<T>::Zero();   ///< derivative of the gyroscope, rad/s²
};

/// Parameter blocks by effect; entries of effects not in the set may be null.
template <typename T>
using ParamPointers = std::array<const T*, kEffectCount>;

inline ParamPointers<double> pointers(const ModelParams& p) {
  ParamPointers<double> out{};
  for (Effect e : kAllEffects) out[index(e)] = p.block(e);
  return out;
}

/// Gravity vector in the sensor frame (m/s²) given the nominal sensor attitude, the base tilt
/// (paper 001_… eq. 5: B is W rotated about x_W by alpha, then about y by beta) and the sensor
/// mounting rotation. Real-time safe.
template <typename T>
Vec3<T> gravity_sensor(const EffectSet& effects, const ParamPointers<T>& p,
                       const Eigen::Matrix3d& R_base_sensor, const Mat3<T>& R_nominal_true) {
  Vec3<T> g_world(T(0), T(0), T(-kStandardGravity));
  Vec3<T> g_base = g_world;
  if (effects.has(Effect::base_tilt)) {
    const T* tilt = p[index(Effect::base_tilt)];
    Mat3<T> R_world_base = rot_x(tilt[0]) * rot_y(tilt[1]);
    g_base = R_world_base.transpose() * g_world;
  }
  Vec3<T> g_nominal = R_base_sensor.transpose().cast<T>() * g_base;
  return R_nominal_true.transpose() * g_nominal;
}

/// Where the IMU sits in the true sensor frame: the nominal mounting (rig) turned by the sensor
/// rotation, if the model has one (the true sensor frame is the nominal one rotated by Exp(r);
/// the IMU is fixed to the flange side, so a sensor rotation also turns the IMU relative to S).
template <typename T>
struct ImuMount {
  Mat3<T> R_nominal_true = Mat3<T>::Identity();
  Mat3<T> R_sensor_imu = Mat3<T>::Identity();  ///< IMU axes in the true sensor frame
  Vec3<T> p_sensor_imu = Vec3<T>::Zero();      ///< IMU origin in the true sensor frame, m
};

// Always inlined: payload_wrench runs every cycle, and a call returning the mount through memory
// cost more than the mount itself (loop_bench).
template <typename T>
EIGEN_ALWAYS_INLINE ImuMount<T> imu_mount(const EffectSet& effects, const ParamPointers<T>& p,
                                          const RigGeometry& rig) {
  ImuMount<T> m;
  if (effects.has(Effect::sensor_rotation)) {
    m.R_nominal_true = rotation_from_vector(Vec3<T>(p[index(Effect::sensor_rotation)]));
  }
  m.R_sensor_imu = m.R_nominal_true.transpose() * rig.R_sensor_imu.cast<T>();
  m.p_sensor_imu = m.R_nominal_true.transpose() * rig.p_sensor_imu_m.cast<T>();
  return m;
}

/// The symmetric inertia tensor from rotational_inertia's parameters (Ixx, Iyy, Izz, Ixy, Ixz,
/// Iyz), about the centre of mass, sensor axes, kg·m².
template <typename T>
Mat3<T> inertia_tensor(const T* I) {
  Mat3<T> inertia;
  inertia << I[0], I[3], I[4], I[3], I[1], I[5], I[4], I[5], I[2];
  return inertia;
}

/// The part of stage 1 that payload_wrench and payload_wrench_mean share: the payload's force on
/// the sensor and its moment about the sensor origin, c × F (gravity's parameters: mass m, centre
/// of mass c in sensor axes). Without linear_inertia F is the weight; with it F = m (g − a_c) =
/// −m × (specific force at the centre of mass), which `specific_force_com(r)` gives from the lever
/// r = c − p_sensor_imu. The rotational terms are the caller's. Real-time safe.
template <typename T, typename SpecificForceAtCom>
Wrench<T> weight_and_linear_inertia(const EffectSet& effects, const ParamPointers<T>& p,
                                    const ImuMount<T>& mount, const Eigen::Matrix3d& R_base_sensor,
                                    SpecificForceAtCom&& specific_force_com) {
  const T* grav = p[index(Effect::gravity)];
  const T mass = grav[0];
  const Vec3<T> com(grav[1], grav[2], grav[3]);
  Vec3<T> force;
  if (effects.has(Effect::linear_inertia)) {
    const Vec3<T> f_com = specific_force_com(Vec3<T>(com - mount.p_sensor_imu));
    force = -mass * f_com;
  } else {
    force = mass * gravity_sensor(effects, p, R_base_sensor, mount.R_nominal_true);
  }
  Wrench<T> w;
  w.template head<3>() = force;
  w.template tail<3>() = com.cross(force);
  return w;
}

/// Stage 1 of the model: the wrench the payload's gravity and inertia exert on the sensor
/// (sensor frame, torque about the sensor origin). Nonlinear in its parameters (gravity,
/// base_tilt, rotational_inertia, sensor_rotation; imu_time_offset through `imu`).
/// Real-time safe.
template <typename T>
Wrench<T> payload_wrench(const EffectSet& effects, const ParamPointers<T>& p,
                         const PoseSignals& pose, const ImuSignals<T>& imu,
                         const RigGeometry& rig) {
  Wrench<T> w = Wrench<T>::Zero();
  if (!effects.has(Effect::gravity)) return w;
  const ImuMount<T> mount = imu_mount(effects, p, rig);
  const Mat3<T>& R_sensor_imu = mount.R_sensor_imu;
  const Vec3<T> omega = R_sensor_imu * imu.angular_rate_imu;
  const Vec3<T> omega_dot = R_sensor_imu * imu.angular_accel_imu;
  w = weight_and_linear_inertia(effects, p, mount, pose.R_base_sensor, [&](const Vec3<T>& r) {
    // The accelerometer measures specific force at the IMU; rigid-body transfer to the centre of
    // mass (lever r).
    return Vec3<T>(R_sensor_imu * imu.specific_force_imu + omega_dot.cross(r) +
                   omega.cross(omega.cross(r)));
  });
  if (effects.has(Effect::rotational_inertia)) {
    const Mat3<T> inertia = inertia_tensor(p[index(Effect::rotational_inertia)]);
    // Newton–Euler (000_… eq. 5): the payload needs I ω̇ + ω × I ω from the sensor.
    w.template tail<3>() -= inertia * omega_dot + omega.cross(inertia * omega);
  }
  return w;
}

/// Block means of the signals stage 1 depends on: the sufficient statistics of payload_wrench
/// over a block of samples that share the parameters. Templated like ImuSignals (with an IMU
/// time offset the means are interpolated, so they depend on it).
template <typename T>
struct PayloadMeans {
  /// Mean nominal sensor attitude (a mean of rotations, not itself a rotation).
  Eigen::Matrix3d R_base_sensor = Eigen::Matrix3d::Identity();
  Vec3<T> specific_force_imu = Vec3<T>::Zero();  ///< mean specific force, IMU frame, m/s²
  Vec3<T> angular_accel_imu = Vec3<T>::Zero();   ///< mean angular acceleration, IMU frame, rad/s²
  Mat3<T> rate_outer_imu = Mat3<T>::Zero();  ///< mean ω ωᵀ of the gyroscope, IMU frame, rad²/s²
};

/// The mean of payload_wrench over a block of samples, from the block means of its signals
/// (PayloadMeans): exact, because with the parameters fixed stage 1 is affine in R_base_sensor,
/// specific force and ω̇, and quadratic in ω only through ω ωᵀ. In payload_wrench's notation,
/// with R = R_sensor_imu (rotated by the sensor rotation) and M = R mean(ω_I ω_Iᵀ) Rᵀ:
///   mean(ω × (ω × r)) = (M − tr(M) 1) r,
///   mean(ω × (I ω))_a = ε_abc (I M)_cb,
/// the other terms are those of payload_wrench on the means (c × F with c constant; gravity_sensor
/// is linear in R_base_sensor). tests/unit/model/predict_test.cpp checks it against the mean of
/// payload_wrench.
///
/// This overload takes the mount already computed (imu_mount of the same `p`), so that a caller
/// evaluating many blocks at one parameter point computes it once; and the means in their own
/// scalar S, so that means which do not depend on the differentiated parameters can stay plain
/// doubles (S = double with T a Jet: each product then costs a Jet times a number). Real-time
/// safe.
template <typename T, typename S>
Wrench<T> payload_wrench_mean(const EffectSet& effects, const ParamPointers<T>& p,
                              const ImuMount<T>& mount, const PayloadMeans<S>& means) {
  Wrench<T> w = Wrench<T>::Zero();
  if (!effects.has(Effect::gravity)) return w;
  const Mat3<T>& R_sensor_imu = mount.R_sensor_imu;
  const Vec3<T> omega_dot = R_sensor_imu * means.angular_accel_imu;
  const Mat3<T> rate_outer = R_sensor_imu * means.rate_outer_imu * R_sensor_imu.transpose();
  w = weight_and_linear_inertia(effects, p, mount, means.R_base_sensor, [&](const Vec3<T>& r) {
    return Vec3<T>(R_sensor_imu * means.specific_force_imu + omega_dot.cross(r) +
                   (rate_outer - rate_outer.trace() * Mat3<T>::Identity()) * r);
  });
  if (effects.has(Effect::rotational_inertia)) {
    const Mat3<T> inertia = inertia_tensor(p[index(Effect::rotational_inertia)]);
    const Mat3<T> N = inertia * rate_outer;
    const Vec3<T> gyroscopic(N(2, 1) - N(1, 2), N(0, 2) - N(2, 0), N(1, 0) - N(0, 1));
    w.template tail<3>() -= inertia * omega_dot + gyroscopic;
  }
  return w;
}

/// payload_wrench_mean with the mount of the rig and `p` (imu_mount). Real-time safe.
template <typename T>
Wrench<T> payload_wrench_mean(const EffectSet& effects, const ParamPointers<T>& p,
                              const PayloadMeans<T>& means, const RigGeometry& rig) {
  if (!effects.has(Effect::gravity)) return Wrench<T>::Zero();
  return payload_wrench_mean<T, T>(effects, p, imu_mount(effects, p, rig), means);
}

/// Per-sample inputs of stage 2. Stage 2 is affine in them for fixed parameters, so the mean of
/// stage 2 over samples equals stage 2 of their mean (the host fit uses that).
struct SensorInputs {
  double t_rel_s = 0.0;                           ///< time since the start of the log, s
  double temperature_C = kTemperatureReferenceC;  ///< sensor temperature, °C
  std::array<double, 6> cable_features{};         ///< cos, sin of A4, A5, A6 (kCableJoints)
};

inline SensorInputs sensor_inputs(const PoseSignals& pose) {
  SensorInputs in;
  in.t_rel_s = pose.t_rel_s;
  in.temperature_C = pose.temperature_C;
  for (int j = 0; j < 3; ++j) {
    in.cable_features[2 * j] = std::cos(pose.joints_rad[kCableJoints[j]]);
    in.cable_features[2 * j + 1] = std::sin(pose.joints_rad[kCableJoints[j]]);
  }
  return in;
}

/// Stage 2 of the model: what the sensor reports for a payload wrench: plus the cable's wrench
/// (a load too), through the crosstalk, plus the zero terms (bias, drift, temperature).
/// Real-time safe.
template <typename T>
Wrench<T> sensor_output(const EffectSet& effects, const ParamPointers<T>& p, const SensorInputs& in,
                        const Wrench<T>& payload) {
  Wrench<T> w = payload;
  if (effects.has(Effect::cable)) {
    const T* c = p[index(Effect::cable)];
    for (int j = 0; j < 3; ++j) {
      const double cq = in.cable_features[2 * j], sq = in.cable_features[2 * j + 1];
      for (int k = 0; k < 6; ++k) w[k] += c[j * 12 + k] * cq + c[j * 12 + 6 + k] * sq;
    }
  }
  if (effects.has(Effect::crosstalk)) {
    const T* e = p[index(Effect::crosstalk)];
    Eigen::Map<const Eigen::Matrix<T, 6, 6, Eigen::RowMajor>> E(e);
    w += E * w;  // Eigen evaluates the product into a temporary (no aliasing)
  }
  if (effects.has(Effect::bias)) {
    w += Eigen::Map<const Wrench<T>>(p[index(Effect::bias)]);
  }
  if (effects.has(Effect::bias_drift)) {
    w += Eigen::Map<const Wrench<T>>(p[index(Effect::bias_drift)]) * T(in.t_rel_s);
  }
  if (effects.has(Effect::temperature_bias)) {
    w += Eigen::Map<const Wrench<T>>(p[index(Effect::temperature_bias)]) *
         T(in.temperature_C - kTemperatureReferenceC);
  }
  return w;
}

/// The derivatives of sensor_output (the same formula, differentiated by hand: it is affine in
/// each parameter): with A = 1 + E (E the crosstalk, 1 without it) and u the payload plus the
/// cable wrench, out = A u + bias + drift t + temperature ΔT, so d out / d payload = A,
/// d out / d cable (cos, sin of joint j, axis k) = A e_k (cos, sin), d out / d E_rc = e_r u_c,
/// and 1, t, ΔT for the zero terms. Writes d out / d payload to columns 0..5 of `jacobian` and
/// the parameters of each stage-2 effect e of `effects` from column `column[index(e)]`; other
/// columns are zero. tests/unit/model/predict_test.cpp checks it against autodiff.
/// Real-time safe.
template <int Cols>
void sensor_output_jacobian(const EffectSet& effects, const ParamPointers<double>& p,
                            const SensorInputs& in, const Wrench<double>& payload,
                            const std::array<int, kEffectCount>& column,
                            Eigen::Matrix<double, 6, Cols>& jacobian) {
  jacobian.setZero();
  Eigen::Matrix<double, 6, 6> A = Eigen::Matrix<double, 6, 6>::Identity();
  if (effects.has(Effect::crosstalk)) {
    A +=
        Eigen::Map<const Eigen::Matrix<double, 6, 6, Eigen::RowMajor>>(p[index(Effect::crosstalk)]);
  }
  jacobian.template leftCols<6>() = A;
  Wrench<double> u = payload;
  if (effects.has(Effect::cable)) {
    const double* c = p[index(Effect::cable)];
    const int col = column[index(Effect::cable)];
    for (int j = 0; j < 3; ++j) {
      const double cq = in.cable_features[2 * j], sq = in.cable_features[2 * j + 1];
      for (int k = 0; k < 6; ++k) {
        u[k] += c[j * 12 + k] * cq + c[j * 12 + 6 + k] * sq;
        jacobian.col(col + j * 12 + k) = A.col(k) * cq;
        jacobian.col(col + j * 12 + 6 + k) = A.col(k) * sq;
      }
    }
  }
  if (effects.has(Effect::crosstalk)) {
    const int col = column[index(Effect::crosstalk)];
    for (int r = 0; r < 6; ++r)
      for (int c = 0; c < 6; ++c) jacobian(r, col + r * 6 + c) = u[c];
  }
  const double zero_terms[3] = {1.0, in.t_rel_s, in.temperature_C - kTemperatureReferenceC};
  const Effect zero_effects[3] = {Effect::bias, Effect::bias_drift, Effect::temperature_bias};
  for (int z = 0; z < 3; ++z) {
    if (!effects.has(zero_effects[z])) continue;
    const int col = column[index(zero_effects[z])];
    for (int k = 0; k < 6; ++k) jacobian(k, col + k) = zero_terms[z];
  }
}

/// Effects whose parameters enter stage 1 (payload_wrench); the others enter stage 2.
inline constexpr bool is_payload_effect(Effect e) {
  return e == Effect::gravity || e == Effect::base_tilt || e == Effect::linear_inertia ||
         e == Effect::rotational_inertia || e == Effect::imu_time_offset ||
         e == Effect::sensor_rotation;
}

/// Predicted wrench the payload exerts on the sensor (sensor frame, torque about the sensor
/// origin), before contact: stage 1 then stage 2. Effects not in `effects` contribute nothing.
/// Real-time safe.
template <typename T>
Wrench<T> predict_wrench(const EffectSet& effects, const ParamPointers<T>& p,
                         const PoseSignals& pose, const ImuSignals<T>& imu,
                         const RigGeometry& rig) {
  return sensor_output<T>(effects, p, sensor_inputs(pose),
                          payload_wrench<T>(effects, p, pose, imu, rig));
}

}  // namespace zerog::model
