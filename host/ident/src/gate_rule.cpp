#include "zerog/ident/gate_rule.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <numbers>

#include "zerog/control/motion.hpp"
#include "zerog/control/virtual_body.hpp"

namespace zerog::ident {

namespace {

// The recording replayed through zerog-rt's own gate (control::ContactGate) at threshold `t`:
// how many times it would have confirmed a push, and in how many cycles it was open (the noise
// driving the body). A gap in the cycles restarts the gate.
void replay(const std::vector<Eigen::Vector3d>& x, const std::vector<std::size_t>& gaps, double t,
            double dt_s, const GateRuleOptions& o, std::size_t& confirms, std::size_t& open) {
  control::ContactGate gate;
  confirms = open = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (gaps[i]) gate.reset();
    const bool was_open = gate.is_open();
    (void)gate.step(x[i], dt_s, t, o.release_fraction * t, o.confirm_cycles);
    if (gate.is_open() && !was_open) ++confirms;
    if (gate.is_open()) ++open;
  }
}

double lag1(const std::vector<double>& v) {
  if (v.size() < 3) return 0.0;
  double mean = 0.0;
  for (double x : v) mean += x;
  mean /= static_cast<double>(v.size());
  double num = 0.0, den = 0.0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    den += (v[i] - mean) * (v[i] - mean);
    if (i > 0) num += (v[i] - mean) * (v[i - 1] - mean);
  }
  return den > 0.0 ? num / den : 0.0;
}

// The confirm statistic: the smallest norm over `confirm` consecutive cycles with no gap among
// them (a window confirms a push at threshold t when it is above t). Windows over a gap are left
// out.
std::vector<double> run_minima(const std::vector<double>& norm,
                               const std::vector<std::size_t>& gaps, int confirm) {
  std::vector<double> out;
  const std::size_t c = static_cast<std::size_t>(std::max(confirm, 1));
  std::size_t since_gap = 0;
  for (std::size_t i = 0; i < norm.size(); ++i) {
    since_gap = gaps[i] ? 1 : since_gap + 1;
    if (since_gap < c) continue;
    double m = norm[i];
    for (std::size_t k = 1; k < c; ++k) m = std::min(m, norm[i - k]);
    out.push_back(m);
  }
  return out;
}

// P(|x| > t) of one cycle's noise (norm_tail over the noise's principal variances).
using Tail = std::function<double(double)>;

// The smallest x in [0, hi] with f(x) ≤ target, for an f that falls with x, by bisection to
// `tol`; hi if f(hi) is still above it.
double first_below(const std::function<double(double)>& f, double target, double hi, double tol) {
  if (!(f(hi) <= target)) return hi;
  double lo = 0.0;
  while (hi - lo > tol) {
    const double mid = 0.5 * (lo + hi);
    (f(mid) > target ? lo : hi) = mid;
  }
  return hi;
}

// t with tail(t) = q, t within 20 `scale`.
double tail_level(double q, const Tail& tail, double scale) {
  return first_below(tail, q, 20.0 * scale, 1e-9 * scale);
}

// The 48-point Gauss–Legendre rule on [−1, 1]: the nodes are the roots of the Legendre
// polynomial P₄₈ (three-term recurrence (j) P_j = (2j − 1) z P_{j−1} − (j − 1) P_{j−2}), found by
// Newton's iteration from z = cos(π (i + 3/4) / (n + 1/2)); the weights 2 / ((1 − z²) P₄₈′(z)²).
// Checked against the χ² tail to 1e-9 (gate_rule_test, TheNormsTailWithUnequalAxes).
struct GaussLegendre {
  static constexpr int kN = 48;
  std::array<double, kN> x{}, w{};
  GaussLegendre() {
    for (int i = 0; i < (kN + 1) / 2; ++i) {
      double z = std::cos(std::numbers::pi * (i + 0.75) / (kN + 0.5)), dp = 0.0;
      for (int it = 0; it < 100; ++it) {
        double p1 = 1.0, p2 = 0.0;
        for (int j = 1; j <= kN; ++j) {
          const double p3 = p2;
          p2 = p1;
          p1 = ((2.0 * j - 1.0) * z * p2 - (j - 1.0) * p3) / j;
        }
        dp = kN * (z * p1 - p2) / (z * z - 1.0);
        const double dz = p1 / dp;
        z -= dz;
        if (std::abs(dz) < 1e-15) break;
      }
      x[static_cast<std::size_t>(i)] = -z;
      x[static_cast<std::size_t>(kN - 1 - i)] = z;
      w[static_cast<std::size_t>(i)] = w[static_cast<std::size_t>(kN - 1 - i)] =
          2.0 / ((1.0 - z * z) * dp * dp);
    }
  }
};

// The exponent e of the rule, measured at moderate levels: at levels t_q where one cycle is
// above with probability q (norm_tail), the windows of `confirm` cycles all above t_q are
// counted; where they are more than q^confirm by three standard errors of that count (and at
// least 5), q^e = their fraction gives e = ln(fraction) / ln(q). The smallest e over the levels;
// `confirm` where none is significant. It sees tails heavier than the Gaussian's.
double measured_exponent(const std::vector<double>& minima, const Tail& tail, double sigma,
                         int confirm, int& levels_measured) {
  levels_measured = 0;
  double e = confirm;
  const double n = static_cast<double>(minima.size());
  if (minima.empty() || sigma <= 0.0) return e;
  static constexpr double kLevels[] = {0.5,  0.3,  0.2,   0.1,   0.05,  0.03,
                                       0.02, 0.01, 0.005, 0.002, 0.001, 5e-4};
  for (const double q : kLevels) {
    const double t = tail_level(q, tail, sigma);
    const double count = static_cast<double>(
        std::count_if(minima.begin(), minima.end(), [t](double m) { return m > t; }));
    if (count < 5.0) break;
    ++levels_measured;
    const double independent = std::pow(q, confirm);
    const double se = std::sqrt(independent * (1.0 - independent) / n);
    if (count / n > independent + 3.0 * se) e = std::min(e, std::log(count / n) / std::log(q));
  }
  return e;
}

// The exponent e of the rule for a Gaussian noise with the recording's correlation from cycle
// to cycle: for X ~ N(0, Σ) over `confirm` cycles, P(all above t) falls as exp(−e t²/2) with
// e = min over x ≥ 1 of xᵀ Σ⁻¹ x (Σ the correlation matrix; 1ᵀΣ⁻¹1 when Σ⁻¹1 ≥ 0), against
// exp(−t²/2) for one cycle: so P(run) ≈ p(t)^e deep in the tail, where the rule's threshold lies
// (at moderate levels the run is rarer than that: the safe side). Σ from the autocorrelation of
// the three axes pooled (mean included, as in σ), at lags 1 … confirm − 1 within stretches
// without a gap; a lag whose correlation is within three standard errors (3/√(3n)) of zero is
// taken as zero, so white noise keeps e = confirm. AR(1) with correlation ρ gives
// e = (confirm − (confirm − 2) ρ)/(1 + ρ); a Σ that is not positive definite, e = 1.
double gaussian_exponent(const std::vector<Eigen::Vector3d>& x,
                         const std::vector<std::size_t>& gaps, int confirm,
                         std::vector<double>& correlation) {
  const int c = std::max(confirm, 1);
  correlation.assign(static_cast<std::size_t>(c), 0.0);
  correlation[0] = 1.0;
  double energy = 0.0;
  for (const Eigen::Vector3d& v : x) energy += v.squaredNorm();
  if (energy <= 0.0 || c == 1) return 1.0;
  std::vector<std::size_t> since_gap(x.size());
  for (std::size_t i = 0; i < x.size(); ++i)
    since_gap[i] = i == 0 || gaps[i] ? 0 : since_gap[i - 1] + 1;
  const double significant = 3.0 / std::sqrt(3.0 * static_cast<double>(x.size()));
  for (int k = 1; k < c; ++k) {
    double sum = 0.0;
    const std::size_t lag = static_cast<std::size_t>(k);
    for (std::size_t i = lag; i < x.size(); ++i)
      if (since_gap[i] >= lag) sum += x[i].dot(x[i - lag]);
    const double r = sum / energy;
    correlation[lag] = std::abs(r) > significant ? r : 0.0;
  }
  Eigen::MatrixXd S(c, c);
  for (int i = 0; i < c; ++i)
    for (int j = 0; j < c; ++j) S(i, j) = correlation[static_cast<std::size_t>(std::abs(i - j))];
  const Eigen::LLT<Eigen::MatrixXd> llt(S);
  if (llt.info() != Eigen::Success) return 1.0;
  const Eigen::MatrixXd P = llt.solve(Eigen::MatrixXd::Identity(c, c));
  // min xᵀPx over x ≥ 1: the optimum has some components at 1 (the set A) and the others at
  // their unconstrained optimum given those, which must be ≥ 1. Every A is tried (2^c − 1 of
  // them); beyond 12 cycles only A = all, and e = 1 if that is not the optimum.
  const Eigen::VectorXd ones = Eigen::VectorXd::Ones(c);
  if (c > 12) {
    const Eigen::VectorXd g = P * ones;
    return (g.array() >= 0.0).all() ? ones.dot(g) : 1.0;
  }
  double best = std::numeric_limits<double>::infinity();
  for (unsigned mask = 1; mask < (1u << c); ++mask) {
    std::vector<int> active, free;
    for (int i = 0; i < c; ++i) ((mask >> i) & 1u ? active : free).push_back(i);
    Eigen::VectorXd v = ones;
    if (!free.empty()) {
      Eigen::MatrixXd Pff(free.size(), free.size());
      Eigen::VectorXd rhs = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(free.size()));
      for (std::size_t a = 0; a < free.size(); ++a) {
        for (std::size_t b = 0; b < free.size(); ++b)
          Pff(static_cast<Eigen::Index>(a), static_cast<Eigen::Index>(b)) = P(free[a], free[b]);
        for (const int j : active) rhs[static_cast<Eigen::Index>(a)] -= P(free[a], j);
      }
      const Eigen::VectorXd xf = Pff.llt().solve(rhs);
      if ((xf.array() < 1.0 - 1e-12).any()) continue;
      for (std::size_t a = 0; a < free.size(); ++a) v[free[a]] = xf[static_cast<Eigen::Index>(a)];
    }
    best = std::min(best, v.dot(P * v));
  }
  return best;
}

// `x` the noise the advised gate judges, `x_now` the one the configured gate (threshold `now`)
// judges: the same for the force; for the torque they differ with the force gate's threshold.
GateGroup group(const std::vector<Eigen::Vector3d>& x, const std::vector<Eigen::Vector3d>& x_now,
                const std::vector<std::size_t>& gaps, double cycle_s, const GateRuleOptions& o,
                double now) {
  const double cycles_per_hour = 3600.0 / cycle_s;
  GateGroup g;
  double sum = 0.0;
  for (int k = 0; k < 3; ++k) {
    double s = 0.0;
    for (const Eigen::Vector3d& v : x) s += v[k] * v[k];
    g.rms[static_cast<std::size_t>(k)] = std::sqrt(s / static_cast<double>(x.size()));
    sum += s / static_cast<double>(x.size());
  }
  g.sigma = std::sqrt(sum / 3.0);
  // The noise's principal variances (the eigenvalues of its second moment, the mean included):
  // the norm's tail is that of unequal axes (the torque's z axis is often half the others).
  Eigen::Matrix3d S = Eigen::Matrix3d::Zero();
  for (const Eigen::Vector3d& v : x) S += v * v.transpose();
  S /= static_cast<double>(x.size());
  const Eigen::Vector3d lambda =
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(S, Eigen::EigenvaluesOnly).eigenvalues();
  for (int k = 0; k < 3; ++k)
    g.principal_sigma[static_cast<std::size_t>(k)] = std::sqrt(std::max(0.0, lambda[k]));
  const Tail tail = [lambda](double t) { return norm_tail(lambda, t); };
  std::vector<double> norm(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) norm[i] = x[i].norm();
  g.lag1 = lag1(norm);
  // How many cycles in a row the noise must clear, in effect: `confirm` for independent
  // cycles, fewer when the noise stays up for runs of cycles. The smaller of the two exponents
  // (each errs on the safe side where the other does not), within [1, confirm].
  const double measured = measured_exponent(run_minima(norm, gaps, o.confirm_cycles), tail, g.sigma,
                                            o.confirm_cycles, g.levels_measured);
  const double gaussian = gaussian_exponent(x, gaps, o.confirm_cycles, g.correlation);
  g.effective_confirm =
      std::clamp(std::min(measured, gaussian), 1.0, static_cast<double>(o.confirm_cycles));
  // The smallest t (within 100 σ, to 1e-6 σ) with cycles/h × P(|x| > t)^e ≤ the target.
  const auto rate = [&](double t) {
    return cycles_per_hour * std::pow(tail(t), g.effective_confirm);
  };
  const double t = first_below(rate, o.false_per_hour, 100.0 * g.sigma, 1e-6 * g.sigma);
  g.threshold = t;
  g.false_per_hour = rate(t);
  replay(x, gaps, t, cycle_s, o, g.confirms_at_threshold, g.open_cycles_at_threshold);
  replay(x_now, gaps, now, cycle_s, o, g.confirms_now, g.open_cycles_now);
  return g;
}

}  // namespace

double chi2_3_tail(double x) {
  if (x <= 0.0) return 1.0;
  return std::erfc(std::sqrt(x / 2.0)) + std::sqrt(2.0 * x / std::numbers::pi) * std::exp(-x / 2.0);
}

double norm_tail(const Eigen::Vector3d& variances, double t) {
  if (t <= 0.0) return 1.0;
  // x = Λ^½ z with z standard normal: over the directions d of z (uniform on the sphere) |z| is
  // χ₃-distributed, so P(|x| > t) = (1/4π) ∫ Q₃(t² / dᵀΛd) dΩ. The integrand is smooth however
  // unequal the axes (the density of x itself is not: with one axis a thousandth of the others
  // it lives in a sliver of directions). The octant times eight (even in each axis), the largest
  // variance at the pole, 48 × 48 Gauss–Legendre points.
  std::array<double, 3> l = {variances[0], variances[1], variances[2]};
  std::sort(l.begin(), l.end());
  if (!(l[2] > 0.0)) return 0.0;
  for (double& v : l) v = std::max(v, 0.0);
  static const GaussLegendre gl;
  const double quarter = std::numbers::pi / 4.0;  // [0, π/2] mapped from [−1, 1]
  double sum = 0.0;
  for (int i = 0; i < GaussLegendre::kN; ++i) {
    const double th = quarter * (gl.x[static_cast<std::size_t>(i)] + 1.0);
    const double st = std::sin(th), ct = std::cos(th);
    for (int j = 0; j < GaussLegendre::kN; ++j) {
      const double ph = quarter * (gl.x[static_cast<std::size_t>(j)] + 1.0);
      const double cp = std::cos(ph), sp = std::sin(ph);
      const double a = st * st * (l[0] * cp * cp + l[1] * sp * sp) + ct * ct * l[2];
      const double q = a > 0.0 ? chi2_3_tail(t * t / a) : 0.0;
      sum += gl.w[static_cast<std::size_t>(i)] * gl.w[static_cast<std::size_t>(j)] * st * q;
    }
  }
  return std::min(1.0, sum * quarter * quarter * 2.0 / std::numbers::pi);
}

GateAdvice gate_rule(const std::vector<loop::CycleRecord>& cycles, const GateRuleOptions& o) {
  GateAdvice a;
  std::vector<Eigen::Vector3d> force, torque_sensor, torque_com;
  std::vector<std::size_t> gaps;
  std::vector<double> dt;
  std::uint64_t last = 0;
  // A push's first cycles leave the body still while the gate confirms: the cycles that come
  // fewer than confirm + 2 before the body moves are the push's, not the noise's.
  const auto moves = [](const loop::CycleRecord& r) {
    return r.state == loop::State::zero_g &&
           (!r.body.v_world_mps.isZero(0.0) || !r.body.L_world_kgm2ps.isZero(0.0));
  };
  std::vector<std::uint8_t> before_push(cycles.size(), 0);
  int until = -1;
  for (std::size_t i = cycles.size(); i-- > 0;) {
    until = moves(cycles[i]) ? 0 : until < 0 ? -1 : until + 1;
    before_push[i] = until >= 0 && until <= o.confirm_cycles + 2;
  }
  for (std::size_t i = 0; i < cycles.size(); ++i) {
    const loop::CycleRecord& r = cycles[i];
    // At rest in zero-g: the virtual body has not moved (no push confirmed so far, none about
    // to be), the model's row was not a held sensor value, and zerog-rt's gate could open on
    // it: not while the motion estimator settles or the contact's tare is taken (the gate
    // stays closed there, and those rows carry the offsets the settled, tared ones do not).
    constexpr std::uint32_t kGateClosed = loop::kEstimatorSettling | loop::kContactTaring;
    if (r.state != loop::State::zero_g || (r.flags & (loop::kContactHeld | kGateClosed)) != 0)
      continue;
    if (moves(r) || before_push[i]) continue;
    const Eigen::Vector3d F(r.contact[0], r.contact[1], r.contact[2]);
    const Eigen::Vector3d M(r.contact[3], r.contact[4], r.contact[5]);
    force.push_back(F);
    torque_sensor.push_back(M);
    torque_com.push_back(control::torque_about(M, F, Eigen::Vector3d::Zero(), o.com_sensor_m));
    gaps.push_back(last != 0 && r.cycle != last + 1 ? 1 : 0);
    last = r.cycle;
    dt.push_back(r.dt_s);
  }
  a.cycles = force.size();
  if (a.cycles < kMinGateCycles) {
    a.note = "only " + std::to_string(a.cycles) +
             " zero-g cycles at rest (the virtual body still, " + std::to_string(kMinGateCycles) +
             " needed): record zerog-rt in zero-g with nobody touching the part for a few "
             "seconds (or minutes: the longer, the surer)";
    return a;
  }
  std::nth_element(dt.begin(), dt.begin() + static_cast<std::ptrdiff_t>(dt.size() / 2), dt.end());
  a.cycle_s = dt[dt.size() / 2];
  a.force = group(force, force, gaps, a.cycle_s, o, o.force_now_N);
  // The torque the torque gate judges (control::torque_gate_input) depends on the force gate's
  // threshold: the advised one for the advice and its replay, the configured one for the
  // configured gate's replay.
  const auto judged = [&](double force_open_N) {
    std::vector<Eigen::Vector3d> m(force.size());
    for (std::size_t i = 0; i < force.size(); ++i)
      m[i] = control::torque_gate_input(torque_sensor[i], torque_com[i], force[i], force_open_N);
    return m;
  };
  a.torque =
      group(judged(a.force.threshold), judged(o.force_now_N), gaps, a.cycle_s, o, o.torque_now_Nm);
  a.known = true;
  return a;
}

std::string format_gate_advice(const GateAdvice& a, const GateRuleOptions& o) {
  if (!a.known) return "gate: not known: " + a.note + "\n";
  std::string out;
  char line[600];
  std::snprintf(line, sizeof line,
                "gate: %zu zero-g cycles at rest (%.4g s each), confirm %d cycles in a row, "
                "target %.3g false confirms per hour (docs/zerog-rt.md, \"Setting the contact "
                "gate\")\n",
                a.cycles, a.cycle_s, o.confirm_cycles, o.false_per_hour);
  out += line;
  const auto one = [&](const char* name, const char* unit, const GateGroup& g, double now) {
    std::snprintf(line, sizeof line,
                  "  %s: contact RMS %.3g / %.3g / %.3g %s (principal %.3g / %.3g / %.3g), "
                  "lag-1 correlation of the norm %.2f, runs as of %.2f independent cycles (%d "
                  "levels measured); threshold %.3g %s (%.3g false confirms/h; replayed: %zu "
                  "confirms), configured %.3g %s (replayed: %zu confirms, open %zu cycles)\n",
                  name, g.rms[0], g.rms[1], g.rms[2], unit, g.principal_sigma[0],
                  g.principal_sigma[1], g.principal_sigma[2], g.lag1, g.effective_confirm,
                  g.levels_measured, g.threshold, unit, g.false_per_hour, g.confirms_at_threshold,
                  now, unit, g.confirms_now, g.open_cycles_now);
    out += line;
  };
  one("force", "N", a.force, o.force_now_N);
  one("torque the torque gate judges (control::torque_gate_input)", "N*m", a.torque,
      o.torque_now_Nm);
  std::snprintf(line, sizeof line,
                "[limits] for zerog-rt (proto/rt_config.md):\nforce_deadband_N = %.3g\n"
                "torque_deadband_Nm = %.3g\n",
                a.force.threshold, a.torque.threshold);
  out += line;
  if (a.force.effective_confirm < o.confirm_cycles || a.torque.effective_confirm < o.confirm_cycles)
    out +=
        "  note: the noise is correlated from cycle to cycle: it stays above a threshold for "
        "runs of cycles more often than independent cycles would, so the thresholds count fewer "
        "cycles in a row than the gate's (the measured figure above) and sit higher\n";
  if (a.force.levels_measured == 0 || a.torque.levels_measured == 0)
    out +=
        "  note: too few cycles at rest to measure whether the noise is correlated; the "
        "thresholds assume independent cycles: record longer at rest to check\n";
  return out;
}

nlohmann::json to_json(const GateAdvice& a, const GateRuleOptions& o) {
  if (!a.known) return {{"known", false}, {"note", a.note}, {"cycles", a.cycles}};
  const auto g = [](const GateGroup& x) {
    return nlohmann::json{{"rms", x.rms},
                          {"sigma", x.sigma},
                          {"principal_sigma", x.principal_sigma},
                          {"lag1", x.lag1},
                          {"effective_confirm", x.effective_confirm},
                          {"levels_measured", x.levels_measured},
                          {"correlation", x.correlation},
                          {"threshold", x.threshold},
                          {"false_per_hour", x.false_per_hour},
                          {"confirms_at_threshold", x.confirms_at_threshold},
                          {"confirms_now", x.confirms_now},
                          {"open_cycles_at_threshold", x.open_cycles_at_threshold},
                          {"open_cycles_now", x.open_cycles_now}};
  };
  return {{"known", true},
          {"cycles", a.cycles},
          {"cycle_s", a.cycle_s},
          {"confirm_cycles", o.confirm_cycles},
          {"target_false_per_hour", o.false_per_hour},
          {"force_N", g(a.force)},
          {"torque_Nm", g(a.torque)}};
}

}  // namespace zerog::ident
