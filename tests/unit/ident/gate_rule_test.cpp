// The contact gate's threshold from the measured noise (issue 28, item 4;
// host/ident/include/zerog/ident/gate_rule.hpp).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <random>

#include "zerog/ident/gate_rule.hpp"

namespace zerog::ident {
namespace {

using ::testing::HasSubstr;

TEST(GateRule, TheChiSquareTailOfThreeDegrees) {
  // Tables: P(χ²₃ > 7.815) = 0.05, P(χ²₃ > 11.345) = 0.01, P(χ²₃ > 16.266) = 0.001.
  EXPECT_NEAR(chi2_3_tail(7.815), 0.05, 1e-4);
  EXPECT_NEAR(chi2_3_tail(11.345), 0.01, 1e-5);
  EXPECT_NEAR(chi2_3_tail(16.266), 0.001, 1e-6);
  EXPECT_EQ(chi2_3_tail(0.0), 1.0);
}

TEST(GateRule, TheNormsTailWithUnequalAxes) {
  for (const double t : {0.5, 1.0, 2.0, 3.0, 4.0, 5.0})
    EXPECT_NEAR(norm_tail(Eigen::Vector3d(1.0, 1.0, 1.0), t) / chi2_3_tail(t * t), 1.0, 1e-9) << t;
  // Two axes: P(χ²₂ > t²) = e^(−t²/2); one: P(|z| > t) = erfc(t/√2).
  for (const double t : {1.0, 2.0, 3.0, 4.0}) {
    EXPECT_NEAR(norm_tail(Eigen::Vector3d(1.0, 1.0, 1e-10), t) / std::exp(-0.5 * t * t), 1.0, 1e-3)
        << t;
    EXPECT_NEAR(norm_tail(Eigen::Vector3d(1e-10, 1.0, 1e-10), t) / std::erfc(t / std::sqrt(2.0)),
                1.0, 1e-3)
        << t;
  }
  // The torque about the centre of mass at rest (quiet_fused, seed 11): z at half of x and y.
  // The pooled σ's χ² tail is 2.4× too small at 4.2 σ; the tail of the three axes is not.
  const Eigen::Vector3d torque(0.0196 * 0.0196, 0.0426 * 0.0426, 0.0433 * 0.0433);
  const double sigma = std::sqrt(torque.mean());
  EXPECT_GT(norm_tail(torque, 4.2 * sigma) / chi2_3_tail(4.2 * 4.2), 2.5);
}

// Zero-g cycles at 12 ms with white contact noise σ_F per force axis and σ_M per torque axis; a
// push at cycle `push` (20 N for 10 cycles) after which the body moves.
std::vector<loop::CycleRecord> cycles(double sigma_F, double sigma_M, std::uint64_t seed,
                                      std::size_t n, std::size_t push) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<loop::CycleRecord> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    loop::CycleRecord& r = out[i];
    r.cycle = i + 1;
    r.dt_s = 0.012;
    r.state = i < 10 ? loop::State::idle : loop::State::zero_g;
    for (int k = 0; k < 3; ++k) r.contact[static_cast<std::size_t>(k)] = sigma_F * g(rng);
    for (int k = 3; k < 6; ++k) r.contact[static_cast<std::size_t>(k)] = sigma_M * g(rng);
    if (i >= push && i < push + 10) r.contact[0] += 20.0;
    if (i >= push + 3) r.body.v_world_mps = Eigen::Vector3d(0.01, 0.0, 0.0);
  }
  return out;
}

TEST(GateRule, TheThresholdKeepsTheNoiseOutOnThreeSeeds) {
  GateRuleOptions o;  // the centre of mass at the sensor: the torque is the contact's own
  for (const std::uint64_t seed : {1u, 2u, 3u}) {
    const GateAdvice a = gate_rule(cycles(0.6, 0.06, seed, 20000, 15000), o);
    ASSERT_TRUE(a.known) << a.note;
    // The push's cycles and everything after it are left out; so are the idle ones.
    // Zero-g from cycle 10; the body moves from 15003: the confirm + 2 cycles before it go too.
    EXPECT_EQ(a.cycles, 15003u - 10u - (static_cast<std::size_t>(o.confirm_cycles) + 2u));
    EXPECT_NEAR(a.force.sigma, 0.6, 0.6 * 0.02);
    EXPECT_NEAR(a.torque.sigma, 0.06, 0.06 * 0.02);
    // The rule: cycles/h × Q₃(t²/σ²)³ = 0.01 at 12 ms gives t = 3.72 σ.
    EXPECT_NEAR(a.force.threshold / a.force.sigma, 3.72, 0.01);
    EXPECT_LE(a.force.false_per_hour, 0.01);
    EXPECT_EQ(a.force.confirms_at_threshold, 0u);
    EXPECT_EQ(a.torque.confirms_at_threshold, 0u);
    EXPECT_EQ(a.force.open_cycles_at_threshold, 0u);
    // A threshold at 1.5 σ is confirmed by the noise alone, and zerog-rt's gate (replayed, with
    // its release at half the threshold) then stays open: the noise drives the body in most
    // cycles.
    GateRuleOptions low = o;
    low.force_now_N = 1.5 * 0.6;
    const GateAdvice noisy = gate_rule(cycles(0.6, 0.06, seed, 20000, 15000), low);
    EXPECT_GE(noisy.force.confirms_now, 5u);
    EXPECT_GT(noisy.force.open_cycles_now, noisy.cycles / 2);
  }
  // A lower target rate asks for a higher threshold.
  GateRuleOptions strict = o;
  strict.false_per_hour = 1e-4;
  EXPECT_GT(gate_rule(cycles(0.6, 0.06, 1, 20000, 15000), strict).force.threshold,
            gate_rule(cycles(0.6, 0.06, 1, 20000, 15000), o).force.threshold);
  // The torque the gate judges (control::torque_gate_input): with the force under the force
  // gate's threshold, about the sensor origin, so a force noise 0.2 m from the virtual centre of
  // mass does not add to it; about the centre of mass it would (√(0.06² + ⅔ 0.12²) = 0.115).
  GateRuleOptions com = o;
  com.com_sensor_m = Eigen::Vector3d(0.0, 0.0, 0.2);
  const GateAdvice a = gate_rule(cycles(0.6, 0.06, 1, 20000, 15000), com);
  EXPECT_NEAR(a.torque.sigma, 0.06, 0.06 * 0.03);
  EXPECT_EQ(a.torque.confirms_at_threshold, 0u);
  const std::string text = format_gate_advice(a, com);
  EXPECT_THAT(text, HasSubstr("force_deadband_N = "));
  EXPECT_THAT(text, HasSubstr("torque_deadband_Nm = "));
  EXPECT_EQ(to_json(a, com)["force_N"]["confirms_at_threshold"], 0);
}

// Zero-g at 12 ms, nobody touching: contact noise per axis a first-order autoregression
// e_k = ρ e_{k−1} + √(1 − ρ²) ε_k of standard deviation σ (an arm that rings, an estimator that
// smooths: the noise stays up for runs of cycles).
std::vector<loop::CycleRecord> correlated_cycles(double sigma_F, double sigma_M, double rho,
                                                 std::uint64_t seed, std::size_t n) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<loop::CycleRecord> out(n);
  std::array<double, 6> e{};
  for (double& v : e) v = g(rng);
  for (std::size_t i = 0; i < n; ++i) {
    loop::CycleRecord& r = out[i];
    r.cycle = i + 1;
    r.dt_s = 0.012;
    r.state = loop::State::zero_g;
    for (std::size_t k = 0; k < 6; ++k) {
      e[k] = rho * e[k] + std::sqrt(1.0 - rho * rho) * g(rng);
      r.contact[k] = (k < 3 ? sigma_F : sigma_M) * e[k];
    }
  }
  return out;
}

TEST(GateRule, CorrelatedNoiseCountsFewerCyclesInARowAndStaysOut) {
  GateRuleOptions o;
  for (const std::uint64_t seed : {4u, 5u, 6u}) {
    SCOPED_TRACE(seed);
    // White noise: the runs are as rare as independent cycles make them.
    const GateAdvice white = gate_rule(cycles(0.6, 0.06, seed, 20000, 15000), o);
    EXPECT_EQ(white.force.effective_confirm, 3.0);
    EXPECT_EQ(white.torque.effective_confirm, 3.0);
    EXPECT_GE(white.force.levels_measured, 3);
    // Twelve minutes of noise correlated from cycle to cycle (ρ = 0.9: a time constant of ten
    // cycles). The independent rule's threshold (3.72 σ, replayed as the configured one) lets
    // the noise confirm pushes; the measured rule counts fewer cycles in a row and does not.
    GateRuleOptions independent = o;
    independent.force_now_N = 3.72 * 0.6;
    independent.torque_now_Nm = 3.72 * 0.06;
    const GateAdvice a = gate_rule(correlated_cycles(0.6, 0.06, 0.9, seed, 60000), independent);
    ASSERT_TRUE(a.known) << a.note;
    EXPECT_GE(a.force.confirms_now + a.torque.confirms_now, 2u);
    EXPECT_LT(a.force.effective_confirm, 2.0);
    EXPECT_LT(a.torque.effective_confirm, 2.0);
    EXPECT_GT(a.force.threshold, 4.0 * a.force.sigma);
    EXPECT_EQ(a.force.confirms_at_threshold, 0u);
    EXPECT_EQ(a.torque.confirms_at_threshold, 0u);
    EXPECT_THAT(format_gate_advice(a, o), HasSubstr("correlated from cycle to cycle"));
    // Deep in the tail a Gaussian noise of correlation ρ stays above t for three cycles with
    // Q₃^((3 − ρ)/(1 + ρ)); at ρ = 0.5 (5/3) the runs above moderate levels alone say about 2.
    const GateAdvice half = gate_rule(correlated_cycles(0.6, 0.06, 0.5, seed, 60000), o);
    EXPECT_NEAR(half.force.effective_confirm, 2.5 / 1.5, 0.05);
    EXPECT_NEAR(half.torque.effective_confirm, 2.5 / 1.5, 0.05);
    EXPECT_EQ(half.force.confirms_at_threshold, 0u);
  }
}

// White noise with bursts (an arm that rings for a few cycles after a bump): every 2000 cycles,
// four cycles 5 σ along a random direction. Too rare to correlate the cycles measurably, but
// they stay above the independent rule's threshold for three cycles at a time; the runs
// counted above moderate levels see them and the threshold goes above them.
TEST(GateRule, BurstsOfNoiseStayOutToo) {
  GateRuleOptions o;
  for (const std::uint64_t seed : {4u, 5u, 6u}) {
    SCOPED_TRACE(seed);
    std::vector<loop::CycleRecord> c = correlated_cycles(0.6, 0.06, 0.0, seed, 60000);
    std::mt19937_64 rng(seed + 100);
    std::normal_distribution<double> g(0.0, 1.0);
    for (std::size_t start = 1000; start + 4 < c.size(); start += 2000) {
      const Eigen::Vector3d d = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
      for (std::size_t i = start; i < start + 4; ++i)
        for (std::size_t k = 0; k < 3; ++k) c[i].contact[k] += 5.0 * 0.6 * d[k];
    }
    GateRuleOptions independent = o;
    independent.force_now_N = 3.72 * 0.6;
    const GateAdvice a = gate_rule(c, independent);
    EXPECT_GE(a.force.confirms_now, 10u);
    EXPECT_LT(a.force.effective_confirm, 1.5);
    EXPECT_EQ(a.force.confirms_at_threshold, 0u);
  }
}

// White noise on one axis only (the others a thousandth of it): the norm is |z| of one axis,
// whose tail is far heavier than the χ² tail of three axes at the pooled σ. The pooled rule's
// threshold (3.72 σ, replayed as the configured one) lets the noise confirm pushes; the rule on
// the axes' own variances does not.
TEST(GateRule, NoiseOnOneAxisStaysOut) {
  GateRuleOptions o;
  std::size_t pooled_confirms = 0;
  for (const std::uint64_t seed : {7u, 8u, 9u}) {
    SCOPED_TRACE(seed);
    std::vector<loop::CycleRecord> c = correlated_cycles(0.6, 0.06, 0.0, seed, 120000);
    for (loop::CycleRecord& r : c)
      for (const std::size_t k : {1u, 2u, 4u, 5u}) r.contact[k] *= 1e-3;
    GateRuleOptions pooled = o;
    const double pooled_sigma = 0.6 / std::sqrt(3.0);
    pooled.force_now_N = 3.72 * pooled_sigma;
    const GateAdvice a = gate_rule(c, pooled);
    ASSERT_TRUE(a.known) << a.note;
    EXPECT_NEAR(a.force.sigma, pooled_sigma, 0.02 * pooled_sigma);
    EXPECT_NEAR(a.force.principal_sigma[2], 0.6, 0.012);
    pooled_confirms += a.force.confirms_now;
    EXPECT_GT(a.force.threshold, 1.3 * pooled.force_now_N);
    EXPECT_EQ(a.force.confirms_at_threshold, 0u);
    EXPECT_EQ(a.torque.confirms_at_threshold, 0u);
  }
  EXPECT_GE(pooled_confirms, 3u);
}

// zerog-rt's first zero-g rows while its motion estimator settles, and while the contact's tare
// is taken, keep the gate closed and carry an offset (the estimator's first rows, the zero not
// yet subtracted): they are no part of the noise the gate judges, and replaying the gate on
// them would confirm pushes zerog-rt never could.
TEST(GateRule, RowsWhereTheGateIsClosedAreLeftOut) {
  std::vector<loop::CycleRecord> c = cycles(0.6, 0.06, 1, 20000, 15000);
  for (std::size_t i = 10; i < 400; ++i) {
    c[i].flags |= i < 200 ? loop::kEstimatorSettling : loop::kContactTaring;
    c[i].contact[1] += 3.0;  // 5 sigma: the advised gate would confirm it
  }
  const GateAdvice a = gate_rule(c, GateRuleOptions{});
  ASSERT_TRUE(a.known) << a.note;
  EXPECT_EQ(a.cycles,
            15003u - 400u - (static_cast<std::size_t>(GateRuleOptions{}.confirm_cycles) + 2u));
  EXPECT_NEAR(a.force.sigma, 0.6, 0.6 * 0.02);
  EXPECT_EQ(a.force.confirms_at_threshold, 0u);
}

TEST(GateRule, TooFewCyclesAtRestSaySo) {
  const GateAdvice a = gate_rule(cycles(0.6, 0.06, 1, 150, 100000), GateRuleOptions{});
  EXPECT_FALSE(a.known);
  EXPECT_THAT(a.note, HasSubstr("record zerog-rt in zero-g with nobody touching"));
  EXPECT_THAT(format_gate_advice(a, GateRuleOptions{}), HasSubstr("gate: not known"));
}

}  // namespace
}  // namespace zerog::ident
