#include "zerog/robot/servo.hpp"

#include <cmath>

namespace zerog::robot {

Eigen::Matrix2d servo_transition(double omega_radps, double tau_s) {
  const double w = omega_radps, e = std::exp(-w * tau_s);
  Eigen::Matrix2d phi;
  phi << e * (1.0 + w * tau_s), e * tau_s, -e * w * w * tau_s, e * (1.0 - w * tau_s);
  return phi;
}

void servo_advance(double omega_radps, double tau_s, double rate, const Eigen::Matrix2d& phi,
                   double& s, double& q, double& qd) {
  const double w = omega_radps;
  const Eigen::Vector2d x(q - s + 2.0 * rate / w, qd - rate);
  const Eigen::Vector2d next = phi * x;
  s += rate * tau_s;
  q = s + next[0] - 2.0 * rate / w;
  qd = next[1] + rate;
}

}  // namespace zerog::robot
