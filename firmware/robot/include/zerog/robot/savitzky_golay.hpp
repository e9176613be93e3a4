#pragma once
// Savitzky–Golay smoothing differentiator on possibly non-uniform time stamps
// (proto/robot_kinematics.md, "The differentiator").
//
// Method (Savitzky & Golay, Anal. Chem. 36(8), 1964; Schafer, "What is a Savitzky–Golay
// filter?", IEEE Signal Processing Magazine 28(4), 2011): around a centre sample c, a polynomial
// of order n (2 or 3) is fitted by least squares to the 2M+1 samples c−M..c+M, in the local time
// τ_k = t_k − t_c of the actual time stamps (a local fit: non-uniform stamps need no
// resampling), and its value and derivatives at τ = 0 are the smoothed value, rate and
// acceleration. The estimate is linear in the samples: y^(d)(t_c) = Σ_k w_{d,k} y_k. On a uniform
// grid of period h the weights are w_{d,k} = c_{d,k} / h^d with c_{d,k} the classic SG
// coefficients (sg_coefficients), so for white noise of standard deviation σ on y:
//
//   noise gain   σ_out / σ = sqrt(Σ_k c_{d,k}²) / h^d             (sg_noise_gain)
//   lag          0 for the centred window (the fit is evaluated at its centre). A causal user
//                (zerog-rt) evaluates the same centred fit on the newest 2M+1 samples and so
//                reports the value of M·h ago: delay M·h (sg_causal_delay_s).
//   bandwidth    the frequency at which |H_d(f)| has fallen 3 dB below the ideal differentiator
//                |2πf|^d (d = 0: below 1), H_d(f) = Σ_k c_{d,k} e^{j 2π f k h} / h^d
//                (sg_cutoff_hz). Motion below it passes (polynomial of order n exactly);
//                noise above it is attenuated.
//
// Everything here is allocation-free; the fit is real-time safe (bounded by kMaxHalfWidth).
#include <Eigen/Core>
#include <cstddef>
#include <span>

namespace zerog::robot {

inline constexpr int kMinSgOrder = 2;
inline constexpr int kMaxSgOrder = 3;
inline constexpr int kMaxHalfWidth = 200;  ///< M ≤ 200: at most 401 samples a window
inline constexpr int kMaxSgDerivative = 2;

struct SgSettings {
  int half_width = 8;  ///< M: the window holds 2M+1 samples
  int order = 3;       ///< polynomial order n, 2 or 3
};

/// True if `s` is usable: order in [2, 3], M in [ceil(order/2), kMaxHalfWidth].
bool valid(const SgSettings& s);

/// A least-squares polynomial fit in local time τ (s) around a centre sample, kept as the
/// inverse normal matrix so that the weight of any sample is one small product. Build with
/// add() for every τ_k of the window, then solve(); weight(τ_k, d) is then w_{d,k} (units
/// 1/s^d). Real-time safe.
class LocalPolyFit {
 public:
  explicit LocalPolyFit(int order) : order_(order) {}
  /// Adds a sample at local time tau_s. `scale_s` (the window's half span) only conditions the
  /// normal matrix; pass the same value to every add().
  void add(double tau_s, double scale_s);
  /// False if the samples do not determine the polynomial (fewer than order+1 distinct times).
  bool solve();
  /// The weight of the sample at tau_s in the d-th derivative at τ = 0 (d in 0..2), 1/s^d.
  double weight(double tau_s, int derivative) const;

 private:
  Eigen::Vector4d basis(double tau_s) const;  // (τ/s)^j, j ≤ order, zero above
  int order_;
  double scale_s_ = 1.0;
  Eigen::Matrix4d normal_ = Eigen::Matrix4d::Zero();
  Eigen::Matrix4d inverse_ = Eigen::Matrix4d::Zero();
};

/// First sample of the window of centre `c` among `n` samples: c − M, shifted inwards within M
/// samples of either end (then the fit is evaluated off its centre). Needs n ≥ 2M+1.
inline std::size_t sg_window_first(std::size_t c, std::size_t n, std::size_t half_width) {
  if (c < half_width) return 0;
  if (c + half_width >= n) return n - 1 - 2 * half_width;
  return c - half_width;
}

/// The d-th derivative (d in 0..2) of a vector stream `values` at `times_s` (strictly
/// increasing, s; sizes equal, at least 2M+1 samples, else false and `out` untouched) into
/// `out`, per sample, by the local fit. For the IMU: the gyro differenced into ω̇ (d = 1) with
/// the same differentiator as the robot's. Allocation-free; O(N·M).
bool sg_differentiate(std::span<const double> times_s, std::span<const Eigen::Vector3d> values,
                      const SgSettings& s, int derivative, std::span<Eigen::Vector3d> out);

/// The classic SG coefficients c_{d,k}, k = −M..M (time in samples, h = 1), written to
/// `out[0..2M]`; `out` must hold 2M+1 values. Same fit as LocalPolyFit on τ_k = k.
void sg_coefficients(const SgSettings& s, int derivative, std::span<double> out);

/// Standard deviation of the d-th derivative estimate per unit of white noise on the samples,
/// uniform period `period_s`: sqrt(Σ c_{d,k}²) / h^d (units 1/s^d).
double sg_noise_gain(const SgSettings& s, int derivative, double period_s);

/// The −3 dB frequency (Hz) of the d-th derivative filter against the ideal (jω)^d, uniform
/// period `period_s`. Found by scanning up to Nyquist and bisecting; Nyquist if never −3 dB.
double sg_cutoff_hz(const SgSettings& s, int derivative, double period_s);

/// Delay of the causal use (the newest sample is the window's end): M·h (s).
double sg_causal_delay_s(const SgSettings& s, double period_s);

/// The widest window (least noise) whose d-th derivative still passes `bandwidth_hz`
/// (sg_cutoff_hz ≥ bandwidth_hz) at `period_s` with polynomial `order`. The smallest valid
/// window if even that one cuts below the bandwidth; kMaxHalfWidth at most.
SgSettings choose_sg_window(double period_s, double bandwidth_hz, int order = 3,
                            int derivative = 2);

}  // namespace zerog::robot
