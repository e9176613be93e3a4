#include "zerog/ident/servo_fit.hpp"

#include <ceres/ceres.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "zerog/loop/servo_model.hpp"

namespace zerog::ident {
namespace {

constexpr int kMaxLag = 4;
constexpr std::size_t kQuarters = 4;
constexpr double kMinHz = 0.3;
constexpr int kGridPoints = 60;
// Newton steps of the set point's inverse kinematics (the third changes nothing measurable).
constexpr int kNewtonSteps = 3;
// The fit may leave this fraction of the joints' steps (RMS) unexplained at most.
constexpr double kMaxUnexplained = 0.2;
// A recorded step of a joint this small is no command (RSI's 4 decimals of a degree).
constexpr double kNoCommand_rad = 1e-9;

// The recording as the servo model sees it: per row its measured joints and the increment the
// correction sent in reply commands; rows of one run follow each other by one cycle.
struct Rows {
  std::vector<std::array<double, robot::kMaxJoints>> q, dq;
  std::vector<std::size_t> run_start, run_end;  // per row: its run's [start, end)
  std::vector<std::size_t> compared;            // rows k whose steps are compared (all lags)
  int joints = 6;
  double cycle_s = 0.0;
};

// The measured step of joint u into row k + L (the row a reply at row k moves it into, for L = 2).
double measured_step(const Rows& rows, std::size_t k, int L, std::size_t u) {
  const std::size_t a = k + static_cast<std::size_t>(L);
  return rows.q[a][u] - rows.q[a - 1][u];
}

bool breaks_run(const loop::CycleRecord& r) {
  return (r.flags & (loop::kIpocGap | loop::kIpocStale | loop::kRobotLost)) != 0;
}

double median_period(const std::vector<loop::CycleRecord>& records) {
  std::vector<double> dt;
  for (std::size_t i = 1; i < records.size(); ++i) {
    const double d = records[i].t_s - records[i - 1].t_s;
    if (d > 0.0) dt.push_back(d);
  }
  if (dt.empty()) return 0.0;
  std::nth_element(dt.begin(), dt.begin() + static_cast<std::ptrdiff_t>(dt.size() / 2), dt.end());
  return dt[dt.size() / 2];
}

Rows make_rows(const std::vector<loop::CycleRecord>& records, const ServoFitOptions& options,
               ServoFit& fit) {
  Rows rows;
  rows.cycle_s = median_period(records);
  if (options.robot) rows.joints = std::min(options.robot->joint_count, 6);
  std::size_t start = 0;
  std::array<double, 6> set_point{};
  // Without the rig's robot only AKorr can be taken (RKorr is refused below): six joints, no
  // kinematics.
  robot::RobotModel axes_only;
  axes_only.joint_count = 6;
  for (std::size_t i = 0; i < records.size(); ++i) {
    const loop::CycleRecord& r = records[i];
    // A row more than 1.5 cycles after the last (or a lost, stale datagram) starts a new run.
    const bool new_run =
        i == 0 || breaks_run(r) || !(r.t_s - records[i - 1].t_s < 1.5 * rows.cycle_s);
    if (new_run) start = rows.q.size();
    if (r.reply.kind == samples::RobotCorrection::Kind::cartesian && !options.robot) {
      throw std::invalid_argument(
          "row " + std::to_string(i + 1) +
          ": zerog-rt sent a Cartesian correction (RKorr), and the servo model needs the "
          "robot's kinematics to turn it into joint increments: give the rig that describes the "
          "robot (run.rig.toml beside cycles.csv, or --rig)");
    }
    // The controller's set point, accumulated from the joints at the run's start (at rest
    // when zero-g starts) by each correction's exact inverse kinematics, as the controller
    // applies it to its set point: first-order steps from the measured joints were off by the
    // servo's lag times the step (4e-5 rad a row on the 0.5 m/s glide, the size of what is
    // measured here).
    if (new_run) set_point = r.joints_rad;
    Eigen::Matrix<double, robot::kMaxJoints, 1> dq;
    loop::commanded_increment(options.robot ? *options.robot : axes_only, r.reply, set_point, dq,
                              kNewtonSteps);
    for (int j = 0; j < 6; ++j) set_point[static_cast<std::size_t>(j)] += dq[j];
    std::array<double, robot::kMaxJoints> q{}, d{};
    for (int j = 0; j < rows.joints; ++j) {
      q[static_cast<std::size_t>(j)] = r.joints_rad[static_cast<std::size_t>(j)];
      d[static_cast<std::size_t>(j)] = dq[j];
      fit.max_command_rad = std::max(fit.max_command_rad, std::abs(dq[j]));
    }
    rows.q.push_back(q);
    rows.dq.push_back(d);
    rows.run_start.push_back(start);
  }
  rows.run_end.resize(rows.q.size());
  for (std::size_t k = rows.q.size(); k-- > 0;) {
    const bool last = k + 1 == rows.q.size() || rows.run_start[k + 1] != rows.run_start[k];
    rows.run_end[k] = last ? k + 1 : rows.run_end[k + 1];
    if (last) ++fit.runs;
  }
  for (std::size_t k = 0; k < rows.q.size(); ++k) {
    if (k >= rows.run_start[k] + 1 && k + kMaxLag < rows.run_end[k]) rows.compared.push_back(k);
  }
  fit.joints = rows.joints;
  fit.cycle_s = rows.cycle_s;
  return rows;
}

// The model's step of each joint into each row: the servo model (hz > 0) or the set point
// itself (hz = 0, the instant servo), restarted at each run.
std::vector<std::array<double, robot::kMaxJoints>> model_steps(const Rows& rows, double hz) {
  std::vector<std::array<double, robot::kMaxJoints>> steps(rows.q.size());
  loop::ServoModel servo;
  servo.configure(hz);
  std::array<double, robot::kMaxJoints> last{};
  for (std::size_t k = 0; k < rows.q.size(); ++k) {
    if (rows.run_start[k] == k) {
      servo.reset();
      last = {};
    }
    if (hz > 0.0) {
      servo.advance(rows.dq[k], rows.joints, static_cast<double>(k) * rows.cycle_s, rows.cycle_s);
    }
    for (int j = 0; j < rows.joints; ++j) {
      const std::size_t u = static_cast<std::size_t>(j);
      const double angle = hz > 0.0 ? servo.angle(j) : last[u] + rows.dq[k][u];
      steps[k][u] = angle - last[u];
      last[u] = angle;
    }
  }
  return steps;
}

// Sums of squared residuals per lag (index L − 1) and quarter of the compared rows.
struct Sums {
  std::array<std::array<double, kQuarters>, kMaxLag> s{};
  double lag(int L) const {
    double t = 0.0;
    for (double v : s[static_cast<std::size_t>(L - 1)]) t += v;
    return t;
  }
};

std::size_t quarter_of(std::size_t index, std::size_t n) {
  return std::min(kQuarters - 1, index * kQuarters / std::max<std::size_t>(n, 1));
}

Sums residual_sums(const Rows& rows, const std::vector<std::array<double, robot::kMaxJoints>>& m) {
  Sums sums;
  const std::size_t n = rows.compared.size();
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t k = rows.compared[i];
    for (int L = 1; L <= kMaxLag; ++L) {
      double e2 = 0.0;
      for (int j = 0; j < rows.joints; ++j) {
        const std::size_t u = static_cast<std::size_t>(j);
        const double e = measured_step(rows, k, L, u) - m[k][u];
        e2 += e * e;
      }
      sums.s[static_cast<std::size_t>(L - 1)][quarter_of(i, n)] += e2;
    }
  }
  return sums;
}

// Ceres' residuals for log f at lag L over the compared rows of one quarter (or all).
struct StepResiduals {
  const Rows* rows;
  int lag;
  std::size_t first, count;  // indices into rows->compared
  bool operator()(double const* const* p, double* out) const {
    const auto m = model_steps(*rows, std::exp(p[0][0]));
    for (std::size_t i = 0; i < count; ++i) {
      const std::size_t k = rows->compared[first + i];
      for (int j = 0; j < rows->joints; ++j) {
        const std::size_t u = static_cast<std::size_t>(j);
        out[i * static_cast<std::size_t>(rows->joints) + u] =
            measured_step(*rows, k, lag, u) - m[k][u];
      }
    }
    return true;
  }
};

double refine(const Rows& rows, int lag, std::size_t first, std::size_t count, double hz0,
              double hz_max) {
  double log_hz = std::log(hz0);
  auto* cost = new ceres::DynamicNumericDiffCostFunction<StepResiduals, ceres::CENTRAL>(
      new StepResiduals{&rows, lag, first, count});
  cost->AddParameterBlock(1);
  cost->SetNumResiduals(static_cast<int>(count) * rows.joints);
  ceres::Problem problem;
  problem.AddResidualBlock(cost, nullptr, &log_hz);
  problem.SetParameterLowerBound(&log_hz, 0, std::log(kMinHz));
  problem.SetParameterUpperBound(&log_hz, 0, std::log(hz_max));
  ceres::Solver::Options o;
  o.max_num_iterations = 30;
  o.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(o, &problem, &summary);
  return std::exp(log_hz);
}

double rms_of(double sum, std::size_t terms) {
  return terms > 0 ? std::sqrt(sum / static_cast<double>(terms)) : 0.0;
}

std::string hz_text(double hz) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", hz);
  return b;
}

// RMS of the measured joints' steps over the compared rows (at the model's lag).
double motion_rms(const Rows& rows) {
  double m2 = 0.0;
  for (std::size_t k : rows.compared)
    for (std::size_t j = 0; j < static_cast<std::size_t>(rows.joints); ++j) {
      const double d = measured_step(rows, k, ServoFit::kModelLag, j);
      m2 += d * d;
    }
  return rms_of(m2, rows.compared.size() * static_cast<std::size_t>(rows.joints));
}

// The quarters of the compared rows, each fitted alone at the lag found; the excited ones' fits
// give the spread quoted. Returns how many were excited.
std::size_t fit_quarters(const Rows& rows, const std::vector<double>& grid,
                         const std::vector<Sums>& sums, const Sums& instant, ServoFit& fit) {
  const std::size_t n = rows.compared.size();
  const int best_L = fit.lag_rows;
  const std::size_t Li = static_cast<std::size_t>(best_L - 1);
  std::vector<double> excited;
  for (std::size_t q = 0; q < kQuarters; ++q) {
    ServoQuarter quarter;
    quarter.first_row = q * n / kQuarters;
    quarter.rows = (q + 1) * n / kQuarters - quarter.first_row;
    std::size_t bi = 0;
    for (std::size_t i = 0; i < grid.size(); ++i)
      if (sums[i].s[Li][q] < sums[bi].s[Li][q]) bi = i;
    const double inst = instant.s[Li][q];
    quarter.excited = inst > 0.0 && (inst - sums[bi].s[Li][q]) >= kMinGain * inst;
    if (quarter.excited) {
      quarter.hz = refine(rows, best_L, quarter.first_row, quarter.rows, grid[bi], fit.hz_max);
      excited.push_back(quarter.hz);
    }
    fit.quarters.push_back(quarter);
  }
  if (!excited.empty()) {
    fit.hz_lo = *std::min_element(excited.begin(), excited.end());
    fit.hz_hi = *std::max_element(excited.begin(), excited.end());
  }
  if (excited.size() >= 2) {
    double mean = 0.0, var = 0.0;
    for (double v : excited) mean += v / static_cast<double>(excited.size());
    for (double v : excited)
      var += (v - mean) * (v - mean) / (static_cast<double>(excited.size()) - 1.0);
    fit.hz_sigma = std::sqrt(var / static_cast<double>(excited.size()));
  }

  return excited.size();
}

}  // namespace

ServoFit fit_servo(const std::vector<loop::CycleRecord>& records, const ServoFitOptions& options) {
  ServoFit fit;
  fit.records = records.size();
  fit.hz = std::numeric_limits<double>::quiet_NaN();
  fit.hz_sigma = fit.hz;
  const Rows rows = make_rows(records, options, fit);
  const std::size_t n = rows.compared.size();
  fit.rows = n;
  if (!(rows.cycle_s > 0.0) || n < kMinServoRows) {
    fit.note = "too short: " + std::to_string(n) + " rows to compare (at least " +
               std::to_string(kMinServoRows) +
               "): record a few seconds of zero-g in which the part is pushed";
    return fit;
  }
  if (fit.max_command_rad < kNoCommand_rad) {
    fit.note =
        "zerog-rt commanded no motion in this recording (every correction zero): record zero-g "
        "while someone pushes the part, starts and stops it";
    return fit;
  }
  fit.hz_max = 0.5 / rows.cycle_s;
  const std::size_t terms = n * static_cast<std::size_t>(rows.joints);

  // The grid: every f once, every lag and quarter from that one run of the model.
  std::vector<double> grid;
  for (int i = 0; i < kGridPoints; ++i)
    grid.push_back(kMinHz * std::pow(fit.hz_max / kMinHz, i / (kGridPoints - 1.0)));
  std::vector<Sums> sums;
  for (double hz : grid) sums.push_back(residual_sums(rows, model_steps(rows, hz)));
  const Sums instant = residual_sums(rows, model_steps(rows, 0.0));

  // Each lag's best grid point refined; the lag of the smallest residual after refinement (on
  // the grid alone a slow servo one tick later can look better than the right one).
  int best_L = 1;
  double best_sum = std::numeric_limits<double>::infinity();
  for (int L = 1; L <= kMaxLag; ++L) {
    std::size_t bi = 0;
    for (std::size_t i = 0; i < grid.size(); ++i)
      if (sums[i].lag(L) < sums[bi].lag(L)) bi = i;
    const double hz = refine(rows, L, 0, n, grid[bi], fit.hz_max);
    const double sum = residual_sums(rows, model_steps(rows, hz)).lag(L);
    fit.lag_rms_rad.push_back(rms_of(sum, terms));
    if (sum < best_sum) {
      best_sum = sum;
      best_L = L;
      fit.hz = hz;
    }
  }
  fit.lag_rows = best_L;
  fit.motion_rms_rad = motion_rms(rows);
  fit.best = {fit.hz, rms_of(best_sum, terms)};
  fit.instant = {0.0, rms_of(instant.lag(best_L), terms)};
  if (options.configured_hz > 0.0) {
    fit.configured = {
        options.configured_hz,
        rms_of(
            residual_sums(rows, model_steps(rows, options.configured_hz)).lag(ServoFit::kModelLag),
            terms)};
  }

  const std::size_t excited = fit_quarters(rows, grid, sums, instant, fit);

  const double gain =
      (fit.instant.rms_rad * fit.instant.rms_rad - fit.best.rms_rad * fit.best.rms_rad) /
      (fit.instant.rms_rad * fit.instant.rms_rad);
  if (!(gain >= kMinGain)) {
    fit.note =
        "cannot tell: an instant servo explains the joints' steps about as well (the "
        "bandwidth lowers their residual by " +
        std::to_string(static_cast<int>(std::lround(100 * gain))) +
        " %): the commanded rate hardly changed; record pushes that start and stop the "
        "part";
  } else if (fit.hz < 1.05 * kMinHz) {
    fit.note = "cannot tell: the joints hardly followed the corrections (a servo slower than " +
               hz_text(kMinHz) +
               " Hz fits best): was the controller stopped, or the corrections not applied?";
  } else if (fit.best.rms_rad > kMaxUnexplained * fit.motion_rms_rad) {
    fit.note =
        "cannot tell: the servo model leaves " +
        std::to_string(static_cast<int>(std::lround(100 * fit.best.rms_rad / fit.motion_rms_rad))) +
        " % of the joints' motion unexplained, so the robot does not move as one "
        "critically damped servo; leave servo_hz off";
  } else if (fit.hz > 0.95 * fit.hz_max) {
    fit.note = "cannot tell: the servo is faster than half the cycle rate (" + hz_text(fit.hz_max) +
               " Hz), which the rows cannot tell from an instant one";
  } else if (best_L != ServoFit::kModelLag) {
    fit.note = "the joints follow a correction answered at row k from row k + " +
               std::to_string(best_L - 1) + " to k + " + std::to_string(best_L) +
               ", and zerog-rt's servo model assumes k + 1 to k + 2: leave servo_hz off (at "
               "this lag the bandwidth would be " +
               hz_text(fit.hz) + " Hz)";
  } else if (excited >= 2 && fit.hz_hi > kMaxQuarterRatio * fit.hz_lo) {
    fit.note = "cannot tell: the quarters of the recording give " + hz_text(fit.hz_lo) + "–" +
               hz_text(fit.hz_hi) +
               " Hz, so the robot does not move as one critically damped servo; leave servo_hz "
               "off";
  } else {
    fit.known = true;
    if (excited < 2) {
      fit.note =
          "only one quarter of the recording starts or stops the part: no spread to "
          "quote; record more pushes for an uncertainty";
    }
  }
  return fit;
}

std::string format_servo_fit(const ServoFit& f) {
  char b[512];
  std::string out;
  std::snprintf(b, sizeof b,
                "rows: %zu compared (%zu records, %zu run%s, %.3g ms cycles, %d joints); largest "
                "commanded step %.3g rad\n",
                f.rows, f.records, f.runs, f.runs == 1 ? "" : "s", 1e3 * f.cycle_s, f.joints,
                f.max_command_rad);
  out += b;
  if (f.lag_rms_rad.empty()) return out + "servo: " + f.note + "\n";
  out += "joint-step residual RMS at each lag's best fit (L = 1..4):";
  for (double v : f.lag_rms_rad) {
    std::snprintf(b, sizeof b, " %.3g", v);
    out += b;
  }
  std::snprintf(b, sizeof b, " rad; L = %d%s\n", f.lag_rows,
                f.lag_rows == ServoFit::kModelLag ? " (as zerog-rt's servo model assumes)" : "");
  out += b;
  std::snprintf(b, sizeof b, "bandwidth: %.4g Hz", f.hz);
  out += b;
  if (std::isfinite(f.hz_sigma)) {
    std::snprintf(b, sizeof b, " ± %.2g (quarters %.4g–%.4g Hz)", f.hz_sigma, f.hz_lo, f.hz_hi);
    out += b;
  }
  int excited = 0;
  for (const ServoQuarter& q : f.quarters) excited += q.excited ? 1 : 0;
  std::snprintf(b, sizeof b, "; %d of %zu quarters excited; the rows tell up to %.3g Hz\n", excited,
                f.quarters.size(), f.hz_max);
  out += b;
  std::snprintf(b, sizeof b, "residual RMS: %.3g rad at the fit, %.3g rad with an instant servo",
                f.best.rms_rad, f.instant.rms_rad);
  out += b;
  if (f.configured.hz > 0.0) {
    std::snprintf(b, sizeof b, ", %.3g rad at the configured %.3g Hz", f.configured.rms_rad,
                  f.configured.hz);
    out += b;
  }
  out += "\n";
  if (f.known) out += "set [filter] servo_hz = " + hz_text(f.hz) + " in zerog-rt's configuration\n";
  if (!f.note.empty()) out += (f.known ? "note: " : "servo: ") + f.note + "\n";
  return out;
}

nlohmann::json to_json(const ServoFit& f) {
  auto num = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); };
  nlohmann::json quarters = nlohmann::json::array();
  for (const ServoQuarter& q : f.quarters) {
    quarters.push_back({{"first_row", q.first_row},
                        {"rows", q.rows},
                        {"excited", q.excited},
                        {"hz", q.excited ? num(q.hz) : nlohmann::json()}});
  }
  return {{"known", f.known},
          {"note", f.note},
          {"records", f.records},
          {"rows", f.rows},
          {"runs", f.runs},
          {"cycle_s", f.cycle_s},
          {"joints", f.joints},
          {"max_command_rad", f.max_command_rad},
          {"motion_rms_rad", f.motion_rms_rad},
          {"lag_rows", f.lag_rows},
          {"model_lag_rows", ServoFit::kModelLag},
          {"lag_rms_rad", f.lag_rms_rad},
          {"servo_hz", num(f.hz)},
          {"servo_hz_sigma", num(f.hz_sigma)},
          {"quarters_hz", {num(f.hz_lo), num(f.hz_hi)}},
          {"hz_max", f.hz_max},
          {"rms_rad",
           {{"fit", f.best.rms_rad},
            {"instant", f.instant.rms_rad},
            {"configured", f.configured.hz > 0.0 ? num(f.configured.rms_rad) : nlohmann::json()},
            {"configured_hz", f.configured.hz}}},
          {"quarters", quarters}};
}

}  // namespace zerog::ident
