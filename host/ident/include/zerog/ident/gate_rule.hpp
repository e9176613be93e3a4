#pragma once
// The contact gate's threshold from the measured noise (issue 28, item 4; `zerog gate`,
// docs/zerog-rt.md "Setting the contact gate"). zerog-rt confirms a push when the contact force
// (|F|), or the torque its torque gate judges (|M|, control::torque_gate_input: about the virtual
// centre of mass with a force above the force threshold, else the smaller of that and the
// torque about the sensor origin), stays above its threshold for contact_confirm_cycles cycles
// in a row (control::ContactGate). The lower the threshold, the gentler the push that moves the
// part, and the likelier the noise alone confirms one.
//
// The rule: from a recording of zerog-rt at rest in zero-g (cycles.csv; the cycles whose virtual
// body has not moved: no push was confirmed), the contact wrench's second moment (its mean
// included: a model offset is seen by the gate too) has principal variances λ₁, λ₂, λ₃ (σ² is
// their mean, reported); the norm exceeds t with p(t) = P(|x| > t), x ~ N(0, diag(λ)) (norm_tail;
// with equal axes the χ² tail Q₃(t²/σ²), Q₃(x) = erfc(√(x/2)) + √(2x/π) e^(−x/2)). Unequal axes
// matter: the torque about the centre of mass had z at half of x and y, and with the pooled σ
// the χ² tail was 2.4× too small at 4.2 σ (ten minutes at rest, docs/zerog-rt.md). `confirm`
// cycles in a row exceed t with p(t)^e: e = confirm for independent cycles. The cycles are not
// always independent (the IMU's differenced noise spans 5 cycles; an elastic arm rings over
// many): e comes from the recording, the smaller of the deep-tail exponent of a Gaussian noise
// with its correlation from cycle to cycle and the exponent of how often `confirm` consecutive
// cycles stay above moderate levels (gate_rule.cpp), and is smaller when runs are likelier. The
// threshold is the smallest t whose expected false confirms, cycles per hour × p(t)^e, stay
// below `false_per_hour` (default 0.01: one per 100 hours of zero-g). The recording is then
// replayed through zerog-rt's own gate (control::ContactGate) at the threshold (it must not
// confirm) and at the configured one.
#include <cstddef>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "zerog/loop/cycle_record.hpp"

namespace zerog::ident {

struct GateRuleOptions {
  Eigen::Vector3d com_sensor_m = Eigen::Vector3d::Zero();  ///< the virtual centre of mass in S
  int confirm_cycles = 3;                                  ///< contact_confirm_cycles
  double release_fraction = 0.5;                           ///< contact_release_fraction
  double false_per_hour = 0.01;
  double force_now_N = 2.0;  ///< the configured thresholds, replayed for comparison
  double torque_now_Nm = 0.3;
};

struct GateGroup {
  std::array<double, 3> rms{};  ///< per axis, the mean included
  double sigma = 0.0;           ///< sqrt(mean of rms²)
  /// The noise's principal standard deviations (√ of the eigenvalues of its second moment),
  /// smallest first: the norm's tail is that of these axes (norm_tail).
  std::array<double, 3> principal_sigma{};
  double lag1 = 0.0;  ///< lag-1 correlation of the norm over the cycles used
  /// The cycles in a row the rule counts: confirm_cycles if the recording's runs above
  /// moderate levels are as rare as independent cycles make them, fewer if they are not.
  double effective_confirm = 0.0;
  int levels_measured = 0;  ///< levels with enough windows above them to measure it
  /// The pooled autocorrelation of the three axes at lags 0 … confirm − 1 (0 where not
  /// significant).
  std::vector<double> correlation;
  double threshold = 0.0;                 ///< the rule's
  double false_per_hour = 0.0;            ///< expected at the threshold (independent cycles)
  std::size_t confirms_at_threshold = 0;  ///< replayed through the gate
  std::size_t confirms_now = 0;           ///< at the configured threshold
  /// Cycles the replayed gate was open (the noise driving the body), at each threshold.
  std::size_t open_cycles_at_threshold = 0, open_cycles_now = 0;
};

struct GateAdvice {
  bool known = false;
  std::string note;        ///< why not (too few cycles at rest)
  std::size_t cycles = 0;  ///< zero-g cycles at rest used
  double cycle_s = 0.0;    ///< median dt_s
  GateGroup force, torque;
};

/// At least this many zero-g cycles at rest.
inline constexpr std::size_t kMinGateCycles = 200;

GateAdvice gate_rule(const std::vector<loop::CycleRecord>& cycles, const GateRuleOptions& options);

/// Q₃(x): P(χ²₃ > x).
double chi2_3_tail(double x);
/// P(|x| > t) for x ~ N(0, diag(variances)) in three dimensions (a generalized χ² tail;
/// Q₃(t²/σ²) when all three are σ²): (1/4π) ∫ Q₃(t²/dᵀΛd) dΩ, 48 × 48-point Gauss–Legendre
/// over the sphere's octant.
double norm_tail(const Eigen::Vector3d& variances, double t);

std::string format_gate_advice(const GateAdvice& a, const GateRuleOptions& options);
nlohmann::json to_json(const GateAdvice& a, const GateRuleOptions& options);

}  // namespace zerog::ident
