#pragma once
// Rotation helpers templated on the scalar (work with ceres::Jet). Real-time safe.
#include <Eigen/Core>
#include <algorithm>
#include <cmath>

namespace zerog::model {

/// Rotation about x by angle a (rad): maps vectors of the rotated frame into the original one.
template <typename T>
Eigen::Matrix<T, 3, 3> rot_x(const T& a) {
  using std::cos, std::sin;
  Eigen::Matrix<T, 3, 3> R;
  R << T(1), T(0), T(0), T(0), cos(a), -sin(a), T(0), sin(a), cos(a);
  return R;
}

template <typename T>
Eigen::Matrix<T, 3, 3> rot_y(const T& a) {
  using std::cos, std::sin;
  Eigen::Matrix<T, 3, 3> R;
  R << cos(a), T(0), sin(a), T(0), T(1), T(0), -sin(a), T(0), cos(a);
  return R;
}

template <typename T>
Eigen::Matrix<T, 3, 3> rot_z(const T& a) {
  using std::cos, std::sin;
  Eigen::Matrix<T, 3, 3> R;
  R << cos(a), -sin(a), T(0), sin(a), cos(a), T(0), T(0), T(0), T(1);
  return R;
}

template <typename T>
Eigen::Matrix<T, 3, 3> skew(const Eigen::Matrix<T, 3, 1>& v) {
  Eigen::Matrix<T, 3, 3> S;
  S << T(0), -v.z(), v.y(), v.z(), T(0), -v.x(), -v.y(), v.x(), T(0);
  return S;
}

/// Rodrigues' formula: rotation matrix of the rotation vector r (axis × angle, rad).
/// Near zero it uses the series expansion so derivatives stay exact at r = 0.
template <typename T>
Eigen::Matrix<T, 3, 3> rotation_from_vector(const Eigen::Matrix<T, 3, 1>& r) {
  using std::cos, std::sin, std::sqrt;
  const T theta2 = r.squaredNorm();
  const Eigen::Matrix<T, 3, 3> K = skew(r);
  if (theta2 < T(1e-12)) {
    return Eigen::Matrix<T, 3, 3>::Identity() + K + T(0.5) * K * K;
  }
  const T theta = sqrt(theta2);
  const T a = sin(theta) / theta;
  const T b = (T(1) - cos(theta)) / theta2;
  return Eigen::Matrix<T, 3, 3>::Identity() + a * K + b * K * K;
}

/// KUKA A, B, C angles (rad): rotation about Z by A, then Y' by B, then X'' by C.
template <typename T>
Eigen::Matrix<T, 3, 3> rotation_from_kuka_abc(const T& a, const T& b, const T& c) {
  return rot_z(a) * rot_y(b) * rot_x(c);
}

/// The inverse of rotation_from_kuka_abc (double only): A, B, C in rad with B in [−π/2, π/2]
/// and A, C in (−π, π]. At B = ±π/2 (gimbal lock) only A ∓ C is determined: C is set to 0.
inline Eigen::Vector3d kuka_abc_from_rotation(const Eigen::Matrix3d& R) {
  const double sb = std::clamp(-R(2, 0), -1.0, 1.0);
  const double b = std::asin(sb);
  if (std::abs(sb) > 1.0 - 1e-12) {
    // R = Rz(A) Ry(±π/2) Rx(C) depends on A ∓ C only: R(0,1) = sin(C)sb cos(A) − cos(C) sin(A)
    // = −sin(A ∓ C), R(1,1) = cos(A ∓ C).
    return {std::atan2(-R(0, 1), R(1, 1)), b, 0.0};
  }
  return {std::atan2(R(1, 0), R(0, 0)), b, std::atan2(R(2, 1), R(2, 2))};
}

}  // namespace zerog::model
