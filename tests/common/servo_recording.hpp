#pragma once
// A zerog-rt recording made by a robot written out here (tests of `zerog servo`,
// host/ident/include/zerog/ident/servo_fit.hpp): AKorr increments that start and stop the joints,
// and the joints of a critically damped servo (the emulator's formula, robot::servo_advance,
// stepped per cycle) that executes each from a given tick, as AIPos carries them. Not
// loop::ServoModel, which the fit runs: a model at the wrong tick or bandwidth would not find
// these.
#include <array>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "zerog/loop/cycle_record.hpp"
#include "zerog/robot/servo.hpp"

namespace zerog::test {

inline constexpr double kServoCycle = 0.012;
inline constexpr double kServoDeg = std::numbers::pi / 180.0;

// AKorr increments (rad) per row: pushes that start and stop the joints, `starts` of them spread
// over the recording (none: nothing commanded).
inline std::vector<std::array<double, 6>> servo_pushes(std::size_t rows, int starts,
                                                       unsigned seed) {
  std::vector<std::array<double, 6>> dq(rows, std::array<double, 6>{});
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> rate(-0.3, 0.3);  // rad/s
  for (int p = 0; p < starts; ++p) {
    const std::size_t a = (2 * static_cast<std::size_t>(p) + 1) * rows / (2 * starts + 1);
    const std::size_t b = a + rows / (2 * static_cast<std::size_t>(starts) + 1);
    std::array<double, 6> r{};
    for (double& v : r) v = rate(rng);
    for (std::size_t k = a; k < b && k < rows; ++k) {
      // A half-sine speed profile: starts and stops smoothly, as a push on the part.
      const double s =
          std::sin(std::numbers::pi * static_cast<double>(k - a) / static_cast<double>(b - a));
      for (std::size_t j = 0; j < 6; ++j) dq[k][j] = r[j] * s * kServoCycle;
    }
  }
  return dq;
}

// The robot: the increment answered at row k ramps the set point over the cycle that ends at row
// k + lag; a critically damped servo of `hz` follows it; AIPos carries 4 decimals of a degree.
inline std::vector<loop::CycleRecord> servo_recording(const std::vector<std::array<double, 6>>& dq,
                                                      double hz, int lag) {
  const double w = 2.0 * std::numbers::pi * hz;
  const Eigen::Matrix2d phi = robot::servo_transition(w, kServoCycle);
  std::array<double, 6> s{}, q{}, qd{};
  for (std::size_t j = 0; j < 6; ++j) s[j] = q[j] = 0.1 * static_cast<double>(j + 1);
  std::vector<loop::CycleRecord> out(dq.size());
  for (std::size_t m = 0; m < dq.size(); ++m) {
    if (m >= static_cast<std::size_t>(lag)) {
      const auto& d = dq[m - static_cast<std::size_t>(lag)];
      for (std::size_t j = 0; j < 6; ++j)
        robot::servo_advance(w, kServoCycle, d[j] / kServoCycle, phi, s[j], q[j], qd[j]);
    }
    loop::CycleRecord& r = out[m];
    r.cycle = m + 1;
    r.ipoc = 1000 + 12 * m;
    r.t_s = static_cast<double>(m) * kServoCycle;
    r.state = loop::State::zero_g;
    for (std::size_t j = 0; j < 6; ++j)
      r.joints_rad[j] = std::round(q[j] / kServoDeg * 1e4) / 1e4 * kServoDeg;
    bool any = false;
    for (std::size_t j = 0; j < 6; ++j) {
      r.reply.axes_rad[j] = dq[m][j];
      any = any || dq[m][j] != 0.0;
    }
    r.reply.kind =
        any ? samples::RobotCorrection::Kind::axes : samples::RobotCorrection::Kind::none;
  }
  return out;
}

}  // namespace zerog::test
