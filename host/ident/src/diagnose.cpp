#include "zerog/ident/diagnose.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "zerog/io/model_file.hpp"

namespace zerog::ident {
namespace {

using model::Effect;

std::vector<std::uint8_t> invert(const std::vector<std::uint8_t>& m) {
  std::vector<std::uint8_t> out(m.size());
  for (std::size_t i = 0; i < m.size(); ++i) out[i] = m[i] ? 0 : 1;
  return out;
}

HeldOut heldout_error(const std::vector<Wrench>& res, const std::vector<std::uint8_t>& mask,
                      const std::array<double, 6>& sigma) {
  ErrorAccumulator acc;
  double ws = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < res.size(); ++i) {
    if (!mask[i]) continue;
    acc.add(res[i]);
    for (int k = 0; k < 6; ++k) ws += (res[i][k] / sigma[k]) * (res[i][k] / sigma[k]);
    ++n;
  }
  HeldOut h;
  h.stats = acc.stats();
  h.whitened_mse = n ? ws / (6.0 * static_cast<double>(n)) : 0.0;
  return h;
}

std::array<double, 6> noise_estimate(const std::vector<Wrench>& res,
                                     const std::vector<std::uint8_t>& mask) {
  constexpr std::size_t kLag = 5;
  std::array<double, 6> dd{};
  std::size_t nd = 0;
  for (std::size_t i = kLag; i < res.size(); ++i) {
    if (!mask[i] || !mask[i - kLag]) continue;
    const Wrench diff = res[i] - res[i - kLag];
    for (int k = 0; k < 6; ++k) dd[k] += diff[k] * diff[k];
    ++nd;
  }
  std::array<double, 6> out{};
  for (int k = 0; k < 6; ++k)
    out[k] = std::max(std::sqrt(dd[k] / (2.0 * static_cast<double>(std::max<std::size_t>(nd, 1)))),
                      1e-9);
  return out;
}

struct Split {
  std::vector<std::uint8_t> heldout, train;
};

Split make_split(const Dataset& data, const DiagnoseOptions& o) {
  Split s;
  s.heldout = heldout_mask(data, o.block_s, o.every, o.heldout_offset);
  s.train = invert(s.heldout);
  if (o.exclude) {
    for (std::size_t i = 0; i < data.size(); ++i) {
      if ((*o.exclude)[i]) s.heldout[i] = 0, s.train[i] = 0;
    }
  }
  const std::size_t nh = std::count(s.heldout.begin(), s.heldout.end(), 1);
  const std::size_t nt = std::count(s.train.begin(), s.train.end(), 1);
  if (nh < 100 || nt < 100)
    throw std::runtime_error("log too short for a time-blocked held-out split (" +
                             std::to_string(data.size()) + " samples, blocks of " +
                             std::to_string(o.block_s) + " s): record longer or use --block");
  return s;
}

struct Baseline {
  FitResult fit;
  std::vector<Wrench> res;
  HeldOut heldout;
};

Baseline fit_baseline(const Dataset& data, const model::EffectSet& effects, const Split& split,
                      const DiagnoseOptions& o, const model::ModelParams* initial) {
  FitOptions fo = o.fit;
  fo.effects = effects;
  fo.mask = &split.train;
  fo.covariance = false;
  fo.initial = initial;
  fo.progress = nullptr;
  Baseline b;
  b.fit = fit(data, fo);
  if (!b.fit.usable)
    throw std::runtime_error("the fit of the model " + io::effect_list_string(effects) +
                             " is not usable: " + b.fit.termination);
  b.res = residuals(b.fit.params, data);
  b.heldout = heldout_error(b.res, split.heldout, b.fit.residual_rms);
  return b;
}

// Two held-out gains are indistinguishable if they differ by less than half a percentage point
// or 2 % of the larger.
bool gains_tie(double a, double b) {
  return std::abs(a - b) < std::max(0.005, 0.02 * std::max(a, b));
}

std::vector<Candidate> evaluate_candidates(const Dataset& data, const Baseline& base,
                                           const Split& split, const DiagnoseOptions& o,
                                           const std::array<double, 6>& scale) {
  std::vector<Candidate> out;
  const auto effects = candidate_effects(base.fit.params.effects, data);
  int k = 0;
  for (Effect e : effects) {
    ++k;
    if (o.progress)
      o.progress("  candidate " + std::to_string(k) + "/" + std::to_string(effects.size()) + ": " +
                 model::info(e).name);
    Candidate c;
    c.effect = e;
    c.effects = base.fit.params.effects;
    c.effects.add(e);
    FitOptions fo = o.fit;
    fo.effects = c.effects;
    fo.mask = &split.train;
    fo.covariance = false;
    fo.initial = &base.fit.params;
    fo.sigma = base.fit.sigma;
    fo.progress = nullptr;
    c.fit = fit(data, fo);
    if (!c.fit.usable) continue;
    const auto res = residuals(c.fit.params, data);
    c.heldout = heldout_error(res, split.heldout, scale);
    c.gain = 1.0 - c.heldout.whitened_mse / base.heldout.whitened_mse;
    for (int a = 0; a < 6; ++a) {
      const double b2 = base.heldout.stats.rms[a] * base.heldout.stats.rms[a];
      const double c2 = c.heldout.stats.rms[a] * c.heldout.stats.rms[a];
      c.axis_gain[a] = b2 > 0 ? 1.0 - c2 / b2 : 0.0;
    }
    c.delta_bic = c.fit.bic - base.fit.bic;
    out.push_back(std::move(c));
  }
  std::sort(out.begin(), out.end(),
            [](const Candidate& a, const Candidate& b) { return a.gain > b.gain; });
  // Candidates that remove the same error (a general effect can mimic a specific one, e.g.
  // crosstalk can represent a sensor rotation) are tied; among tied ones the information
  // criterion decides, so the simpler explanation comes first.
  for (std::size_t g = 0; g < out.size();) {
    std::size_t end = g + 1;
    while (end < out.size() && gains_tie(out[g].gain, out[end].gain)) ++end;
    std::sort(out.begin() + static_cast<std::ptrdiff_t>(g),
              out.begin() + static_cast<std::ptrdiff_t>(end),
              [](const Candidate& a, const Candidate& b) { return a.delta_bic < b.delta_bic; });
    g = end;
  }
  return out;
}

// Candidate signals for residual correlation, in plain words.
struct Feature {
  std::string name;
  std::vector<double> v;
};

std::vector<Feature> features(const Dataset& data) {
  std::vector<Feature> f;
  const std::size_t n = data.size();
  auto add = [&](std::string name, auto fn) {
    Feature x{std::move(name), std::vector<double>(n)};
    for (std::size_t i = 0; i < n; ++i) x.v[i] = fn(i);
    f.push_back(std::move(x));
  };
  add("time since start", [&](std::size_t i) { return data.pose[i].t_rel_s; });
  if (data.columns.temperature)
    add("sensor temperature", [&](std::size_t i) { return data.pose[i].temperature_C; });
  if (data.columns.joints) {
    for (int j = 0; j < 6; ++j) {
      const std::string a = "joint A" + std::to_string(j + 1);
      add(a + " angle (sine)",
          [&, j](std::size_t i) { return std::sin(data.pose[i].joints_rad[j]); });
      add(a + " angle (cosine)",
          [&, j](std::size_t i) { return std::cos(data.pose[i].joints_rad[j]); });
      add(a + " velocity", [&, j](std::size_t i) { return data.joint_vel_radps[i][j]; });
      add(a + " velocity direction (sign)", [&, j](std::size_t i) {
        const double v = data.joint_vel_radps[i][j];
        return std::abs(v) < 1e-3 ? 0.0 : (v > 0 ? 1.0 : -1.0);
      });
    }
  }
  if (data.columns.imu) {
    const char* ax = "xyz";
    for (int k = 0; k < 3; ++k) {
      add(std::string("angular rate about IMU ") + ax[k],
          [&, k](std::size_t i) { return data.imu[i * 9 + 3 + k]; });
      add(std::string("angular acceleration about IMU ") + ax[k],
          [&, k](std::size_t i) { return data.imu[i * 9 + 6 + k]; });
      add(std::string("specific force along IMU ") + ax[k],
          [&, k](std::size_t i) { return data.imu[i * 9 + k]; });
    }
    add("squared angular rate", [&](std::size_t i) {
      return Eigen::Map<const Eigen::Vector3d>(&data.imu[i * 9 + 3]).squaredNorm();
    });
  }
  for (int k = 0; k < 3; ++k) {
    const char* ax = "xyz";
    add(std::string("gravity direction along sensor ") + ax[k], [&, k](std::size_t i) {
      return (data.pose[i].R_base_sensor.transpose() * Eigen::Vector3d(0, 0, -1))[k];
    });
  }
  return f;
}

std::vector<SignalCorrelation> correlate(const Dataset& data, const std::vector<Wrench>& res,
                                         const std::vector<std::uint8_t>& mask) {
  std::vector<SignalCorrelation> out;
  for (const Feature& f : features(data)) {
    for (int a = 0; a < 6; ++a) {
      double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0;
      double n = 0;
      for (std::size_t i = 0; i < data.size(); ++i) {
        if (!mask[i]) continue;
        const double x = f.v[i], y = res[i][a];
        sx += x, sy += y, sxx += x * x, syy += y * y, sxy += x * y, n += 1;
      }
      const double vx = sxx - sx * sx / n, vy = syy - sy * sy / n;
      if (vx <= 1e-12 * n || vy <= 0) continue;
      out.push_back({f.name, a, (sxy - sx * sy / n) / std::sqrt(vx * vy)});
    }
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    return std::abs(a.correlation) > std::abs(b.correlation);
  });
  if (out.size() > 8) out.resize(8);
  return out;
}

std::string fmt(const char* f, double a) {
  char b[64];
  std::snprintf(b, sizeof b, f, a);
  return b;
}

std::string param_summary(const Candidate& c) {
  const auto& ei = model::info(c.effect);
  std::string s;
  const double* v = c.fit.params.block(c.effect);
  // The largest few parameters (by magnitude) in their units.
  std::vector<int> idx(ei.num_params);
  for (int i = 0; i < ei.num_params; ++i) idx[i] = i;
  std::sort(idx.begin(), idx.end(), [&](int a, int b) { return std::abs(v[a]) > std::abs(v[b]); });
  for (int q = 0; q < std::min(ei.num_params, 6); ++q) {
    const int i = idx[q];
    s += (s.empty() ? "" : ", ") + std::string(ei.params[i].name) + " = " + fmt("%.4g", v[i]) +
         " " + ei.params[i].unit;
  }
  if (ei.num_params > 6) s += ", … (" + std::to_string(ei.num_params) + " parameters)";
  return s;
}

}  // namespace

std::vector<Effect> candidate_effects(const model::EffectSet& m, const Dataset& data) {
  std::vector<Effect> out;
  for (Effect e : model::kAllEffects) {
    if (m.has(e)) continue;
    model::EffectSet with = m;
    with.add(e);
    try {
      check_signals(with, data);
    } catch (const std::runtime_error&) {
      continue;  // needs a signal the log lacks, or an effect the model lacks
    }
    out.push_back(e);
  }
  return out;
}

Diagnosis diagnose(const Dataset& data, const DiagnoseOptions& o) {
  Diagnosis d;
  d.model = o.fit.effects;
  const Split split = make_split(data, o);
  if (o.progress)
    o.progress("diagnose: fitting " + io::effect_list_string(d.model) + " on the training blocks");
  Baseline base = fit_baseline(data, d.model, split, o, o.fit.initial);
  d.baseline = base.fit;
  d.baseline_heldout = base.heldout;

  // White noise per axis from differences of held-out residuals 5 rows apart: structure is
  // smooth over 60 ms, and the 5-point gyro difference makes the noise correlated over 4 rows
  // (lag 1: −0.12, lag 2: −0.49), so shorter lags would misjudge it. var(r[i] − r[i−5]) = 2σ².
  d.noise_rms = noise_estimate(base.res, split.heldout);
  // Everything below in noise-whitened units, so each axis counts by its signal-to-noise.
  base.heldout = heldout_error(base.res, split.heldout, d.noise_rms);
  d.baseline_heldout = base.heldout;
  double total = 0.0, structure = 0.0;
  for (int k = 0; k < 6; ++k) {
    const double ratio = std::pow(base.heldout.stats.rms[k] / d.noise_rms[k], 2);
    total += ratio;
    structure += std::max(0.0, ratio - 1.0);
  }
  d.structured_fraction = structure / total;

  if (o.progress) o.progress("diagnose: trying each candidate effect");
  d.candidates = evaluate_candidates(data, base, split, o, d.noise_rms);
  d.correlated = correlate(data, base.res, split.heldout);

  const auto& h = base.heldout.stats;
  std::ostringstream os;
  const double explained = d.candidates.empty() || d.structured_fraction <= 0
                               ? 0.0
                               : d.candidates[0].gain / d.structured_fraction;
  if (d.structured_fraction < 0.05 && (d.candidates.empty() || d.candidates[0].gain < 0.02)) {
    d.verdict = Diagnosis::Verdict::nothing_left;
    os << "The residual is at the noise level (held-out force RMS " << fmt("%.3f", h.force_rms)
       << " N, torque RMS " << fmt("%.3f", h.torque_rms) << " N*m; "
       << fmt("%.0f", 100 * d.structured_fraction)
       << "% of it is structured): nothing is missing that the library could add.";
  } else if (!d.candidates.empty() && d.candidates[0].gain > 0.02 && explained >= 0.5) {
    const Candidate& c = d.candidates[0];
    d.verdict = Diagnosis::Verdict::effect;
    const auto& ei = model::info(c.effect);
    const auto& ch = c.heldout.stats;
    os << "Missing effect: " << ei.name << " (" << ei.summary << "). Adding it removes "
       << fmt("%.0f", 100 * c.gain) << "% of the held-out error (force RMS "
       << fmt("%.3f", h.force_rms) << " -> " << fmt("%.3f", ch.force_rms) << " N, torque RMS "
       << fmt("%.3f", h.torque_rms) << " -> " << fmt("%.3f", ch.torque_rms) << " N*m)";
    if (d.candidates.size() > 1 && gains_tie(c.gain, d.candidates[1].gain)) {
      const Candidate& alt = d.candidates[1];
      os << "; " << model::info(alt.effect).name << " removes as much ("
         << fmt("%.0f", 100 * alt.gain) << "%) because it can mimic it, but with "
         << model::info(alt.effect).num_params << " parameters against " << ei.num_params
         << ": the information criterion prefers " << ei.name;
    } else if (d.candidates.size() > 1) {
      os << "; the next best, " << model::info(d.candidates[1].effect).name << ", removes "
         << fmt("%.0f", 100 * d.candidates[1].gain) << "%";
    }
    os << ". Estimated: " << param_summary(c) << ".";
    d.command = "zerog fit " + o.log_path + " --effects " + io::effect_list_string(c.effects) +
                " --out fitted.json";
  } else {
    d.verdict = Diagnosis::Verdict::none;
    os << "No library effect explains the remaining structure: "
       << fmt("%.0f", 100 * d.structured_fraction) << "% of the held-out error is structured, ";
    if (!d.candidates.empty())
      os << "but the best candidate, " << model::info(d.candidates[0].effect).name
         << ", removes only " << fmt("%.0f", 100 * std::max(0.0, d.candidates[0].gain)) << "% ("
         << fmt("%.0f", 100 * std::max(0.0, explained)) << "% of the structure). ";
    else
      os << "and no candidate is left to try. ";
    if (!d.correlated.empty()) {
      os << "The residual correlates with: ";
      for (std::size_t q = 0; q < std::min<std::size_t>(3, d.correlated.size()); ++q) {
        const auto& s = d.correlated[q];
        os << (q ? "; " : "") << s.signal << " on " << kAxisNames[s.axis]
           << " (rho = " << fmt("%.2f", s.correlation) << ")";
      }
      os << ". Look for a physical cause tied to " << d.correlated[0].signal << ".";
    }
  }
  d.text = os.str();
  return d;
}

std::vector<LadderStep> ladder(const Dataset& data, const LadderOptions& o) {
  std::vector<LadderStep> steps;
  const Split split = make_split(data, o.diagnose);
  model::EffectSet effects =
      o.diagnose.fit.effects.size() ? o.diagnose.fit.effects : model::kMinimalModel;
  if (o.diagnose.progress)
    o.diagnose.progress("ladder: step 0, " + io::effect_list_string(effects));
  Baseline base = fit_baseline(data, effects, split, o.diagnose, nullptr);
  steps.push_back({effects, std::nullopt, base.heldout, base.fit.bic, 0.0});
  for (int s = 0; s < o.max_steps; ++s) {
    // Gains are measured against the noise of this step's residuals.
    const auto scale = noise_estimate(base.res, split.heldout);
    base.heldout = heldout_error(base.res, split.heldout, scale);
    const auto cands = evaluate_candidates(data, base, split, o.diagnose, scale);
    if (cands.empty()) break;
    const Candidate& best = cands[0];
    if (best.gain < o.min_gain || best.delta_bic >= 0) break;
    effects = best.effects;
    if (o.diagnose.progress)
      o.diagnose.progress("ladder: step " + std::to_string(s + 1) + ", adds " +
                          model::info(best.effect).name);
    // Refit so the next step's whitening matches the new model.
    base = fit_baseline(data, effects, split, o.diagnose, &best.fit.params);
    steps.push_back({effects, best.effect, base.heldout, base.fit.bic, best.gain});
  }
  return steps;
}

namespace {
nlohmann::json heldout_json(const HeldOut& h) {
  return {{"force_rms", h.stats.force_rms},
          {"torque_rms", h.stats.torque_rms},
          {"rms", h.stats.rms},
          {"max", h.stats.max_abs},
          {"count", h.stats.count}};
}
nlohmann::json names(const model::EffectSet& s) {
  nlohmann::json a = nlohmann::json::array();
  for (Effect e : model::kAllEffects)
    if (s.has(e)) a.push_back(model::info(e).name);
  return a;
}
}  // namespace

nlohmann::json to_json(const Diagnosis& d) {
  nlohmann::json j;
  j["kind"] = "zerog-diagnosis";
  j["version"] = 1;
  j["model"] = names(d.model);
  j["baseline"] = heldout_json(d.baseline_heldout);
  j["noise_rms"] = d.noise_rms;
  j["structured_fraction"] = d.structured_fraction;
  j["candidates"] = nlohmann::json::array();
  for (const auto& c : d.candidates) {
    nlohmann::json cj;
    cj["effect"] = model::info(c.effect).name;
    cj["heldout"] = heldout_json(c.heldout);
    cj["gain"] = c.gain;
    cj["axis_gain"] = c.axis_gain;
    cj["delta_bic"] = c.delta_bic;
    nlohmann::json p = nlohmann::json::object();
    const auto& ei = model::info(c.effect);
    for (int i = 0; i < ei.num_params; ++i) p[ei.params[i].name] = c.fit.params.block(c.effect)[i];
    cj["params"] = p;
    j["candidates"].push_back(cj);
  }
  const char* kinds[] = {"effect", "none", "nothing_left"};
  j["verdict"] = {
      {"kind", kinds[static_cast<int>(d.verdict)]},
      {"effect", d.verdict == Diagnosis::Verdict::effect
                     ? nlohmann::json(model::info(d.candidates[0].effect).name)
                     : nlohmann::json(nullptr)},
      {"text", d.text},
      {"command", d.command.empty() ? nlohmann::json(nullptr) : nlohmann::json(d.command)}};
  j["correlated_signals"] = nlohmann::json::array();
  for (const auto& s : d.correlated)
    j["correlated_signals"].push_back(
        {{"signal", s.signal}, {"axis", kAxisNames[s.axis]}, {"correlation", s.correlation}});
  return j;
}

nlohmann::json to_json(const std::vector<LadderStep>& steps) {
  nlohmann::json j;
  j["kind"] = "zerog-ladder";
  j["version"] = 1;
  j["steps"] = nlohmann::json::array();
  for (const auto& s : steps) {
    j["steps"].push_back(
        {{"effects", names(s.effects)},
         {"added", s.added ? nlohmann::json(model::info(*s.added).name) : nlohmann::json(nullptr)},
         {"heldout", heldout_json(s.heldout)},
         {"bic", s.bic},
         {"gain", s.gain}});
  }
  return j;
}

std::string format_diagnosis(const Diagnosis& d) {
  std::ostringstream os;
  os << "model: " << io::effect_list_string(d.model) << "\n";
  os << "held-out error: force RMS " << fmt("%.3f", d.baseline_heldout.stats.force_rms)
     << " N, torque RMS " << fmt("%.3f", d.baseline_heldout.stats.torque_rms)
     << " N*m; white-noise estimate force "
     << fmt("%.3f", std::sqrt((d.noise_rms[0] * d.noise_rms[0] + d.noise_rms[1] * d.noise_rms[1] +
                               d.noise_rms[2] * d.noise_rms[2]) /
                              3))
     << " N, torque "
     << fmt("%.3f", std::sqrt((d.noise_rms[3] * d.noise_rms[3] + d.noise_rms[4] * d.noise_rms[4] +
                               d.noise_rms[5] * d.noise_rms[5]) /
                              3))
     << " N*m (" << fmt("%.0f", 100 * d.structured_fraction) << "% structured)\n\n";
  char line[200];
  std::snprintf(line, sizeof line, "%-4s %-20s %8s %11s %12s %10s  %s\n", "rank", "effect", "gain",
                "force rms", "torque rms", "dBIC", "per-axis gain Fx Fy Fz Mx My Mz");
  os << line;
  int r = 0;
  for (const auto& c : d.candidates) {
    std::snprintf(line, sizeof line, "%-4d %-20s %7.1f%% %9.3f N %8.3f N*m %10.0f ", ++r,
                  model::info(c.effect).name, 100 * c.gain, c.heldout.stats.force_rms,
                  c.heldout.stats.torque_rms, c.delta_bic);
    os << line;
    for (double g : c.axis_gain) os << fmt(" %4.0f%%", 100 * g);
    os << "\n";
  }
  if (!d.correlated.empty()) {
    os << "\nresidual correlates with (held-out):\n";
    for (const auto& s : d.correlated)
      os << "  " << fmt("%+.2f", s.correlation) << "  " << kAxisNames[s.axis] << " ~ " << s.signal
         << "\n";
  }
  os << "\n" << d.text << "\n";
  if (!d.command.empty()) os << "add it:  " << d.command << "\n";
  return os.str();
}

std::string format_ladder(const std::vector<LadderStep>& steps) {
  std::ostringstream os;
  char line[200];
  std::snprintf(line, sizeof line, "%-4s %-20s %12s %14s %8s\n", "step", "added", "force rms",
                "torque rms", "gain");
  os << line;
  int k = 0;
  for (const auto& s : steps) {
    std::snprintf(line, sizeof line, "%-4d %-20s %10.3f N %10.3f N*m %7.1f%%\n", k++,
                  s.added ? model::info(*s.added).name : "(start)", s.heldout.stats.force_rms,
                  s.heldout.stats.torque_rms, 100 * s.gain);
    os << line;
  }
  os << "final model: " << io::effect_list_string(steps.back().effects) << "\n";
  return os.str();
}

}  // namespace zerog::ident
