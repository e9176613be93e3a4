#include "zerog/robot/savitzky_golay.hpp"

#include <Eigen/LU>
#include <array>
#include <cmath>
#include <complex>
#include <numbers>

namespace zerog::robot {
namespace {

constexpr std::array<double, 3> kFactorial = {1.0, 1.0, 2.0};

// |H_d(f)| / |2πf|^d for the uniform coefficients c (k = −M..M) at period h.
double relative_gain(std::span<const double> c, int half_width, int derivative, double period_s,
                     double f_hz) {
  const double w = 2.0 * std::numbers::pi * f_hz;
  std::complex<double> h(0.0, 0.0);
  for (int k = -half_width; k <= half_width; ++k)
    h += c[static_cast<std::size_t>(k + half_width)] *
         std::exp(std::complex<double>(0.0, w * k * period_s));
  return std::abs(h) / std::pow(period_s, derivative) / std::pow(w, derivative);
}

}  // namespace

bool valid(const SgSettings& s) {
  return s.order >= kMinSgOrder && s.order <= kMaxSgOrder && s.half_width >= (s.order + 1) / 2 &&
         s.half_width <= kMaxHalfWidth;
}

Eigen::Vector4d LocalPolyFit::basis(double tau_s) const {
  const double x = tau_s / scale_s_;
  Eigen::Vector4d b = Eigen::Vector4d::Zero();
  double power = 1.0;
  for (int j = 0; j <= order_; ++j, power *= x) b[j] = power;
  return b;
}

void LocalPolyFit::add(double tau_s, double scale_s) {
  scale_s_ = scale_s;
  const Eigen::Vector4d b = basis(tau_s);
  normal_ += b * b.transpose();
}

bool LocalPolyFit::solve() {
  // Unused powers (above the order) get a unit diagonal so the 4×4 inverse exists.
  for (int j = order_ + 1; j < 4; ++j) normal_(j, j) = 1.0;
  bool invertible = false;
  double determinant = 0.0;
  normal_.computeInverseAndDetWithCheck(inverse_, determinant, invertible, 1e-12);
  return invertible;
}

double LocalPolyFit::weight(double tau_s, int derivative) const {
  // The fit's coefficients are β = N⁻¹ Σ b_k y_k (in x = τ/s); y^(d)(0) = d! β_d / s^d.
  const double row = inverse_.row(derivative).dot(basis(tau_s));
  return kFactorial[static_cast<std::size_t>(derivative)] * row / std::pow(scale_s_, derivative);
}

bool sg_differentiate(std::span<const double> times_s, std::span<const Eigen::Vector3d> values,
                      const SgSettings& s, int derivative, std::span<Eigen::Vector3d> out) {
  const std::size_t n = times_s.size(), m = static_cast<std::size_t>(s.half_width);
  if (!valid(s) || values.size() != n || out.size() != n || n < 2 * m + 1 || derivative < 0 ||
      derivative > kMaxSgDerivative)
    return false;
  for (std::size_t c = 0; c < n; ++c) {
    const std::size_t first = sg_window_first(c, n, m), last = first + 2 * m;
    LocalPolyFit fit(s.order);
    const double scale = 0.5 * (times_s[last] - times_s[first]);
    for (std::size_t k = first; k <= last; ++k) fit.add(times_s[k] - times_s[c], scale);
    if (!fit.solve()) return false;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (std::size_t k = first; k <= last; ++k)
      sum += fit.weight(times_s[k] - times_s[c], derivative) * values[k];
    out[c] = sum;
  }
  return true;
}

void sg_coefficients(const SgSettings& s, int derivative, std::span<double> out) {
  LocalPolyFit fit(s.order);
  const double scale = s.half_width;
  for (int k = -s.half_width; k <= s.half_width; ++k) fit.add(k, scale);
  fit.solve();
  for (int k = -s.half_width; k <= s.half_width; ++k)
    out[static_cast<std::size_t>(k + s.half_width)] = fit.weight(k, derivative);
}

double sg_noise_gain(const SgSettings& s, int derivative, double period_s) {
  std::array<double, 2 * kMaxHalfWidth + 1> c{};
  sg_coefficients(s, derivative, c);
  double sum = 0.0;
  for (int k = 0; k < 2 * s.half_width + 1; ++k) sum += c[static_cast<std::size_t>(k)] * c[k];
  return std::sqrt(sum) / std::pow(period_s, derivative);
}

double sg_cutoff_hz(const SgSettings& s, int derivative, double period_s) {
  std::array<double, 2 * kMaxHalfWidth + 1> c{};
  sg_coefficients(s, derivative, c);
  const double nyquist = 0.5 / period_s;
  const double limit = 1.0 / std::sqrt(2.0);
  // The passband is flat from 0 (exact for polynomials); scan for the first fall below −3 dB.
  constexpr int kSteps = 400;
  double below = nyquist, above = 0.0;
  bool found = false;
  for (int i = 1; i <= kSteps; ++i) {
    const double f = nyquist * i / kSteps;
    if (relative_gain(c, s.half_width, derivative, period_s, f) < limit) {
      below = f;
      above = nyquist * (i - 1) / kSteps;
      found = true;
      break;
    }
  }
  if (!found) return nyquist;
  if (above == 0.0) above = 1e-9 * nyquist;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (above + below);
    (relative_gain(c, s.half_width, derivative, period_s, mid) < limit ? below : above) = mid;
  }
  return 0.5 * (above + below);
}

double sg_causal_delay_s(const SgSettings& s, double period_s) { return s.half_width * period_s; }

SgSettings choose_sg_window(double period_s, double bandwidth_hz, int order, int derivative) {
  // The cutoff falls as the window grows (about (n + 1) / (3.2 M − 4.6) of Nyquist for d = 0,
  // Schafer 2011, eq. 11): bisect for the largest M that still passes the bandwidth.
  const auto passes = [&](int m) {
    return sg_cutoff_hz({m, order}, derivative, period_s) >= bandwidth_hz;
  };
  int lo = (order + 1) / 2, hi = kMaxHalfWidth;
  if (!passes(lo)) return {lo, order};
  if (passes(hi)) return {hi, order};
  while (hi - lo > 1) {  // passes(lo), !passes(hi)
    const int mid = (lo + hi) / 2;
    (passes(mid) ? lo : hi) = mid;
  }
  return {lo, order};
}

}  // namespace zerog::robot
