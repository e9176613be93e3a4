// The Savitzky–Golay differentiator: classic coefficients, exactness on polynomials with
// non-uniform stamps, the stated noise gain (Monte Carlo) and −3 dB frequency (a sine through
// the filter), and the window choice.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "zerog/robot/savitzky_golay.hpp"

namespace zerog::robot {
namespace {

// Output of the fit at the centre sample c of uniform-or-not `t`, `y`.
double apply(const std::vector<double>& t, const std::vector<double>& y, std::size_t c, int m,
             int order, int derivative) {
  LocalPolyFit fit(order);
  const double scale = 0.5 * (t[c + m] - t[c - m]);
  for (std::size_t k = c - m; k <= c + m; ++k) fit.add(t[k] - t[c], scale);
  EXPECT_TRUE(fit.solve());
  double out = 0.0;
  for (std::size_t k = c - m; k <= c + m; ++k) out += fit.weight(t[k] - t[c], derivative) * y[k];
  return out;
}

TEST(SavitzkyGolay, ClassicCoefficients) {
  // Savitzky & Golay 1964, Table I (smoothing, quadratic, 5 points): (−3, 12, 17, 12, −3) / 35;
  // first derivative, quadratic, 5 points: (−2, −1, 0, 1, 2) / 10; second derivative,
  // quadratic, 5 points: (2, −1, −2, −1, 2) / 7.
  std::array<double, 5> c{};
  sg_coefficients({2, 2}, 0, c);
  const double smooth[] = {-3, 12, 17, 12, -3};
  for (int k = 0; k < 5; ++k) EXPECT_NEAR(c[k], smooth[k] / 35.0, 1e-14);
  sg_coefficients({2, 2}, 1, c);
  for (int k = 0; k < 5; ++k) EXPECT_NEAR(c[k], (k - 2) / 10.0, 1e-14);
  sg_coefficients({2, 2}, 2, c);
  const double second[] = {2, -1, -2, -1, 2};
  for (int k = 0; k < 5; ++k) EXPECT_NEAR(c[k], second[k] / 7.0, 1e-14);
  // Order 3 gives the same smoothing and second derivative as order 2 on a centred window.
  std::array<double, 5> c3{};
  sg_coefficients({2, 3}, 2, c3);
  for (int k = 0; k < 5; ++k) EXPECT_NEAR(c3[k], c[k], 1e-13);
}

TEST(SavitzkyGolay, ExactOnCubicsWithJitteredStamps) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  const double h = 0.012;
  std::vector<double> t(41), y(41);
  const auto f = [](double x) { return 0.3 - 1.7 * x + 4.0 * x * x - 9.0 * x * x * x; };
  for (std::size_t k = 0; k < t.size(); ++k) {
    t[k] = 5.0 + (static_cast<double>(k) + jitter(rng)) * h;
    y[k] = f(t[k]);
  }
  const std::size_t c = 20;
  const double x = t[c];
  EXPECT_NEAR(apply(t, y, c, 7, 3, 0), f(x), 1e-9);
  EXPECT_NEAR(apply(t, y, c, 7, 3, 1), -1.7 + 8.0 * x - 27.0 * x * x, 1e-7);
  EXPECT_NEAR(apply(t, y, c, 7, 3, 2), 8.0 - 54.0 * x, 1e-5);
}

TEST(SavitzkyGolay, NoiseGainMatchesMonteCarlo) {
  const double h = 0.004;
  const SgSettings s{10, 3};
  std::mt19937_64 rng(9);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<double> t(21), y(21);
  for (std::size_t k = 0; k < t.size(); ++k) t[k] = static_cast<double>(k) * h;
  for (int d = 0; d <= 2; ++d) {
    double sum2 = 0.0;
    constexpr int kTrials = 20000;
    for (int trial = 0; trial < kTrials; ++trial) {
      for (double& v : y) v = noise(rng);
      const double out = apply(t, y, 10, 10, 3, d);
      sum2 += out * out;
    }
    const double measured = std::sqrt(sum2 / kTrials);
    EXPECT_NEAR(measured / sg_noise_gain(s, d, h), 1.0, 0.03) << "derivative " << d;
  }
  // The gain falls with a wider window, rises as h^−d with a shorter period.
  EXPECT_LT(sg_noise_gain({20, 3}, 2, h), sg_noise_gain({10, 3}, 2, h));
  EXPECT_NEAR(sg_noise_gain(s, 2, h / 2) / sg_noise_gain(s, 2, h), 4.0, 1e-9);
}

TEST(SavitzkyGolay, CutoffIsWhereASineLosesThreeDecibels) {
  const double h = 0.012;
  for (int d = 0; d <= 2; ++d) {
    const SgSettings s{12, 3};
    const double fc = sg_cutoff_hz(s, d, h);
    ASSERT_GT(fc, 0.0);
    ASSERT_LT(fc, 0.5 / h);
    // Amplitude of the d-th derivative estimate of sin(2π f t) against the true (2π f)^d.
    const auto ratio = [&](double f) {
      std::vector<double> t(25), y(25);
      // Two phases in quadrature give the amplitude exactly: out = A sin(φ + ψ).
      double sum2 = 0.0;
      for (const double phase : {0.0, std::numbers::pi / 2.0}) {
        for (std::size_t k = 0; k < t.size(); ++k) {
          t[k] = static_cast<double>(k) * h;
          y[k] = std::sin(2.0 * std::numbers::pi * f * t[k] + phase);
        }
        const double out = apply(t, y, 12, 12, 3, d);
        sum2 += out * out;
      }
      const double peak = std::sqrt(sum2);
      return peak / std::pow(2.0 * std::numbers::pi * f, d);
    };
    EXPECT_NEAR(ratio(fc), 1.0 / std::sqrt(2.0), 1e-6) << "derivative " << d;
    EXPECT_NEAR(ratio(0.1 * fc), 1.0, 0.02) << "derivative " << d;
  }
}

TEST(SavitzkyGolay, ChosenWindowIsTheWidestThatPassesTheBandwidth) {
  for (const double h : {0.004, 0.012}) {
    const SgSettings s = choose_sg_window(h, 3.0, 3, 2);
    ASSERT_TRUE(valid(s));
    EXPECT_GE(sg_cutoff_hz(s, 2, h), 3.0);
    EXPECT_LT(sg_cutoff_hz({s.half_width + 1, 3}, 2, h), 3.0);
    EXPECT_DOUBLE_EQ(sg_causal_delay_s(s, h), s.half_width * h);
  }
  // A bandwidth no window reaches gives the smallest window.
  EXPECT_EQ(choose_sg_window(0.012, 1000.0, 3, 2).half_width, 2);
  EXPECT_FALSE(valid({1, 3}));
  EXPECT_FALSE(valid({5, 4}));
}

}  // namespace
}  // namespace zerog::robot
