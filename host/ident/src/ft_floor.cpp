#include "zerog/ident/ft_floor.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace zerog::ident {

FtFloor ft_floor(const Dataset& data) {
  FtFloor f;
  if (data.columns.static_rows) {
    f.note =
        "a static table's rows are separate poses, not a time series: the wrench's noise cannot "
        "be told from the pose's change (record a few seconds at rest with time)";
    return f;
  }
  std::array<std::vector<double>, 6> d;
  const std::size_t n = data.size();
  for (std::size_t i = 1; i + 1 < n; ++i) {
    if (data.moving[i - 1] || data.moving[i] || data.moving[i + 1]) continue;
    const Wrench w = data.measured[i + 1] - 2.0 * data.measured[i] + data.measured[i - 1];
    for (int k = 0; k < 6; ++k) d[static_cast<std::size_t>(k)].push_back(std::abs(w[k]));
  }
  f.differences = d[0].size();
  if (f.differences < kMinFloorDifferences) {
    f.note = "only " + std::to_string(f.differences) +
             " rows at rest between two others at rest (" + std::to_string(kMinFloorDifferences) +
             " needed): record a few seconds with the robot still";
    return f;
  }
  for (std::size_t k = 0; k < 6; ++k) {
    std::vector<double>& v = d[k];
    const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
    std::nth_element(v.begin(), mid, v.end());
    f.sigma[k] = 1.4826 * *mid / std::sqrt(6.0);
  }
  f.force_rms = std::sqrt(
      (f.sigma[0] * f.sigma[0] + f.sigma[1] * f.sigma[1] + f.sigma[2] * f.sigma[2]) / 3.0);
  f.torque_rms = std::sqrt(
      (f.sigma[3] * f.sigma[3] + f.sigma[4] * f.sigma[4] + f.sigma[5] * f.sigma[5]) / 3.0);
  f.known = true;
  return f;
}

std::string format_ft_floor(const FtFloor& f, const ErrorVsFloor* e) {
  if (!f.known) return "F/T-only floor: not known: " + f.note + "\n";
  char line[400];
  std::snprintf(line, sizeof line,
                "F/T-only floor (the wrench's own white noise a row, from its second differences "
                "at rest, %zu rows; no truth needed): force %.3f N, torque %.3f N*m\n",
                f.differences, f.force_rms, f.torque_rms);
  std::string out = line;
  if (e != nullptr && f.force_rms > 0.0 && f.torque_rms > 0.0) {
    std::snprintf(line, sizeof line,
                  "  this error against it: at rest %.2fx (force) / %.2fx (torque), moving %.2fx / "
                  "%.2fx\n",
                  e->force_rest / f.force_rms, e->torque_rest / f.torque_rms,
                  e->force_moving / f.force_rms, e->torque_moving / f.torque_rms);
    out += line;
  }
  return out;
}

nlohmann::json to_json(const FtFloor& f, const ErrorVsFloor* e) {
  if (!f.known) return {{"known", false}, {"note", f.note}, {"differences", f.differences}};
  nlohmann::json j = {{"known", true},
                      {"method", "second differences at rest, 1.4826 median|d| / sqrt(6)"},
                      {"differences", f.differences},
                      {"sigma", f.sigma},
                      {"force_rms", f.force_rms},
                      {"torque_rms", f.torque_rms}};
  if (e != nullptr && f.force_rms > 0.0 && f.torque_rms > 0.0)
    j["ratio"] = {{"force_rest", e->force_rest / f.force_rms},
                  {"torque_rest", e->torque_rest / f.torque_rms},
                  {"force_moving", e->force_moving / f.force_rms},
                  {"torque_moving", e->torque_moving / f.torque_rms}};
  return j;
}

}  // namespace zerog::ident
