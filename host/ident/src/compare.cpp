#include "zerog/ident/compare.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>

#include "zerog/formats/log.hpp"
#include "zerog/io/model_file.hpp"

namespace zerog::ident {

void ErrorAccumulator::add(const Wrench& e) {
  ++n_;
  for (int k = 0; k < 6; ++k) {
    ss_[k] += e[k] * e[k];
    max_[k] = std::max(max_[k], std::abs(e[k]));
  }
}

ErrorStats ErrorAccumulator::stats() const {
  ErrorStats s;
  s.count = n_;
  if (n_ == 0) return s;
  const double n = static_cast<double>(n_);
  for (int k = 0; k < 6; ++k) {
    s.rms[k] = std::sqrt(ss_[k] / n);
    s.max_abs[k] = max_[k];
  }
  s.force_rms = std::sqrt((ss_[0] + ss_[1] + ss_[2]) / (3.0 * n));
  s.torque_rms = std::sqrt((ss_[3] + ss_[4] + ss_[5]) / (3.0 * n));
  return s;
}

std::vector<Wrench> residuals(const model::ModelParams& params, const Dataset& data) {
  std::vector<Wrench> out(data.size());
  ResidentWindow window(data);
  for (std::size_t i = 0; i < data.size(); ++i) {
    window.advance(i + 1);
    out[i] = data.measured[i] - predict(params, data, i);
  }
  return out;
}

Comparison compare(const std::vector<Wrench>& res, const Dataset& data,
                   const std::vector<std::uint8_t>* mask, int bins) {
  Comparison c;
  ErrorAccumulator all, stat, moving;
  auto use = [&](std::size_t i) { return mask == nullptr || (*mask)[i] != 0; };
  {
    ResidentWindow window(data);
    for (std::size_t i = 0; i < data.size(); ++i) {
      window.advance(i);
      if (!use(i)) continue;
      all.add(res[i]);
      (data.moving[i] ? moving : stat).add(res[i]);
    }
  }
  c.all = all.stats();
  c.stat = stat.stats();
  c.moving = moving.stats();
  // Worst segment/axis, relative to the axis' overall RMS scale (forces and torques separately).
  double worst_ratio = -1.0;
  if (data.columns.joints) {
    for (int j = 0; j < 6; ++j) {
      double lo = 1e300, hi = -1e300;
      ResidentWindow window(data);
      for (std::size_t i = 0; i < data.size(); ++i) {
        window.advance(i);
        if (!use(i)) continue;
        lo = std::min(lo, data.joints_rad[i][j]);
        hi = std::max(hi, data.joints_rad[i][j]);
      }
      if (!(hi > lo)) continue;
      JointBins jb;
      jb.joint = j;
      for (int b = 0; b <= bins; ++b) jb.edges_rad.push_back(lo + (hi - lo) * b / bins);
      std::vector<ErrorAccumulator> acc(bins);
      ResidentWindow bin_window(data);
      for (std::size_t i = 0; i < data.size(); ++i) {
        bin_window.advance(i);
        if (!use(i)) continue;
        int b = static_cast<int>((data.joints_rad[i][j] - lo) / (hi - lo) * bins);
        b = std::clamp(b, 0, bins - 1);
        acc[b].add(res[i]);
      }
      for (auto& a : acc) jb.bins.push_back(a.stats());
      for (int b = 0; b < bins; ++b) {
        const ErrorStats& s = jb.bins[b];
        if (s.count < 20) continue;
        for (int k = 0; k < 6; ++k) {
          const double scale = k < 3 ? c.all.force_rms : c.all.torque_rms;
          if (scale <= 0) continue;
          const double ratio = s.rms[k] / scale;
          if (ratio > worst_ratio) {
            worst_ratio = ratio;
            c.worst = {k, "joint bin", j, jb.edges_rad[b], jb.edges_rad[b + 1], s.rms[k]};
          }
        }
      }
      c.joints.push_back(std::move(jb));
    }
  }
  // The worse of static/moving per axis decides the segment of the worst axis.
  {
    const int k = c.worst.joint >= 0 ? c.worst.axis : 0;
    c.worst.axis = k;
    c.worst.segment = c.moving.rms[k] > c.stat.rms[k] ? "moving" : "static";
    if (c.worst.joint < 0) c.worst.rms = std::max(c.moving.rms[k], c.stat.rms[k]);
  }
  return c;
}

SegmentStats segment_stats(const std::vector<Wrench>& res, const Dataset& data,
                           const std::vector<std::uint8_t>* mask) {
  ErrorAccumulator all, stat, moving;
  ResidentWindow window(data);
  for (std::size_t i = 0; i < data.size(); ++i) {
    window.advance(i);
    if (mask != nullptr && (*mask)[i] == 0) continue;
    all.add(res[i]);
    (data.moving[i] ? moving : stat).add(res[i]);
  }
  return {all.stats(), stat.stats(), moving.stats()};
}

Floors floors(const model::ModelParams& truth, const Dataset& data, const Dataset* clean,
              const std::vector<std::uint8_t>* mask) {
  Floors f;
  f.reference_residuals = residuals(truth, data);
  f.reference = segment_stats(f.reference_residuals, data, mask);
  if (clean == nullptr) return f;
  if (clean->size() != data.size())
    throw std::runtime_error("the noise-free log has " + std::to_string(clean->size()) +
                             " rows, the log " + std::to_string(data.size()) +
                             ": they are not of the same run");
  ResidentWindow window(data), clean_window(*clean);
  for (std::size_t i = 0; i < data.size(); ++i) {
    window.advance(i);
    clean_window.advance(i);
    const double dw = (clean->measured[i] - data.measured[i]).cwiseAbs().maxCoeff();
    if (std::abs(clean->t_s[i] - data.t_s[i]) > 1e-9 * (1.0 + std::abs(data.t_s[i])) ||
        dw > 1e-9 * (1.0 + data.measured[i].cwiseAbs().maxCoeff()))
      throw std::runtime_error("the noise-free log differs from the log in row " +
                               std::to_string(i + 1) + " (t_s " + std::to_string(data.t_s[i]) +
                               "): time or wrench; they are not of the same run");
  }
  // The noisy wrench of the log against the true model on the noise-free signals; the log's own
  // motion flags (the same poses, so the same flags).
  f.sensor_residuals.resize(data.size());
  ResidentWindow sensor_window(data), sensor_clean_window(*clean);
  for (std::size_t i = 0; i < data.size(); ++i) {
    sensor_window.advance(i);
    sensor_clean_window.advance(i + 1);
    f.sensor_residuals[i] = data.measured[i] - predict(truth, *clean, i);
  }
  f.sensor = segment_stats(f.sensor_residuals, data, mask);
  return f;
}

Floors floors(const std::filesystem::path& truth_path, const Dataset& data,
              const std::vector<std::uint8_t>* mask) {
  const io::ModelFile t = io::read_model(truth_path);
  const auto it = t.extra.find("clean_signals_log");
  if (it == t.extra.end() || !it->is_string() || it->get<std::string>().empty()) {
    Floors f = floors(t.params, data, nullptr, mask);
    f.sensor_note = truth_path.string() +
                    " names no noise-free log (extra.clean_signals_log: a truth from an older "
                    "zerog sim, or not simulated)";
    return f;
  }
  const std::filesystem::path clean_path = truth_path.parent_path() / it->get<std::string>();
  const Dataset clean = read_dataset(clean_path);
  try {
    Floors f = floors(t.params, data, &clean, mask);
    f.clean_log = clean_path.string();
    return f;
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(clean_path.string() + " (named by " + truth_path.string() +
                             "): " + e.what());
  }
}

nlohmann::json to_json(const SegmentStats& s) {
  return {{"all", to_json(s.all)}, {"static", to_json(s.stat)}, {"moving", to_json(s.moving)}};
}

nlohmann::json to_json(const ErrorStats& s) {
  return {{"count", s.count},
          {"rms", s.rms},
          {"max", s.max_abs},
          {"force_rms", s.force_rms},
          {"torque_rms", s.torque_rms}};
}

nlohmann::json to_json(const Comparison& c) {
  nlohmann::json j;
  j["axes"] = kAxisNames;
  j["units"] = kAxisUnits;
  j["samples"] = {{"total", c.all.count}, {"static", c.stat.count}, {"moving", c.moving.count}};
  j["segments"] = {
      {"all", to_json(c.all)}, {"static", to_json(c.stat)}, {"moving", to_json(c.moving)}};
  j["joint_bins"] = nlohmann::json::array();
  for (const auto& jb : c.joints) {
    nlohmann::json b;
    b["joint"] = "A" + std::to_string(jb.joint + 1);
    b["edges_rad"] = jb.edges_rad;
    b["count"] = nlohmann::json::array();
    b["rms"] = nlohmann::json::array();
    for (const auto& s : jb.bins) {
      b["count"].push_back(s.count);
      b["rms"].push_back(s.rms);
    }
    j["joint_bins"].push_back(b);
  }
  nlohmann::json w;
  w["axis"] = kAxisNames[c.worst.axis];
  w["segment"] = c.worst.segment;
  w["rms"] = c.worst.rms;
  if (c.worst.joint >= 0) {
    w["joint"] = "A" + std::to_string(c.worst.joint + 1);
    w["bin_rad"] = {c.worst.lo, c.worst.hi};
  } else {
    w["joint"] = nullptr;
    w["bin_rad"] = nullptr;
  }
  j["worst"] = w;
  return j;
}

std::string format_comparison(const Comparison& c, const Floors* floors) {
  std::ostringstream os;
  char line[256];
  const bool sensor = floors != nullptr && floors->sensor.has_value();
  std::snprintf(line, sizeof line, "%-8s %8s | %9s %9s | %9s %9s | %9s %9s%s%s\n", "axis", "unit",
                "all rms", "max", "static", "max", "moving", "max", floors ? " | reference" : "",
                sensor ? " |    sensor" : "");
  os << line;
  for (int k = 0; k < 6; ++k) {
    std::snprintf(line, sizeof line, "%-8s %8s | %9.3f %9.3f | %9.3f %9.3f | %9.3f %9.3f",
                  kAxisNames[k], kAxisUnits[k], c.all.rms[k], c.all.max_abs[k], c.stat.rms[k],
                  c.stat.max_abs[k], c.moving.rms[k], c.moving.max_abs[k]);
    os << line;
    if (floors) {
      std::snprintf(line, sizeof line, " | %9.3f", floors->reference.all.rms[k]);
      os << line;
    }
    if (sensor) {
      std::snprintf(line, sizeof line, " | %9.3f", floors->sensor->all.rms[k]);
      os << line;
    }
    os << "\n";
  }
  std::snprintf(line, sizeof line,
                "force RMS %.3f N (static %.3f, moving %.3f); torque RMS %.3f N*m (static %.3f, "
                "moving %.3f)\n",
                c.all.force_rms, c.stat.force_rms, c.moving.force_rms, c.all.torque_rms,
                c.stat.torque_rms, c.moving.torque_rms);
  os << line;
  if (floors) os << format_floors(*floors);
  if (c.worst.joint >= 0) {
    std::snprintf(
        line, sizeof line,
        "worst: %s at A%d in [%.1f, %.1f] deg: RMS %.3f %s (%s segments are worse on this axis)\n",
        kAxisNames[c.worst.axis], c.worst.joint + 1, c.worst.lo * 180 / M_PI,
        c.worst.hi * 180 / M_PI, c.worst.rms, kAxisUnits[c.worst.axis], c.worst.segment.c_str());
    os << line;
  }
  return os.str();
}

std::string format_floors(const Floors& f, const std::string& scope) {
  const std::string in = scope.empty() ? "" : " (" + scope + ")";
  auto numbers = [](const SegmentStats& s) {
    char line[256];
    std::snprintf(line, sizeof line,
                  "force %.3f N (static %.3f, moving %.3f), torque %.3f N*m (static %.3f, moving "
                  "%.3f)",
                  s.all.force_rms, s.stat.force_rms, s.moving.force_rms, s.all.torque_rms,
                  s.stat.torque_rms, s.moving.torque_rms);
    return std::string(line);
  };
  std::string out = "true-model reference" + in + ": " + numbers(f.reference) +
                    "\n  (true model, true parameters, the same noisy signals)\n";
  if (f.sensor) {
    out += "sensor floor" + in + ": " + numbers(*f.sensor) +
           "\n  (true model on noise-free signals against the noisy wrench: F/T noise and "
           "quantisation)\n";
  } else {
    out += "sensor floor: not known: " + f.sensor_note + "\n";
  }
  return out;
}

}  // namespace zerog::ident
