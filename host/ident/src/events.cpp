#include "zerog/ident/events.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "zerog/formats/detail/csv_scan.hpp"
#include "zerog/ident/compare.hpp"

namespace zerog::ident {
namespace {

using Vec6 = std::array<double, 6>;

// Prefix sums of the residual over the scanned rows: sums[i] and count[i] cover rows [0, i).
struct Prefix {
  std::vector<Vec6> sum;
  std::vector<double> count;
  Prefix(const std::vector<Wrench>& r, const std::vector<std::uint8_t>& scanned)
      : sum(r.size() + 1), count(r.size() + 1, 0.0) {
    for (std::size_t i = 0; i < r.size(); ++i) {
      sum[i + 1] = sum[i];
      count[i + 1] = count[i];
      if (!scanned[i]) continue;
      for (int k = 0; k < 6; ++k) sum[i + 1][static_cast<std::size_t>(k)] += r[i][k];
      count[i + 1] += 1.0;
    }
  }
  double n(std::size_t a, std::size_t b) const { return count[b] - count[a]; }
  // Mean over the scanned rows of [a, b); false when there are fewer than `min` of them.
  bool mean(std::size_t a, std::size_t b, double min, Vec6& out) const {
    const double m = n(a, b);
    if (m < std::max(min, 1.0)) return false;
    for (std::size_t k = 0; k < 6; ++k) out[k] = (sum[b][k] - sum[a][k]) / m;
    return true;
  }
};

double median_of(std::vector<double>& v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

double scaled_max(const Vec6& d, const Vec6& scale) {
  double m = 0.0;
  for (std::size_t k = 0; k < 6; ++k) m = std::max(m, std::abs(d[k]) / scale[k]);
  return m;
}

Vec6 minus(const Vec6& a, const Vec6& b) {
  Vec6 d;
  for (std::size_t k = 0; k < 6; ++k) d[k] = a[k] - b[k];
  return d;
}

bool motion_edge_near(const Dataset& data, std::size_t row, double tol_s) {
  if (data.moving.empty() || data.size() < 2) return false;
  const double t = data.t_s[row];
  std::size_t a = row, b = row;
  while (a > 1 && t - data.t_s[a - 1] <= tol_s) --a;
  while (b + 1 < data.size() && data.t_s[b + 1] - t <= tol_s) ++b;
  for (std::size_t i = std::max<std::size_t>(a, 1); i <= b; ++i)
    if (data.moving[i] != data.moving[i - 1]) return true;
  return false;
}

std::string num(const char* f, double x) {
  char b[64];
  std::snprintf(b, sizeof b, f, x);
  return b;
}

// ---- find_spans' phases, in the order it runs them ----

// The step detector's window in rows, or why it cannot run on this log (scan.possible false, a
// note).
std::size_t step_window(const Dataset& data, const EventOptions& o, SpanScan& scan) {
  const std::size_t n = data.size();
  if (data.columns.static_rows) {
    scan.possible = false;
    scan.note =
        "a table without time: its rows are poses, not moments, so no span of time can stand "
        "out";
    return 0;
  }
  const std::size_t w =
      std::max<std::size_t>(5, static_cast<std::size_t>(std::lround(o.window_s / data.dt_s)));
  scan.window_rows = w;
  if (n < 4 * w) {
    scan.possible = false;
    scan.note = "the log holds " + std::to_string(n) + " rows; the step detector needs at least " +
                std::to_string(4 * w) + " (four windows of " + num("%.2f", o.window_s) + " s)";
  }
  return w;
}

// The step statistic D(i) = mean(r[i, i+w)) − mean(r[i−w, i)) where both windows hold at least
// half their rows, and its robust spread per axis (scan.scale) and threshold (scan.z_step).
struct Steps {
  std::vector<Vec6> D;              // rows 0..n
  std::vector<std::uint8_t> valid;  // D[i] computed
};

Steps step_statistic(const Prefix& P, std::size_t n, std::size_t w, const EventOptions& o,
                     SpanScan& scan) {
  const double half = 0.5 * static_cast<double>(w);
  Steps s{std::vector<Vec6>(n + 1), std::vector<std::uint8_t>(n + 1, 0)};
  for (std::size_t i = w; i + w <= n; ++i) {
    Vec6 left, right;
    if (!P.mean(i - w, i, half, left) || !P.mean(i, i + w, half, right)) continue;
    s.D[i] = minus(right, left);
    s.valid[i] = 1;
  }
  std::size_t n_valid = 0;
  for (std::size_t k = 0; k < 6; ++k) {
    std::vector<double> v;
    v.reserve(n);
    for (std::size_t i = 0; i <= n; ++i)
      if (s.valid[i]) v.push_back(s.D[i][k]);
    n_valid = v.size();
    const double med = median_of(v);
    for (double& x : v) x = std::abs(x - med);
    // Floor: a residual that is exactly constant (noise-free data) still gets a scale.
    scan.scale[k] = std::max(1.4826 * median_of(v), 1e-9);
  }
  if (n_valid == 0) {
    scan.possible = false;
    scan.note = "too few rows are left outside the excluded spans for the step detector";
    return s;
  }
  scan.z_step =
      o.z_step > 0.0
          ? o.z_step
          : std::sqrt(2.0 * std::log(6.0 * static_cast<double>(n_valid) / static_cast<double>(w))) +
                3.0;
  return s;
}

// Change points: local maxima of the largest scaled step, at least a window apart.
std::vector<std::size_t> change_points(const Steps& steps, std::size_t n, std::size_t w,
                                       const SpanScan& scan) {
  std::vector<double> S(n + 1, 0.0);
  for (std::size_t i = 0; i <= n; ++i)
    if (steps.valid[i]) S[i] = scaled_max(steps.D[i], scan.scale);
  std::vector<std::size_t> cps;
  for (std::size_t i = 0; i <= n; ++i) {
    if (!steps.valid[i] || S[i] < scan.z_step) continue;
    bool peak = true;
    for (std::size_t j = i > w ? i - w : 0; j <= std::min(n, i + w) && peak; ++j)
      if (S[j] > S[i] || (S[j] == S[i] && j < i)) peak = false;
    if (peak) cps.push_back(i);
  }
  return cps;
}

// The segments between change points and their levels (a half window trimmed at each end, where
// the step is).
struct Segments {
  std::vector<std::size_t> bounds;  // segment s is rows [bounds[s], bounds[s + 1])
  std::vector<Vec6> level;
  std::vector<double> weight;  // scanned rows, at least 1
  std::size_t size() const { return level.size(); }
};

Segments segments_between(const std::vector<std::size_t>& cps, const Prefix& P, std::size_t n,
                          std::size_t w) {
  Segments seg;
  seg.bounds = {0};
  seg.bounds.insert(seg.bounds.end(), cps.begin(), cps.end());
  seg.bounds.push_back(n);
  const std::size_t m = seg.bounds.size() - 1;
  seg.level.resize(m);
  seg.weight.resize(m);
  for (std::size_t s = 0; s < m; ++s) {
    const std::size_t a = seg.bounds[s], b = seg.bounds[s + 1];
    const std::size_t trim = std::min(w / 2, (b - a) / 4);
    if (!P.mean(a + trim, b - trim, 1.0, seg.level[s])) P.mean(a, b, 1.0, seg.level[s]);
    seg.weight[s] = std::max(P.n(a, b), 1.0);
  }
  return seg;
}

// An excursion: segments first_seg..last_seg away from the level `out` around them.
struct Excursion {
  std::size_t first_seg, last_seg;
  Vec6 out;
};

// Excursions: segments j..l whose neighbours j−1 and l+1 agree, every one of them away from that
// level; with a single change point, its shorter side (a touch at the start or the end of a
// recording).
std::vector<Excursion> excursions(const Segments& seg, const EventOptions& o,
                                  const SpanScan& scan) {
  const std::size_t m = seg.size();
  const auto& level = seg.level;
  std::vector<Excursion> found;
  for (std::size_t j = 1; j + 1 < m;) {
    bool took = false;
    for (std::size_t l = j; l + 1 < m; ++l) {
      if (scaled_max(minus(level[j - 1], level[l + 1]), scan.scale) >= o.z_agree) continue;
      Vec6 out;
      const double wa = seg.weight[j - 1], wb = seg.weight[l + 1];
      for (std::size_t k = 0; k < 6; ++k)
        out[k] = (wa * level[j - 1][k] + wb * level[l + 1][k]) / (wa + wb);
      bool away = true;
      for (std::size_t s = j; s <= l && away; ++s)
        away = scaled_max(minus(level[s], out), scan.scale) >= scan.z_step;
      if (away) {
        found.push_back({j, l, out});
        j = l + 2;
        took = true;
      }
      break;
    }
    if (!took) ++j;
  }
  if (m == 2) {
    const bool first_shorter = seg.weight[0] < seg.weight[1];
    const std::size_t s = first_shorter ? 0 : 1;
    if (scaled_max(minus(level[0], level[1]), scan.scale) >= scan.z_step)
      found.push_back({s, s, level[1 - s]});
  }
  return found;
}

// Short-window means (h rows each side) of the residual, as deviations from a level.
struct ShortWindow {
  const Prefix& P;
  std::size_t n, h;
  bool dev(std::size_t i, const Vec6& out, Vec6& d) const {
    const std::size_t a = i >= h ? i - h : 0, b = std::min(n, i + h + 1);
    Vec6 mean;
    if (!P.mean(a, b, 1.0, mean)) return false;
    d = minus(mean, out);
    return true;
  }
};

// An excursion's rows, widened over its ramps: outward while a short-window mean on the axis that
// carries the span most (in scale units) still holds a twentieth of its peak there, and stands
// out from that mean's spread.
std::pair<std::size_t, std::size_t> widened_rows(const Excursion& f, const Segments& seg,
                                                 const ShortWindow& sw, std::size_t w,
                                                 const SpanScan& scan) {
  const Prefix& P = sw.P;
  const std::size_t m = seg.size();
  std::size_t first = seg.bounds[f.first_seg], last = seg.bounds[f.last_seg + 1] - 1;
  std::size_t axis = 0;
  double sign = 1.0;
  {
    Vec6 mean;
    P.mean(first, last + 1, 1.0, mean);
    const Vec6 d = minus(mean, f.out);
    for (std::size_t k = 1; k < 6; ++k)
      if (std::abs(d[k]) / scan.scale[k] > std::abs(d[axis]) / scan.scale[axis]) axis = k;
    sign = d[axis] < 0.0 ? -1.0 : 1.0;
  }
  auto proj = [&](std::size_t i) {
    Vec6 dev;
    if (!sw.dev(i, f.out, dev)) return 0.0;
    return sign * dev[axis] / scan.scale[axis];
  };
  double peak = 0.0;
  for (std::size_t i = first; i <= last; ++i) peak = std::max(peak, proj(i));
  // A short-window mean's spread, in scale units, is about sqrt(w / (2 (2h + 1))).
  const double floor =
      3.0 * std::sqrt(static_cast<double>(w) / (2.0 * static_cast<double>(2 * sw.h + 1)));
  const double thr = std::max(0.05 * peak, floor);
  const std::size_t lo = f.first_seg > 0 ? seg.bounds[f.first_seg - 1] : 0;
  const std::size_t hi = f.last_seg + 1 < m ? seg.bounds[f.last_seg + 2] - 1 : sw.n - 1;
  while (first > lo && proj(first - 1) > thr) --first;
  while (last < hi && proj(last + 1) > thr) ++last;
  while (first < last && proj(first) <= thr && f.first_seg > 0) ++first;
  while (last > first && proj(last) <= thr && f.last_seg + 1 < m) --last;
  return {first, last};
}

// The span of rows [first, last] around an excursion: what it carried, and whether motion starts
// or stops at its ends.
Span span_of(std::size_t first, std::size_t last, const Excursion& f, const ShortWindow& sw,
             const Dataset& data, const EventOptions& o, const SpanScan& scan) {
  Span s;
  s.first = first;
  s.last = last;
  s.t0_s = data.t_s[first];
  s.t1_s = data.t_s[last];
  Vec6 mean{};
  sw.P.mean(first, last + 1, 1.0, mean);
  s.mean = minus(mean, f.out);
  s.z = 0.0;
  for (std::size_t i = first; i <= last; ++i) {
    Vec6 dev;
    if (!sw.dev(i, f.out, dev)) continue;
    for (std::size_t k = 0; k < 6; ++k)
      if (std::abs(dev[k]) > std::abs(s.peak[k])) s.peak[k] = dev[k];
  }
  s.z = scaled_max(s.mean, scan.scale);
  for (std::size_t k = 0; k < 6; ++k) s.mean_z[k] = s.mean[k] / scan.scale[k];
  s.starts_with_motion = motion_edge_near(data, first, o.motion_tolerance_s);
  s.ends_with_motion = motion_edge_near(data, last, o.motion_tolerance_s);
  return s;
}

}  // namespace

SpanScan find_spans(const std::vector<Wrench>& r, const Dataset& data,
                    const std::vector<std::uint8_t>* exclude, const EventOptions& o) {
  SpanScan scan;
  scan.window_s = o.window_s;
  const std::size_t n = data.size();
  if (r.size() != n) throw std::invalid_argument("find_spans: one residual per row wanted");
  const std::size_t w = step_window(data, o, scan);
  if (!scan.possible) return scan;
  std::vector<std::uint8_t> scanned(n, 1);
  if (exclude)
    for (std::size_t i = 0; i < n; ++i) scanned[i] = (*exclude)[i] ? 0 : 1;
  const Prefix P(r, scanned);
  const Steps steps = step_statistic(P, n, w, o, scan);
  if (!scan.possible) return scan;
  const std::vector<std::size_t> cps = change_points(steps, n, w, scan);
  scan.change_points = cps.size();
  const Segments seg = segments_between(cps, P, n, w);
  const ShortWindow sw{P, n, std::max<std::size_t>(2, w / 4)};
  for (const Excursion& f : excursions(seg, o, scan)) {
    const auto [first, last] = widened_rows(f, seg, sw, w, scan);
    scan.spans.push_back(span_of(first, last, f, sw, data, o, scan));
  }
  std::sort(scan.spans.begin(), scan.spans.end(),
            [](const Span& a, const Span& b) { return a.first < b.first; });
  double inside = 0.0;
  for (const Span& s : scan.spans) inside += P.n(s.first, s.last + 1);
  scan.coverage = inside / std::max(P.n(0, n), 1.0);
  scan.recurring =
      static_cast<int>(scan.spans.size()) > o.max_events || scan.coverage > o.max_coverage;
  return scan;
}

std::vector<std::uint8_t> span_mask(const Dataset& data, const std::vector<Span>& spans,
                                    std::vector<std::uint8_t> base) {
  if (base.empty()) base.assign(data.size(), 0);
  for (const Span& s : spans)
    for (std::size_t i = s.first; i <= s.last && i < base.size(); ++i) base[i] = 1;
  return base;
}

ExcludeSpec parse_exclude(const std::string& text) {
  ExcludeSpec spec;
  spec.text = text;
  auto number = [&](const std::string& s, const std::string& item) {
    double x = 0.0;
    if (formats::detail::parse_number(s, x) != formats::detail::NumberStatus::ok)
      throw std::invalid_argument("--exclude item '" + item + "': '" + s + "' is not a number");
    return x;
  };
  auto row = [&](const std::string& s, const std::string& item) {
    const double x = number(s, item);
    if (x < 1.0 || x != std::floor(x))
      throw std::invalid_argument("--exclude item '" + item + "': row '" + s +
                                  "' is not a data row number (1, 2, ...)");
    return static_cast<std::size_t>(x);
  };
  std::size_t a = 0;
  while (a <= text.size()) {
    const std::size_t b = std::min(text.find(',', a), text.size());
    const std::string item = text.substr(a, b - a);
    a = b + 1;
    if (item.empty()) throw std::invalid_argument("--exclude '" + text + "' has an empty item");
    if (item.rfind("rows:", 0) == 0 || item.rfind("row:", 0) == 0) {
      const std::string r = item.substr(item.find(':') + 1);
      const std::size_t dash = r.find('-');
      const std::size_t lo = row(r.substr(0, dash), item);
      const std::size_t hi = dash == std::string::npos ? lo : row(r.substr(dash + 1), item);
      if (hi < lo)
        throw std::invalid_argument("--exclude item '" + item + "': the range runs backwards");
      spec.rows.emplace_back(lo, hi);
      continue;
    }
    const std::size_t colon = item.find(':');
    if (colon == std::string::npos)
      throw std::invalid_argument("--exclude item '" + item +
                                  "': wants START:END (s of log time) or rows:A-B (data rows, 1 "
                                  "is the first)");
    const double t0 = number(item.substr(0, colon), item);
    const double t1 = number(item.substr(colon + 1), item);
    if (t1 < t0)
      throw std::invalid_argument("--exclude item '" + item + "': the span ends before it starts");
    spec.times.emplace_back(t0, t1);
  }
  return spec;
}

std::vector<std::uint8_t> exclude_mask(const Dataset& data, const ExcludeSpec& spec,
                                       const std::string& log_name) {
  const std::size_t n = data.size();
  std::vector<std::uint8_t> mask(n, 0);
  for (const auto& [t0, t1] : spec.times) {
    if (data.columns.static_rows)
      throw std::runtime_error("--exclude " + num("%g", t0) + ":" + num("%g", t1) + ": " +
                               log_name +
                               " is a table without time; name its rows instead (rows:A-B)");
    std::size_t hit = 0;
    for (std::size_t i = 0; i < n; ++i)
      if (data.t_s[i] >= t0 && data.t_s[i] <= t1) mask[i] = 1, ++hit;
    if (hit == 0)
      throw std::runtime_error("--exclude " + num("%g", t0) + ":" + num("%g", t1) + ": no row of " +
                               log_name + " lies in it (its time runs " +
                               num("%.3f", data.t_s.front()) + " to " +
                               num("%.3f", data.t_s.back()) + " s)");
  }
  for (const auto& [lo, hi] : spec.rows) {
    if (lo > n)
      throw std::runtime_error("--exclude rows:" + std::to_string(lo) + "-" + std::to_string(hi) +
                               ": " + log_name + " has " + std::to_string(n) + " data rows");
    for (std::size_t i = lo - 1; i < std::min(hi, n); ++i) mask[i] = 1;
  }
  std::size_t left = 0;
  for (std::uint8_t v : mask) left += v ? 0 : 1;
  if (left == 0)
    throw std::runtime_error("--exclude '" + spec.text + "' leaves no row of " + log_name);
  return mask;
}

std::string exclude_text(const std::vector<Span>& spans) {
  std::string out;
  for (const Span& s : spans) {
    if (!out.empty()) out += ",";
    out += num("%.2f", std::floor(s.t0_s * 100.0) / 100.0) + ":" +
           num("%.2f", std::ceil(s.t1_s * 100.0) / 100.0);
  }
  return out;
}

std::vector<TimelineBin> timeline(const std::vector<Wrench>& r, const Dataset& data,
                                  const std::vector<std::uint8_t>* exclude, int bins) {
  std::vector<TimelineBin> out;
  const std::size_t n = data.size();
  if (n == 0 || bins < 1) return out;
  const bool by_time = !data.columns.static_rows && data.t_s.back() > data.t_s.front();
  const double t0 = data.t_s.front(), t1 = data.t_s.back();
  out.resize(static_cast<std::size_t>(std::min<std::size_t>(static_cast<std::size_t>(bins), n)));
  const std::size_t nb = out.size();
  std::vector<Vec6> ss(nb);
  for (std::size_t b = 0; b < nb; ++b) out[b].first = std::numeric_limits<std::size_t>::max();
  for (std::size_t i = 0; i < n; ++i) {
    const double u =
        by_time ? (data.t_s[i] - t0) / (t1 - t0) : static_cast<double>(i) / static_cast<double>(n);
    const std::size_t b = std::min(nb - 1, static_cast<std::size_t>(u * static_cast<double>(nb)));
    TimelineBin& bin = out[b];
    bin.first = std::min(bin.first, i);
    bin.last = i;
    if (exclude && (*exclude)[i]) continue;
    ++bin.count;
    for (std::size_t k = 0; k < 6; ++k)
      ss[b][k] += r[i][static_cast<int>(k)] * r[i][static_cast<int>(k)];
  }
  for (std::size_t b = 0; b < nb; ++b) {
    TimelineBin& bin = out[b];
    if (bin.first == std::numeric_limits<std::size_t>::max()) bin.first = bin.last = 0;
    bin.t0_s = by_time ? t0 + (t1 - t0) * static_cast<double>(b) / static_cast<double>(nb)
                       : static_cast<double>(bin.first);
    bin.t1_s = by_time ? t0 + (t1 - t0) * static_cast<double>(b + 1) / static_cast<double>(nb)
                       : static_cast<double>(bin.last);
    for (std::size_t k = 0; k < 6; ++k)
      bin.rms[k] = bin.count ? std::sqrt(ss[b][k] / static_cast<double>(bin.count)) : 0.0;
  }
  return out;
}

nlohmann::json to_json(const Span& s) {
  return {{"first_row", s.first + 1},
          {"last_row", s.last + 1},
          {"t0_s", s.t0_s},
          {"t1_s", s.t1_s},
          {"duration_s", s.duration_s()},
          {"frame", "S"},
          {"mean_wrench", s.mean},
          {"mean_z", s.mean_z},
          {"peak_wrench", s.peak},
          {"z", s.z},
          {"starts_with_motion", s.starts_with_motion},
          {"ends_with_motion", s.ends_with_motion}};
}

nlohmann::json to_json(const SpanScan& s) {
  nlohmann::json spans = nlohmann::json::array();
  for (const Span& x : s.spans) spans.push_back(to_json(x));
  return {{"possible", s.possible},
          {"note", s.possible ? nlohmann::json(nullptr) : nlohmann::json(s.note)},
          {"window_s", s.window_s},
          {"window_rows", s.window_rows},
          {"z_step", s.z_step},
          {"scale", s.scale},
          {"change_points", s.change_points},
          {"coverage", s.coverage},
          {"recurring", s.recurring},
          {"spans", spans}};
}

nlohmann::json to_json(const std::vector<TimelineBin>& t) {
  nlohmann::json a = nlohmann::json::array();
  for (const TimelineBin& b : t)
    a.push_back({{"t0_s", b.t0_s},
                 {"t1_s", b.t1_s},
                 {"first_row", b.first + 1},
                 {"last_row", b.last + 1},
                 {"count", b.count},
                 {"rms", b.rms}});
  return a;
}

std::string format_spans(const std::vector<Span>& spans, const std::string& indent) {
  std::string out;
  for (const Span& s : spans) {
    out += indent + num("%.2f", s.t0_s) + " - " + num("%.2f", s.t1_s) + " s (" +
           num("%.2f", s.duration_s()) + " s, rows " + std::to_string(s.first + 1) + "-" +
           std::to_string(s.last + 1) + "): mean";
    // The axes that carry it: those standing out from the step's spread (three of it).
    for (std::size_t k = 0; k < 6; ++k) {
      const double v = s.mean[k];
      if (std::abs(s.mean_z[k]) < 3.0) continue;
      out += std::string(" ") + kAxisNames[k] + " " + num("%+.2f", v) + " " + kAxisUnits[k];
    }
    if (s.starts_with_motion && s.ends_with_motion)
      out += " [starts and ends with the robot's motion]";
    else if (s.starts_with_motion)
      out += " [starts with the robot's motion]";
    else if (s.ends_with_motion)
      out += " [ends with the robot's motion]";
    out += "\n";
  }
  return out;
}

}  // namespace zerog::ident
