#include "zerog/robot/ptp_trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace zerog::robot {

PtpLimits kr210_ptp_limits(double speed_fraction) {
  if (!(speed_fraction > 0.0 && speed_fraction <= 1.0))
    throw std::invalid_argument("speed fraction must be in (0, 1]");
  PtpLimits lim;
  constexpr JointVector6 kAccelAt30 = {1.2, 1.2, 1.2, 2.5, 2.5, 3.5};
  for (int j = 0; j < 6; ++j) {
    lim.max_speed_radps[j] = speed_fraction * kKr210MaxSpeedDegps[j] * std::numbers::pi / 180.0;
    lim.max_accel_radps2[j] = kAccelAt30[j] * speed_fraction / 0.3;
  }
  return lim;
}

void MoveProfile::evaluate(double t_s, double& s, double& sd, double& sdd) const {
  const double T = duration_s, Ta = accel_time_s;
  if (T <= 0.0) {
    s = t_s <= 0.0 ? 0.0 : 1.0;
    sd = sdd = 0.0;
    return;
  }
  const double t = std::clamp(t_s, 0.0, T);
  const double V = 1.0 / (T - Ta);  // cruise speed of the normalized profile
  const double A = 2.0 * V / Ta;    // peak acceleration
  const double w = 2.0 * std::numbers::pi / Ta;
  // Acceleration phase, closed form of the integrals of a(t) = A (1 − cos(w t)) / 2.
  auto ramp = [&](double u, double& ps, double& pv, double& pa) {
    pa = 0.5 * A * (1.0 - std::cos(w * u));
    pv = 0.5 * A * (u - std::sin(w * u) / w);
    ps = 0.5 * A * (0.5 * u * u + (std::cos(w * u) - 1.0) / (w * w));
  };
  if (t < Ta) {
    ramp(t, s, sd, sdd);
  } else if (t <= T - Ta) {
    s = 0.5 * V * Ta + V * (t - Ta);
    sd = V;
    sdd = 0.0;
  } else {
    ramp(T - t, s, sd, sdd);
    s = 1.0 - s;
    sdd = -sdd;
  }
}

MoveProfile plan_move(const JointVector6& delta_rad, const PtpLimits& limits) {
  // Cruise time at full speed of the slowest joint; then the acceleration time each joint needs:
  // with T − Ta = Tc, the peak acceleration of joint j is 2 |Δ_j| / (Tc Ta).
  double cruise = 0.0;
  for (int j = 0; j < 6; ++j)
    cruise = std::max(cruise, std::abs(delta_rad[j]) / limits.max_speed_radps[j]);
  MoveProfile p;
  if (cruise <= 0.0) return p;  // no move
  double ta = 0.0;
  for (int j = 0; j < 6; ++j)
    ta = std::max(ta, 2.0 * std::abs(delta_rad[j]) / (cruise * limits.max_accel_radps2[j]));
  ta = std::max(ta, limits.min_accel_time_s);
  if (ta <= cruise) {
    p.accel_time_s = ta;
    p.duration_s = cruise + ta;
  } else {
    // Short move: acceleration-limited, no cruise (T = 2 Ta, peak acceleration 2 |Δ| / Ta²).
    double ta2 = limits.min_accel_time_s;
    for (int j = 0; j < 6; ++j)
      ta2 = std::max(ta2, std::sqrt(2.0 * std::abs(delta_rad[j]) / limits.max_accel_radps2[j]));
    p.accel_time_s = ta2;
    p.duration_s = 2.0 * ta2;
  }
  return p;
}

PtpTrajectory::PtpTrajectory(std::vector<JointVector6> points_rad, const PtpLimits& limits,
                             double dwell_s)
    : points_(std::move(points_rad)), dwell_s_(dwell_s) {
  if (points_.empty()) throw std::invalid_argument("trajectory needs at least one path point");
  if (dwell_s < 0.0) throw std::invalid_argument("dwell must not be negative");
  double t = dwell_s_;
  for (std::size_t k = 0; k + 1 < points_.size(); ++k) {
    JointVector6 delta{};
    for (int j = 0; j < 6; ++j) delta[j] = points_[k + 1][j] - points_[k][j];
    moves_.push_back(plan_move(delta, limits));
    segment_start_s_.push_back(t);
    t += moves_.back().duration_s + dwell_s_;
  }
  total_s_ = t;
  if (segment_start_s_.empty()) segment_start_s_.push_back(t);  // single point: only a dwell
}

JointState PtpTrajectory::at(double t_s) const {
  JointState st;
  const double t = std::clamp(t_s, 0.0, total_s_);
  // Last move that starts at or before t.
  auto it = std::upper_bound(segment_start_s_.begin(), segment_start_s_.end(), t);
  if (it == segment_start_s_.begin() || moves_.empty()) {
    st.q_rad = points_.front();
    return st;
  }
  const std::size_t k = static_cast<std::size_t>(it - segment_start_s_.begin()) - 1;
  const MoveProfile& mv = moves_[k];
  const double u = t - segment_start_s_[k];
  double s = 1.0, sd = 0.0, sdd = 0.0;
  if (u < mv.duration_s) mv.evaluate(u, s, sd, sdd);
  for (int j = 0; j < 6; ++j) {
    const double delta = points_[k + 1][j] - points_[k][j];
    st.q_rad[j] = points_[k][j] + delta * s;
    st.qd_radps[j] = delta * sd;
    st.qdd_radps2[j] = delta * sdd;
  }
  return st;
}

bool PtpTrajectory::is_dwell(double t_s) const {
  const JointState st = at(t_s);
  for (int j = 0; j < 6; ++j)
    if (st.qd_radps[j] != 0.0 || st.qdd_radps2[j] != 0.0) return false;
  return true;
}

}  // namespace zerog::robot
