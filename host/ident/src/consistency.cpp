// check_consistency (fit.hpp): does the fit's answer hold up when the log is halved, or the
// weights are plain? Two more fits from the full fit's values, compared with its uncertainty.
#include <cmath>
#include <exception>
#include <limits>
#include <sstream>
#include <vector>

#include "zerog/ident/fit.hpp"

namespace zerog::ident {

using model::Effect;

Consistency check_consistency(const Dataset& data, const FitOptions& o, const FitResult& full) {
  Consistency c;
  const std::size_t n = data.size();
  std::vector<std::size_t> used;
  for (std::size_t i = 0; i < n; ++i)
    if (o.mask == nullptr || (*o.mask)[i] != 0) used.push_back(i);
  // Free parameters of the full fit, by name.
  struct Param {
    Effect e;
    int k;
  };
  std::vector<Param> params;
  for (Effect e : model::kAllEffects)
    if (full.params.effects.has(e) && !(o.frozen.has(e)))
      for (int k = 0; k < model::info(e).num_params; ++k) params.push_back({e, k});
  auto half = [&](std::size_t a, std::size_t b, Consistency::Half& h) {
    h.first_row = used[a];
    h.last_row = used[b - 1];
    std::vector<std::uint8_t> mask(n, 0);
    for (std::size_t q = a; q < b; ++q) mask[used[q]] = 1;
    FitOptions ho = o;
    ho.mask = &mask;
    ho.initial = &full.params;
    ho.progress = nullptr;
    try {
      const FitResult r = fit(data, ho);
      h.usable = r.usable;
      h.params = r.params;
      h.std = r.std;
      if (!r.usable) h.note = "the fit of this half is not usable (" + r.termination + ")";
      for (const Warning& w : r.warnings)
        if (w.kind == "rank_deficient") h.note += (h.note.empty() ? "" : "; ") + w.message;
    } catch (const std::exception& e) {
      h.note = e.what();
    }
  };
  if (used.size() >= 4) {
    half(0, used.size() / 2, c.first);
    half(used.size() / 2, used.size(), c.second);
  } else {
    c.first.note = c.second.note = "too few rows to split";
  }
  c.max_half_z = std::numeric_limits<double>::quiet_NaN();
  if (c.first.usable && c.second.usable && c.first.std && c.second.std) {
    for (const Param& q : params) {
      const double s1 = (*c.first.std)[model::index(q.e)][q.k];
      const double s2 = (*c.second.std)[model::index(q.e)][q.k];
      if (!std::isfinite(s1) || !std::isfinite(s2) || s1 + s2 <= 0.0) continue;
      const double z = std::abs(c.first.params.block(q.e)[q.k] - c.second.params.block(q.e)[q.k]) /
                       std::hypot(s1, s2);
      if (!(z <= c.max_half_z)) {  // NaN at the start
        c.max_half_z = z;
        c.max_half_param = param_label(q.e, q.k);
      }
    }
  }
  if (std::isfinite(c.max_half_z) && c.max_half_z > 3.0) {
    std::ostringstream os;
    os.precision(4);
    os << "the answer depends on which half of the data is used: " << c.max_half_param
       << " differs by " << c.max_half_z
       << " standard deviations between the halves; something changed between them (the "
          "sensor's bias drifted, a missing effect, an event) that the printed +- do not cover";
    c.warnings.push_back({"split_half", os.str()});
  }
  // Plain weights instead of the per-axis noise estimate.
  FitOptions wo = o;
  wo.sigma = std::array<double, 6>{1, 1, 1, 0.1, 0.1, 0.1};
  wo.initial = &full.params;
  wo.progress = nullptr;
  wo.covariance = false;
  try {
    const FitResult r = fit(data, wo);
    c.weighting_usable = r.usable;
    c.unweighted = r.params;
  } catch (const std::exception&) {
    c.weighting_usable = false;
  }
  if (c.weighting_usable && full.std) {
    for (const Param& q : params) {
      const double sd = (*full.std)[model::index(q.e)][q.k];
      if (!std::isfinite(sd) || sd <= 0.0) continue;
      const double z = std::abs(c.unweighted.block(q.e)[q.k] - full.params.block(q.e)[q.k]) / sd;
      if (z > c.max_weight_shift) {
        c.max_weight_shift = z;
        c.max_weight_param = param_label(q.e, q.k);
      }
    }
    if (c.max_weight_shift > 3.0) {
      std::ostringstream os;
      os.precision(4);
      os << "the answer depends on the weighting: with plain weights (1 N, 0.1 N*m) "
         << c.max_weight_param << " moves by " << c.max_weight_shift
         << " standard deviations; the model misses something that the weights trade off";
      c.warnings.push_back({"weighting", os.str()});
    }
  }
  return c;
}

}  // namespace zerog::ident
