// `zerog design`: path points for an identification run (orthogonal array, random or Sobol),
// with coverage and conditioning figures to compare kinds.
#include <cmath>
#include <cstdio>
#include <memory>
#include <numbers>
#include <string>
#include <vector>

#include "commands.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/trajectory.hpp"

namespace zerog::cli {
namespace {

struct DesignArgs {
  std::string kind = "oa";
  int points = 0;
  int levels = 11;
  std::uint64_t seed = 1;
  std::string out;
  double floor_z_m = -0.675;
  double clearance_m = 0.175;
  double speed_fraction = 0.3;
  double dwell_s = 2.0;
  double period_s = 0.012;
  bool compare = false;
  std::string attitudes;
  // Forearm along +y_B, 35° below horizontal: reaches all 15 attitudes of 001_… Appendix C with
  // |A5| ≤ 101° (a scan of A1..A3 in 5° steps; from home, 5, 7 and 15 need |A5| > 120°).
  std::vector<double> arm_deg = {-90.0, -80.0, 125.0};
};

sim::DesignOptions options_for(const DesignArgs& a, sim::DesignKind kind) {
  sim::DesignOptions o;
  o.kind = kind;
  o.levels = a.levels;
  o.points = a.points;
  if (kind != sim::DesignKind::oa && o.points == 0) o.points = a.levels * a.levels;
  if (kind == sim::DesignKind::oa && a.compare) o.points = 0;
  o.seed = a.seed;
  o.workspace.floor_z_m = a.floor_z_m;
  o.workspace.clearance_m = a.clearance_m;
  return o;
}

void print_figures(const sim::Design& d, const sim::Workspace& ws, const DesignArgs& a) {
  const sim::DesignMetrics m = sim::design_metrics(d.points_rad, ws, d.levels);
  const sim::PtpTrajectory traj(d.points_rad, sim::kr210_ptp_limits(a.speed_fraction), a.dwell_s);
  std::printf(
      "design %s: %zu points (%d candidates, %d dropped: below floor %.3f m + %.3f m "
      "clearance)\n",
      sim::design_kind_name(d.kind), d.points_rad.size(), d.candidates, d.rejected, ws.floor_z_m,
      ws.clearance_m);
  std::printf(
      "  coverage: %dx%d level-pair bins per joint pair covered: min %.1f %%, mean %.1f %%"
      " (15 pairs)\n",
      m.levels, m.levels, 100.0 * m.pair_coverage_min, 100.0 * m.pair_coverage_mean);
  std::printf(
      "  spread: min distance %.4f, mean nearest-neighbour distance %.4f "
      "(joint ranges scaled to [0,1]^6)\n",
      m.min_distance, m.mean_nearest_distance);
  std::printf(
      "  conditioning: cond2(A*D) = %.3g; A stacks [I3 0 g_S 0; 0 I3 0 -[g_S]x] per pose "
      "(unknowns F0, M0, m, m*c), D scales columns to unit norm\n",
      m.condition_number);
  std::printf(
      "  run: %.1f s (%.1f min) at %.0f %% speed with %.1f s dwells, ~%.0f samples at "
      "%.3f s\n",
      traj.duration_s(), traj.duration_s() / 60.0, 100.0 * a.speed_fraction, a.dwell_s,
      std::floor(traj.duration_s() / a.period_s) + 1.0, a.period_s);
}

// Static poses from sensor attitudes (e.g. calib/poses/001_appendix_c_attitudes.csv) by the
// wrist's inverse kinematics, A1..A3 held at --arm.
void run_attitude_design(const DesignArgs& a) {
  if (a.out.empty()) throw std::invalid_argument("--out is required");
  constexpr double kDeg = std::numbers::pi / 180.0;
  sim::AttitudeDesignOptions o;
  for (int j = 0; j < 3; ++j) o.arm_rad[j] = a.arm_deg[j] * kDeg;
  o.workspace.floor_z_m = a.floor_z_m;
  o.workspace.clearance_m = a.clearance_m;
  const auto rotvecs = sim::read_attitudes(a.attitudes);
  const sim::AttitudeDesign ad = sim::design_from_attitudes(rotvecs, o);
  std::printf("arm A1..A3 = %.1f, %.1f, %.1f deg; %zu attitudes from %s (R_base_sensor = Exp(r))\n",
              a.arm_deg[0], a.arm_deg[1], a.arm_deg[2], rotvecs.size(), a.attitudes.c_str());
  std::printf("  %3s  %7s %7s %7s   %7s %7s %7s  (deg)\n", "#", "A4", "A5", "A6", "rx", "ry", "rz");
  for (std::size_t k = 0; k < ad.design.points_rad.size(); ++k) {
    const sim::JointVector& q = ad.design.points_rad[k];
    const Eigen::Vector3d& r = rotvecs[static_cast<std::size_t>(ad.attitude_index[k])];
    std::printf("  %3d  %7.1f %7.1f %7.1f   %7.4f %7.4f %7.4f\n", ad.attitude_index[k] + 1,
                q[3] / kDeg, q[4] / kDeg, q[5] / kDeg, r.x(), r.y(), r.z());
  }
  for (const auto& [index, why] : ad.unreachable)
    std::printf("  %3d  cannot be reached: %s\n", index + 1, why.c_str());
  if (ad.design.points_rad.empty())
    throw std::runtime_error("no attitude can be reached from this arm pose; try another --arm");
  sim::write_design(ad.design, a.out, {a.attitudes});
  const sim::PtpTrajectory traj(ad.design.points_rad, sim::kr210_ptp_limits(a.speed_fraction),
                                a.dwell_s);
  const sim::DesignMetrics m = sim::design_metrics(ad.design.points_rad, o.workspace, a.levels);
  std::printf(
      "%zu of %zu attitudes reached; conditioning cond2(A*D) = %.3g (bias + gravity); run %.1f s "
      "at %.0f %% speed with %.1f s dwells\n",
      ad.design.points_rad.size(), rotvecs.size(), m.condition_number, traj.duration_s(),
      100.0 * a.speed_fraction, a.dwell_s);
  std::printf("wrote %s\n", a.out.c_str());
}

void run_design(const DesignArgs& a) {
  if (!a.attitudes.empty()) {
    run_attitude_design(a);
    return;
  }
  if (a.compare) {
    for (sim::DesignKind k :
         {sim::DesignKind::oa, sim::DesignKind::random, sim::DesignKind::sobol}) {
      const sim::DesignOptions o = options_for(a, k);
      print_figures(sim::make_design(o), o.workspace, a);
    }
    return;
  }
  const auto kind = sim::design_kind_from_name(a.kind);
  if (!kind) throw std::invalid_argument("unknown design kind '" + a.kind + "'");
  if (a.out.empty()) throw std::invalid_argument("--out is required (or use --compare)");
  const sim::DesignOptions o = options_for(a, *kind);
  const sim::Design d = sim::make_design(o);
  sim::write_design(d, a.out);
  print_figures(d, o.workspace, a);
  std::printf("wrote %s\n", a.out.c_str());
}

}  // namespace

void add_design_command(CLI::App& app) {
  auto args = std::make_shared<DesignArgs>();
  CLI::App* cmd = app.add_subcommand(
      "design",
      "Path points for an identification run: orthogonal array (Bose OA(p^2, p+1, p, 2)), uniform "
      "random or Sobol points over the joint ranges of paper 000 Table 4, infeasible points "
      "(below the floor) dropped. Writes a design CSV (proto/design_format.md) and prints "
      "coverage and conditioning figures.");
  cmd->add_option("--kind", args->kind, "oa | random | sobol")
      ->check(CLI::IsMember({"oa", "random", "sobol"}))
      ->capture_default_str();
  cmd->add_option("--points", args->points,
                  "number of points (oa: must be levels^2; default levels^2)");
  cmd->add_option("--levels", args->levels,
                  "oa: levels per joint, a prime >= 5 (11 gives 121 points); also the bin count "
                  "of the coverage figure")
      ->capture_default_str();
  cmd->add_option("--seed", args->seed,
                  "random: the points; sobol: a random digital shift (0 = plain Sobol); oa: unused")
      ->capture_default_str();
  cmd->add_option("--out", args->out, "design CSV to write (atomically)");
  cmd->add_option("--floor-z", args->floor_z_m, "floor height in the base frame, m")
      ->capture_default_str();
  cmd->add_option(
         "--clearance", args->clearance_m,
         "height above the floor the wrist, flange, sensor and payload sphere must keep, m")
      ->capture_default_str();
  cmd->add_option("--speed", args->speed_fraction,
                  "speed override for the run-time estimate (fraction of axis speeds)")
      ->check(CLI::Range(0.01, 1.0))
      ->capture_default_str();
  cmd->add_option("--dwell", args->dwell_s, "dwell at each point for the run-time estimate, s")
      ->capture_default_str();
  cmd->add_option("--period", args->period_s, "sample period for the sample-count estimate, s")
      ->capture_default_str();
  auto* compare = cmd->add_flag(
      "--compare", args->compare,
      "print the figures of all three kinds (same --points and --seed), write nothing");
  cmd->add_option("--attitudes", args->attitudes,
                  "static poses from sensor attitudes instead: CSV of rotation vectors rx_rad, "
                  "ry_rad, rz_rad of the sensor frame in the base frame (e.g. "
                  "calib/poses/001_appendix_c_attitudes.csv); A4..A6 by the wrist's inverse "
                  "kinematics, A1..A3 at --arm")
      ->check(CLI::ExistingFile)
      ->excludes(compare);
  cmd->add_option("--arm", args->arm_deg,
                  "with --attitudes: A1,A2,A3 held for every pose, degrees (as on the pendant)")
      ->expected(3)
      ->delimiter(',')
      ->capture_default_str();
  cmd->callback([args]() { run_design(*args); });
}

}  // namespace zerog::cli
