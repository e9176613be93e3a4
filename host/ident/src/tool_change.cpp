// fit_tool_change (fit.hpp): a new tool's gravity (mass, centre of mass) from the static poses of
// a log, every other effect kept at the base model's values; warnings where the poses cannot
// tell it.
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "zerog/ident/fit.hpp"

namespace zerog::ident {

using model::Effect;

std::vector<std::uint8_t> static_mask(const Dataset& data) {
  std::vector<std::uint8_t> mask(data.size(), 0);
  ResidentWindow window(data);
  for (std::size_t i = 0; i < data.size(); ++i) {
    window.advance(i);
    mask[i] = data.moving[i] ? 0 : 1;
  }
  return mask;
}

ToolChangeResult fit_tool_change(const Dataset& data, const model::ModelParams& base,
                                 const ToolChangeOptions& opt) {
  if (!base.effects.has(Effect::gravity))
    throw std::runtime_error("the base model has no 'gravity' effect to re-identify");
  ToolChangeResult out;
  out.frozen = base.effects;
  out.frozen.remove(Effect::gravity);
  const std::vector<std::uint8_t> mask = static_mask(data);
  // Static samples, dwells (runs long enough for one block) and the spread of gravity in S.
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  std::size_t run = 0;
  ResidentWindow window(data);
  for (std::size_t i = 0; i <= data.size(); ++i) {
    window.advance(i);
    if (i < data.size() && mask[i]) {
      ++run;
      ++out.static_samples;
      const Eigen::Vector3d u = data.pose(i).R_base_sensor.transpose() * Eigen::Vector3d(0, 0, -1);
      scatter += u * u.transpose();
      continue;
    }
    // Every static row (no time) is a pose of its own.
    if (data.columns.static_rows)
      out.dwells += run;
    else if (run >= static_cast<std::size_t>(std::max(1, opt.block_samples)))
      ++out.dwells;
    run = 0;
  }
  if (out.static_samples == 0)
    throw std::runtime_error(
        "the log has no static samples (dwells): a tool change is fitted on "
        "static poses only");
  scatter /= static_cast<double>(out.static_samples);
  const double lmax = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvalues()[2];
  out.spread_deg =
      std::asin(std::sqrt(std::clamp(1.0 - lmax, 0.0, 1.0))) * 180.0 / std::numbers::pi;

  FitOptions fo;
  fo.effects = base.effects;
  fo.frozen = out.frozen;
  fo.initial = &base;
  fo.mask = &mask;
  fo.block_samples = opt.block_samples;
  fo.max_iterations = opt.max_iterations;
  fo.threads = opt.threads;
  fo.loss = opt.loss;
  fo.loss_scale = opt.loss_scale;
  fo.engine = opt.engine;
  fo.errors_in_variables = opt.errors_in_variables;
  fo.progress = opt.progress;
  out.fit = fit(data, fo);

  auto& warnings = out.fit.warnings;
  std::ostringstream os;
  os.precision(3);
  if (out.spread_deg < opt.min_spread_deg) {
    os << "the " << out.dwells << " static poses hold gravity within " << std::fixed
       << std::setprecision(1) << out.spread_deg
       << " deg of one direction in the sensor frame: the centre of mass along that direction "
          "cannot be told (use attitudes that tilt the sensor differently, e.g. "
          "calib/poses/001_appendix_c_attitudes.csv)";
    warnings.push_back({"poses_alike", os.str()});
  }
  if (out.fit.usable && out.fit.std) {
    const double* g = out.fit.params.block(Effect::gravity);
    const auto& sd = (*out.fit.std)[model::index(Effect::gravity)];
    std::string who;
    if (!(sd[0] <= opt.max_rel_std_mass * std::abs(g[0]))) who = param_label(Effect::gravity, 0);
    for (int k = 1; k < 4; ++k)
      if (!(sd[k] <= opt.max_std_com_m))
        who += (who.empty() ? "" : ", ") + param_label(Effect::gravity, k);
    if (!who.empty()) {
      os.str("");
      os << std::defaultfloat << std::setprecision(3);
      os << "the static poses identify " << who << " poorly (std above "
         << 100.0 * opt.max_rel_std_mass << " % of the mass or " << 1000.0 * opt.max_std_com_m
         << " mm, or not at all): add attitudes that tilt the sensor differently";
      warnings.push_back({"poorly_identified", os.str()});
    }
  }
  if (base.effects.has(Effect::rotational_inertia)) {
    warnings.push_back({"kept_inertia",
                        "rotational_inertia keeps the base model's values (the old tool's): "
                        "static poses cannot identify it; fit a moving run to update it"});
  }
  return out;
}

}  // namespace zerog::ident
