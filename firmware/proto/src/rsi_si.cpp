#include "zerog/proto/rsi_si.hpp"

#include <Eigen/Core>

#include "zerog/model/rotation.hpp"

namespace zerog::proto::rsi {
namespace {

using RowMajor3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

samples::Rotation to_array(const Eigen::Matrix3d& R) {
  samples::Rotation out{};
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out[static_cast<std::size_t>(3 * r + c)] = R(r, c);
  }
  return out;
}

Eigen::Matrix3d to_matrix(const samples::Rotation& R) {
  return Eigen::Matrix3d(Eigen::Map<const RowMajor3>(R.data()));
}

// A, B, C (degrees) of R.
std::array<double, 3> abc_deg(const samples::Rotation& R) {
  const Eigen::Vector3d abc = model::kuka_abc_from_rotation(to_matrix(R));
  return {abc[0] / kRadPerDeg, abc[1] / kRadPerDeg, abc[2] / kRadPerDeg};
}

samples::Rotation rotation_from_abc_deg(double a_deg, double b_deg, double c_deg) {
  return to_array(
      model::rotation_from_kuka_abc(a_deg * kRadPerDeg, b_deg * kRadPerDeg, c_deg * kRadPerDeg));
}

}  // namespace

samples::RobotSample robot_sample_from_message(const RobotMessage& m) {
  // Every field named once (no default-initialised sample overwritten afterwards): this runs for
  // every message at the border.
  const bool pose = m.has_actual_pose;
  const CartesianPose& p = m.actual_pose;
  return {.ipoc = m.ipoc,
          .has_delay = m.has_delay,
          .delay = m.delay,
          .joints_rad = joints_to_rad(m.joints_deg),
          .has_pose = pose,
          .p_base_tcp_m = pose ? std::array<double, 3>{p.x_mm * 1e-3, p.y_mm * 1e-3, p.z_mm * 1e-3}
                               : std::array<double, 3>{},
          .R_base_tcp =
              pose ? rotation_from_abc_deg(p.a_deg, p.b_deg, p.c_deg) : samples::kIdentityRotation};
}

RobotMessage robot_message_from_sample(const samples::RobotSample& s) {
  RobotMessage m;
  m.ipoc = s.ipoc;
  m.has_delay = s.has_delay;
  m.delay = s.delay;
  for (std::size_t i = 0; i < m.joints_deg.size(); ++i)
    m.joints_deg[i] = s.joints_rad[i] / kRadPerDeg;
  m.has_actual_pose = s.has_pose;
  if (s.has_pose) {
    const std::array<double, 3> abc = abc_deg(s.R_base_tcp);
    m.actual_pose = {s.p_base_tcp_m[0] * 1e3,
                     s.p_base_tcp_m[1] * 1e3,
                     s.p_base_tcp_m[2] * 1e3,
                     abc[0],
                     abc[1],
                     abc[2]};
  }
  return m;
}

std::array<double, 3> rkorr_abc_rad(const samples::RobotCorrection& c) {
  if (c.kind != samples::RobotCorrection::Kind::cartesian) return {};
  const Eigen::Vector3d abc = model::kuka_abc_from_rotation(to_matrix(c.R_correction));
  return {abc[0], abc[1], abc[2]};
}

void kuka_units_from_correction(const samples::RobotCorrection& c, Correction& rkorr,
                                std::array<double, 6>& akorr_deg) {
  // Each output written once: this runs for every reply.
  using Kind = samples::RobotCorrection::Kind;
  switch (c.kind) {
    case Kind::none:  // zeros as such: A, B, C of the identity would give B = −0
      break;
    case Kind::cartesian: {
      const std::array<double, 3> abc = abc_deg(c.R_correction);
      rkorr = {c.translation_m[0] * 1e3,
               c.translation_m[1] * 1e3,
               c.translation_m[2] * 1e3,
               abc[0],
               abc[1],
               abc[2]};
      akorr_deg = {};
      return;
    }
    case Kind::axes:
      rkorr = {};
      for (std::size_t i = 0; i < akorr_deg.size(); ++i) akorr_deg[i] = c.axes_rad[i] / kRadPerDeg;
      return;
  }
  rkorr = {};
  akorr_deg = {};
}

Reply reply_from_correction(const samples::RobotCorrection& c) {
  using Kind = samples::RobotCorrection::Kind;
  Reply r;
  r.has_rkorr = c.kind == Kind::none || c.kind == Kind::cartesian;
  r.has_akorr = c.kind == Kind::axes;
  r.ipoc = c.ipoc;
  kuka_units_from_correction(c, r.rkorr, r.akorr_deg);
  return r;
}

samples::RobotCorrection correction_from_reply(const Reply& r) {
  samples::RobotCorrection c;
  c.ipoc = r.ipoc;
  c.kind = r.has_akorr   ? samples::RobotCorrection::Kind::axes
           : r.has_rkorr ? samples::RobotCorrection::Kind::cartesian
                         : samples::RobotCorrection::Kind::none;
  if (r.has_rkorr) {
    c.translation_m = {r.rkorr.x_mm * 1e-3, r.rkorr.y_mm * 1e-3, r.rkorr.z_mm * 1e-3};
    c.R_correction = rotation_from_abc_deg(r.rkorr.a_deg, r.rkorr.b_deg, r.rkorr.c_deg);
  }
  if (r.has_akorr) c.axes_rad = joints_to_rad(r.akorr_deg);
  return c;
}

}  // namespace zerog::proto::rsi
