#include "zerog/ident/gate_rule.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
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

GateGroup group(const std::vector<Eigen::Vector3d>& x, const std::vector<std::size_t>& gaps,
                double cycle_s, const GateRuleOptions& o, double now) {
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
  std::vector<double> norm(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) norm[i] = x[i].norm();
  g.lag1 = lag1(norm);
  // The smallest t (in steps of 0.1 % of σ) with cycles/h × Q₃(t²/σ²)^confirm ≤ the target.
  const auto rate = [&](double t) {
    return cycles_per_hour * std::pow(chi2_3_tail(t * t / (g.sigma * g.sigma)), o.confirm_cycles);
  };
  double t = g.sigma;
  while (rate(t) > o.false_per_hour && t < 100.0 * g.sigma) t += 1e-3 * g.sigma;
  g.threshold = t;
  g.false_per_hour = rate(t);
  replay(x, gaps, t, cycle_s, o, g.confirms_at_threshold, g.open_cycles_at_threshold);
  replay(x, gaps, now, cycle_s, o, g.confirms_now, g.open_cycles_now);
  return g;
}

}  // namespace

double chi2_3_tail(double x) {
  if (x <= 0.0) return 1.0;
  return std::erfc(std::sqrt(x / 2.0)) + std::sqrt(2.0 * x / std::numbers::pi) * std::exp(-x / 2.0);
}

GateAdvice gate_rule(const std::vector<loop::CycleRecord>& cycles, const GateRuleOptions& o) {
  GateAdvice a;
  std::vector<Eigen::Vector3d> force, torque;
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
    // to be), and the model's row was not a held sensor value.
    if (r.state != loop::State::zero_g || (r.flags & loop::kContactHeld) != 0) continue;
    if (moves(r) || before_push[i]) continue;
    const Eigen::Vector3d F(r.contact[0], r.contact[1], r.contact[2]);
    const Eigen::Vector3d M(r.contact[3], r.contact[4], r.contact[5]);
    force.push_back(F);
    torque.push_back(control::torque_about(M, F, Eigen::Vector3d::Zero(), o.com_sensor_m));
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
  a.force = group(force, gaps, a.cycle_s, o, o.force_now_N);
  a.torque = group(torque, gaps, a.cycle_s, o, o.torque_now_Nm);
  a.known = true;
  return a;
}

std::string format_gate_advice(const GateAdvice& a, const GateRuleOptions& o) {
  if (!a.known) return "gate: not known: " + a.note + "\n";
  std::string out;
  char line[400];
  std::snprintf(line, sizeof line,
                "gate: %zu zero-g cycles at rest (%.4g s each), confirm %d cycles in a row, "
                "target %.3g false confirms per hour (docs/zerog-rt.md, \"Setting the contact "
                "gate\")\n",
                a.cycles, a.cycle_s, o.confirm_cycles, o.false_per_hour);
  out += line;
  const auto one = [&](const char* name, const char* unit, const GateGroup& g, double now) {
    std::snprintf(line, sizeof line,
                  "  %s: contact RMS %.3g / %.3g / %.3g %s (sigma %.3g), lag-1 correlation of "
                  "the norm %.2f; threshold %.3g %s (%.3g false confirms/h if independent; "
                  "replayed: %zu confirms), configured %.3g %s (replayed: %zu confirms, open %zu "
                  "cycles)\n",
                  name, g.rms[0], g.rms[1], g.rms[2], unit, g.sigma, g.lag1, g.threshold, unit,
                  g.false_per_hour, g.confirms_at_threshold, now, unit, g.confirms_now,
                  g.open_cycles_now);
    out += line;
  };
  one("force at the virtual centre of mass", "N", a.force, o.force_now_N);
  one("torque about it", "N*m", a.torque, o.torque_now_Nm);
  std::snprintf(line, sizeof line,
                "[limits] for zerog-rt (proto/rt_config.md):\nforce_deadband_N = %.3g\n"
                "torque_deadband_Nm = %.3g\n",
                a.force.threshold, a.torque.threshold);
  out += line;
  if (a.force.lag1 > 0.3 || a.torque.lag1 > 0.3)
    out +=
        "  note: the noise is correlated from cycle to cycle (lag-1 above 0.3): runs above a "
        "threshold are likelier than the independent figure says; the replay is the check\n";
  return out;
}

nlohmann::json to_json(const GateAdvice& a, const GateRuleOptions& o) {
  if (!a.known) return {{"known", false}, {"note", a.note}, {"cycles", a.cycles}};
  const auto g = [](const GateGroup& x) {
    return nlohmann::json{{"rms", x.rms},
                          {"sigma", x.sigma},
                          {"lag1", x.lag1},
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
