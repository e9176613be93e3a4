// diagnose() of a static table (rows without time): cross-validation over the rows, outlier
// poses, a drift over the row order (docs/insight-loop.md, "Small tables").
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "zerog/ident/diagnose.hpp"
#include "zerog/io/effect_file.hpp"
#include "zerog/io/model_file.hpp"

namespace zerog::ident {
namespace {

using Vec6 = std::array<double, 6>;

std::string fmt(const char* f, double x) {
  char b[64];
  std::snprintf(b, sizeof b, f, x);
  return b;
}

double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

// The rows' cross-validated residuals: each fold (rows j with j % k == f, j counting the kept
// rows) predicted by the model fitted on the others. False when a fold's fit is not usable.
bool cv_residuals(const Dataset& data, FitOptions fo, const std::vector<std::size_t>& rows,
                  std::size_t k, std::vector<Wrench>& out) {
  out.assign(data.size(), Wrench::Zero());
  std::vector<std::uint8_t> mask(data.size(), 0);
  fo.covariance = false;
  fo.progress = nullptr;
  fo.mask = &mask;
  for (std::size_t f = 0; f < k; ++f) {
    std::fill(mask.begin(), mask.end(), 0);
    for (std::size_t j = 0; j < rows.size(); ++j)
      if (j % k != f) mask[rows[j]] = 1;
    const FitResult r = fit(data, fo);
    if (!r.usable) return false;
    for (std::size_t j = f; j < rows.size(); j += k)
      out[rows[j]] = data.measured[rows[j]] - predict(r.params, data, rows[j]);
  }
  return true;
}

// Σ over the rows and axes of (e / scale)².
double whitened_ss(const std::vector<Wrench>& e, const std::vector<std::size_t>& rows,
                   const Vec6& scale) {
  double ss = 0.0;
  for (std::size_t i : rows)
    for (int k = 0; k < 6; ++k) ss += std::pow(e[i][k] / scale[static_cast<std::size_t>(k)], 2);
  return ss;
}

ErrorStats stats_of(const std::vector<Wrench>& e, const std::vector<std::size_t>& rows) {
  ErrorAccumulator acc;
  for (std::size_t i : rows) acc.add(e[i]);
  return acc.stats();
}

// ---- diagnose_table's phases, in the order it runs them ----

// The rows the diagnosis uses: all but the excluded ones, at least enough for cross-validation.
std::vector<std::size_t> kept_rows(const Dataset& data, const std::vector<std::uint8_t>* exclude) {
  std::vector<std::size_t> rows;
  for (std::size_t i = 0; i < data.size(); ++i)
    if (!(exclude && (*exclude)[i])) rows.push_back(i);
  constexpr std::size_t kMinRows = 10;
  if (rows.size() < kMinRows)
    throw std::runtime_error("a static table of " + std::to_string(rows.size()) +
                             " rows (no time) is too small to diagnose: cross-validation needs "
                             "at least " +
                             std::to_string(kMinRows) +
                             " poses (zerog fit still fits it, without a diagnosis)");
  return rows;
}

// The folds over n rows: leave-one-out while it is cheap and a single row matters; 10 interleaved
// folds beyond (a drift over the rows is then interpolated by every fold, never extrapolated).
// Returns k and says so in d.split.
std::size_t choose_folds(const Dataset& data, std::size_t n, Diagnosis& d) {
  const std::size_t k = n <= 30 ? n : 10;
  d.split.block_s = 0.0;
  d.split.blocks = static_cast<int>(k);
  d.split.automatic = true;
  d.split.heldout_samples = n;
  d.split.training_samples = n - (n + k - 1) / k;
  d.split.text = "k-fold cross-validation over the rows, k = " + std::to_string(k) +
                 (k == n ? " (leave-one-out: " : " (interleaved folds: ") + "a static table of " +
                 std::to_string(n) +
                 " poses has no time blocks to hold out; each row is predicted by the fit of the "
                 "others)";
  if (!data.rows_in_recorded_order)
    d.split.text +=
        "; the rig says the rows are not in the order recorded (row_order = \"unknown\"), so "
        "no drift over them is tried";
  return k;
}

// Outliers: rows whose cross-validated residual stands out of the robust spread (median absolute
// deviation) on some axis; at most a tenth of the rows (more is a heavy tail, not outliers).
struct OutlierScan {
  Vec6 center{}, spread{};    // per axis: the rows' median and robust spread
  double z_out = 0.0;         // the threshold, in spreads
  std::vector<Outlier> rows;  // largest z first; empty when a heavy tail
  std::string note;           // the heavy tail, when there is one
};

OutlierScan find_outliers(const std::vector<Wrench>& e, const std::vector<std::size_t>& rows) {
  const std::size_t n = rows.size();
  OutlierScan s;
  for (std::size_t a = 0; a < 6; ++a) {
    std::vector<double> v;
    for (std::size_t i : rows) v.push_back(e[i][static_cast<int>(a)]);
    s.center[a] = median_of(v);
    for (double& x : v) x = std::abs(x - s.center[a]);
    s.spread[a] = std::max(1.4826 * median_of(v), 1e-12);
  }
  s.z_out = std::max(5.0, std::sqrt(2.0 * std::log(6.0 * static_cast<double>(n))) + 2.0);
  for (std::size_t i : rows) {
    Outlier x;
    x.row = i;
    for (std::size_t a = 0; a < 6; ++a) {
      x.residual[a] = e[i][static_cast<int>(a)];
      x.z = std::max(x.z, std::abs(x.residual[a] - s.center[a]) / s.spread[a]);
    }
    if (x.z > s.z_out) s.rows.push_back(x);
  }
  std::sort(s.rows.begin(), s.rows.end(),
            [](const Outlier& a, const Outlier& b) { return a.z > b.z; });
  if (s.rows.size() > std::max<std::size_t>(1, n / 10)) {
    s.note = std::to_string(s.rows.size()) + " rows stand out by more than " +
             fmt("%.1f", s.z_out) +
             " robust spreads: a heavy tail across the table, not a few bad poses";
    s.rows.clear();
  }
  return s;
}

// The rows without the outliers, and their cross-validated residuals `e` again.
void drop_outliers(const Dataset& data, const FitOptions& base, const DiagnoseOptions& o,
                   const std::vector<Outlier>& out, std::size_t k, std::vector<std::size_t>& rows,
                   std::vector<Wrench>& e) {
  if (out.empty()) return;
  std::vector<std::uint8_t> excluded(data.size(), 0);
  if (o.exclude) excluded = *o.exclude;
  for (const Outlier& x : out) excluded[x.row] = 1;
  rows.clear();
  for (std::size_t i = 0; i < data.size(); ++i)
    if (!excluded[i]) rows.push_back(i);
  if (!cv_residuals(data, base, rows, std::min(k, rows.size()), e))
    throw std::runtime_error("the model cannot be fitted on the table without its outliers");
}

// The baseline on every kept row, and its cross-validated error per axis: the scale of the
// comparisons below (each axis counts by its own error).
struct Baseline {
  std::vector<std::uint8_t> keep;  // the kept rows, as a fit's mask
  Vec6 scale{};
  double ss = 0.0;  // whitened_ss of its cross-validated residuals
};

Baseline fit_baseline(const Dataset& data, const DiagnoseOptions& o,
                      const std::vector<std::size_t>& rows, const std::vector<Wrench>& e,
                      Diagnosis& d) {
  Baseline b;
  b.keep.assign(data.size(), 0);
  for (std::size_t i : rows) b.keep[i] = 1;
  FitOptions whole = o.fit;
  whole.mask = &b.keep;
  whole.progress = nullptr;
  d.baseline = fit(data, whole);
  d.baseline_heldout.stats = stats_of(e, rows);
  for (std::size_t a = 0; a < 6; ++a)
    b.scale[a] = std::max(d.baseline_heldout.stats.rms[a], a < 3 ? 1e-6 : 1e-7);
  d.noise_rms = b.scale;
  b.ss = whitened_ss(e, rows, b.scale);
  d.baseline_heldout.whitened_mse = b.ss / (6.0 * static_cast<double>(rows.size()));
  return b;
}

// One effect the table can feed (a drift over the row order among them) added to the model,
// cross-validated on the same `kk` folds as the baseline (its residuals `e`). Empty when a fold's
// fit is not usable.
std::optional<Candidate> try_candidate(const Dataset& data, const DiagnoseOptions& o,
                                       const Diagnosis& d, model::Effect eff,
                                       const std::vector<std::size_t>& rows, std::size_t kk,
                                       const std::vector<Wrench>& e, const Baseline& base) {
  Candidate c;
  c.effect = eff;
  c.name = model::info(eff).name;
  c.effects = d.model;
  c.effects.add(eff);
  FitOptions fo = o.fit;
  fo.effects = c.effects;
  fo.progress = nullptr;
  std::vector<Wrench> ec;
  if (!cv_residuals(data, fo, rows, kk, ec)) return std::nullopt;
  fo.mask = &base.keep;
  fo.covariance = false;
  c.fit = fit(data, fo);
  c.heldout.stats = stats_of(ec, rows);
  const double ss = whitened_ss(ec, rows, base.scale);
  c.heldout.whitened_mse = ss / (6.0 * static_cast<double>(rows.size()));
  c.gain = 1.0 - ss / base.ss;
  for (std::size_t a = 0; a < 6; ++a)
    c.axis_gain[a] =
        1.0 - std::pow(c.heldout.stats.rms[a], 2) / std::pow(d.baseline_heldout.stats.rms[a], 2);
  // The share of rows it predicts better.
  std::size_t better = 0;
  for (std::size_t i : rows) {
    double a = 0.0, b = 0.0;
    for (int q = 0; q < 6; ++q) {
      a += std::pow(ec[i][q] / base.scale[static_cast<std::size_t>(q)], 2);
      b += std::pow(e[i][q] / base.scale[static_cast<std::size_t>(q)], 2);
    }
    better += a < b ? 1 : 0;
  }
  c.better_rows = static_cast<double>(better) / static_cast<double>(rows.size());
  return c;
}

// The verdict's outlier paragraph.
void write_outliers(const OutlierScan& s, std::ostringstream& os) {
  const std::vector<Outlier>& out = s.rows;
  os << "Outlier poses: " << out.size() << (out.size() == 1 ? " row stands" : " rows stand")
     << " out of the cross-validated residual by more than " << fmt("%.1f", s.z_out)
     << " robust spreads (median absolute deviation of the other rows):";
  for (const Outlier& x : out) {
    os << " row " << (x.row + 1) << " (" << fmt("%.1f", x.z) << " spreads;";
    for (std::size_t a = 0; a < 6; ++a)
      if (std::abs(x.residual[a] - s.center[a]) > s.z_out * s.spread[a])
        os << " " << kAxisNames[a] << " " << fmt("%+.3g", x.residual[a]) << " " << kAxisUnits[a];
    os << ")";
  }
  os << ". A pose that was not held still, a touch, or a row mixed up: left out of what "
        "follows. ";
}

// The verdict's paragraph on the best candidate, which pays.
void write_effect(const DiagnoseOptions& o, const Candidate& c, const ErrorStats& h, Diagnosis& d,
                  std::ostringstream& os) {
  os << "Missing effect: " << c.name;
  if (c.effect == model::Effect::bias_drift)
    os << " (the sensor's bias drifts over the table's row order, its time order: per row)";
  else
    os << " (" << model::info(c.effect).summary << ")";
  os << ". Adding it removes " << fmt("%.0f", 100 * c.gain)
     << "% of the cross-validated error (force RMS " << fmt("%.3f", h.force_rms) << " -> "
     << fmt("%.3f", c.heldout.stats.force_rms) << " N, torque RMS " << fmt("%.3f", h.torque_rms)
     << " -> " << fmt("%.3f", c.heldout.stats.torque_rms) << " N*m) and predicts "
     << fmt("%.0f", 100 * c.better_rows) << "% of the rows better.";
  d.command = "zerog fit " + o.log_path + " --effects " + io::effect_list_string(c.effects) +
              " --out " + o.fit_out;
}

// The verdict's paragraph when no candidate pays.
void write_nothing_left(const ErrorStats& h, const Diagnosis& d, std::ostringstream& os) {
  os << "No effect the table can feed lowers the cross-validated error by 5 % for most rows";
  if (!d.candidates.empty())
    os << " (the best, " << d.candidates[0].name << ", " << fmt("%.0f", 100 * d.candidates[0].gain)
       << "%)";
  os << ": nothing is proposed. Cross-validated RMS force " << fmt("%.3f", h.force_rms)
     << " N, torque " << fmt("%.3f", h.torque_rms)
     << " N*m; a table cannot tell the sensor's noise from structure the library lacks, so "
        "compare these with the sensor's datasheet noise.";
}

// The verdict, its text, and the command it suggests (with the rows it left out).
void conclude(const DiagnoseOptions& o, const OutlierScan& outliers, Diagnosis& d) {
  const bool pays =
      !d.candidates.empty() && d.candidates[0].gain >= 0.05 && d.candidates[0].better_rows >= 0.5;
  const std::string model =
      o.model_text.empty() ? io::model_spec_string(d.model, o.fit.user) : o.model_text;
  std::string rows_out;
  for (const Outlier& x : outliers.rows)
    rows_out += (rows_out.empty() ? "rows:" : ",rows:") + std::to_string(x.row + 1);
  d.exclude = rows_out.empty()
                  ? o.exclude_text
                  : (o.exclude_text.empty() ? rows_out : o.exclude_text + "," + rows_out);
  std::ostringstream os;
  const auto& h = d.baseline_heldout.stats;
  if (!outliers.rows.empty()) {
    d.verdict = Diagnosis::Verdict::outliers;
    write_outliers(outliers, os);
  }
  if (pays) {
    if (d.verdict != Diagnosis::Verdict::outliers) d.verdict = Diagnosis::Verdict::effect;
    write_effect(o, d.candidates[0], h, d, os);
  } else {
    if (d.verdict != Diagnosis::Verdict::outliers) d.verdict = Diagnosis::Verdict::nothing_left;
    write_nothing_left(h, d, os);
    if (d.verdict == Diagnosis::Verdict::outliers)
      d.command = "zerog fit " + o.log_path + " --effects " + model + " --out " + o.fit_out;
  }
  if (!outliers.note.empty()) os << " " << outliers.note << ".";
  d.text = os.str();
  if (!d.command.empty() && !d.exclude.empty()) d.command += " --exclude " + d.exclude;
}

}  // namespace

Diagnosis diagnose_table(const Dataset& data, const DiagnoseOptions& o) {
  Diagnosis d = start_diagnosis(o.fit.effects, data);
  check_signals(o.fit.effects, data);
  check_signals(o.fit.user, data);
  std::vector<std::size_t> rows = kept_rows(data, o.exclude);
  const std::size_t k = choose_folds(data, rows.size(), d);
  if (o.progress) o.progress("diagnose: " + d.split.text);

  FitOptions base = o.fit;
  base.progress = nullptr;
  std::vector<Wrench> e;
  if (!cv_residuals(data, base, rows, k, e))
    throw std::runtime_error("the model " + io::effect_list_string(d.model) +
                             " cannot be fitted on the table's folds: it has too few poses, or "
                             "poses too alike, for it (zerog fit names what it cannot identify)");
  const OutlierScan outliers = find_outliers(e, rows);
  d.outliers = outliers.rows;
  drop_outliers(data, base, o, outliers.rows, k, rows, e);
  const std::size_t kk = std::min(k, rows.size());
  const Baseline baseline = fit_baseline(data, o, rows, e, d);

  for (model::Effect eff : candidate_effects(d.model, data))
    if (auto c = try_candidate(data, o, d, eff, rows, kk, e, baseline))
      d.candidates.push_back(std::move(*c));
  std::sort(d.candidates.begin(), d.candidates.end(),
            [](const Candidate& a, const Candidate& b) { return a.gain > b.gain; });
  d.candidate_evaluation.method = "refitted";
  d.candidate_evaluation.reason =
      "cross-validated over the rows (" + std::to_string(kk) +
      " folds); 'better rows': the share of rows the candidate predicts better";
  conclude(o, outliers, d);
  return d;
}

}  // namespace zerog::ident
