#include "zerog/sim/design.hpp"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "random.hpp"
#include "zerog/formats/design_csv.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/model/effects.hpp"
#include "zerog/model/rotation.hpp"

namespace zerog::sim {
namespace {

bool is_prime(int n) {
  if (n < 2) return false;
  for (int d = 2; d * d <= n; ++d)
    if (n % d == 0) return false;
  return true;
}

JointVector from_unit(const std::array<double, 6>& u, const JointLimits& lim) {
  JointVector q{};
  for (int j = 0; j < 6; ++j)
    q[j] = lim.lower_rad[j] + u[j] * (lim.upper_rad[j] - lim.lower_rad[j]);
  return q;
}

std::array<double, 6> to_unit(const JointVector& q, const JointLimits& lim) {
  std::array<double, 6> u{};
  for (int j = 0; j < 6; ++j)
    u[j] = (q[j] - lim.lower_rad[j]) / (lim.upper_rad[j] - lim.lower_rad[j]);
  return u;
}

// Joe & Kuo (2008), new-joe-kuo-6.21201, dimensions 2..6 (dimension 1 is van der Corput):
// degree s, coefficient bits a (interior bits of the primitive polynomial), initial m_1..m_s.
struct SobolDim {
  int s;
  unsigned a;
  std::array<unsigned, 4> m;
};
constexpr SobolDim kSobolDims[5] = {
    {1, 0, {1, 0, 0, 0}}, {2, 1, {1, 3, 0, 0}}, {3, 1, {1, 3, 1, 0}},
    {3, 2, {1, 1, 1, 0}}, {4, 1, {1, 1, 3, 3}},
};

using DirectionTable = std::array<std::array<std::uint32_t, 32>, 6>;

DirectionTable make_direction_numbers() {
  DirectionTable v{};
  for (int k = 0; k < 32; ++k) v[0][k] = std::uint32_t{1} << (31 - k);
  for (int d = 1; d < 6; ++d) {
    const SobolDim& sd = kSobolDims[d - 1];
    for (int k = 0; k < 32; ++k) {
      if (k < sd.s) {
        v[d][k] = sd.m[k] << (31 - k);
      } else {
        std::uint32_t x = v[d][k - sd.s] ^ (v[d][k - sd.s] >> sd.s);
        for (int i = 1; i < sd.s; ++i)
          if ((sd.a >> (sd.s - 1 - i)) & 1u) x ^= v[d][k - i];
        v[d][k] = x;
      }
    }
  }
  return v;
}

}  // namespace

const char* design_kind_name(DesignKind kind) {
  switch (kind) {
    case DesignKind::oa:
      return "oa";
    case DesignKind::random:
      return "random";
    case DesignKind::sobol:
      return "sobol";
    case DesignKind::attitudes:
      return "attitudes";
  }
  return "?";
}

std::optional<DesignKind> design_kind_from_name(std::string_view name) {
  for (DesignKind k :
       {DesignKind::oa, DesignKind::random, DesignKind::sobol, DesignKind::attitudes})
    if (name == design_kind_name(k)) return k;
  return std::nullopt;
}

double lowest_point_z(const JointVector& q_rad, const Workspace& ws) {
  const robot::Pose f = robot::flange_pose(kr210(), q_rad);
  const Eigen::Vector3d z_flange = f.R.col(2);
  const Eigen::Vector3d wrist = f.p_m - kr210().joints[5].d_m * z_flange;
  const Eigen::Vector3d sensor = f.p_m + f.R * ws.p_flange_sensor_m;
  const Eigen::Vector3d com = sensor + f.R * ws.R_flange_sensor * ws.com_sensor_m;
  return std::min({wrist.z(), f.p_m.z(), sensor.z(), com.z() - ws.payload_radius_m});
}

bool within_limits(const JointVector& q_rad, const JointLimits& limits) {
  for (int j = 0; j < 6; ++j)
    if (!(q_rad[j] >= limits.lower_rad[j] - 1e-12 && q_rad[j] <= limits.upper_rad[j] + 1e-12))
      return false;
  return true;
}

bool is_feasible(const JointVector& q_rad, const Workspace& ws) {
  return within_limits(q_rad, ws.limits) &&
         lowest_point_z(q_rad, ws) >= ws.floor_z_m + ws.clearance_m;
}

std::vector<std::vector<int>> bose_oa(int p) {
  if (!is_prime(p)) throw std::invalid_argument("Bose OA needs a prime number of levels");
  std::vector<std::vector<int>> rows;
  rows.reserve(static_cast<std::size_t>(p * p));
  for (int a = 0; a < p; ++a) {
    for (int b = 0; b < p; ++b) {
      std::vector<int> row(static_cast<std::size_t>(p + 1));
      for (int j = 0; j < p; ++j) row[j] = (a + j * b) % p;
      row[p] = b;
      rows.push_back(std::move(row));
    }
  }
  return rows;
}

std::array<double, 6> sobol_point(std::uint32_t index) {
  static const DirectionTable v = make_direction_numbers();
  const std::uint32_t gray = index ^ (index >> 1);
  std::array<double, 6> x{};
  for (int d = 0; d < 6; ++d) {
    std::uint32_t acc = 0;
    for (int k = 0; k < 32; ++k)
      if ((gray >> k) & 1u) acc ^= v[d][k];
    x[d] = static_cast<double>(acc) * 0x1.0p-32;
  }
  return x;
}

Design make_design(const DesignOptions& opt) {
  Design d;
  d.kind = opt.kind;
  d.seed = opt.seed;
  d.levels = opt.levels;
  if (opt.kind == DesignKind::attitudes)
    throw std::invalid_argument(
        "attitudes: designs from attitudes come from design_from_attitudes");
  const JointLimits& lim = opt.workspace.limits;
  auto consider = [&](const JointVector& q) {
    ++d.candidates;
    if (is_feasible(q, opt.workspace)) {
      d.points_rad.push_back(q);
    } else {
      ++d.rejected;
    }
  };
  if (opt.kind == DesignKind::oa) {
    const int p = opt.levels;
    if (!is_prime(p) || p < 5)
      throw std::invalid_argument("oa: --levels must be a prime ≥ 5 (Bose construction)");
    if (opt.points != 0 && opt.points != p * p)
      throw std::invalid_argument(
          "oa: the Bose array has exactly levels² = " + std::to_string(p * p) +
          " rows; use --points " + std::to_string(p * p) + " or change --levels");
    for (const auto& row : bose_oa(p)) {
      std::array<double, 6> u{};
      for (int j = 0; j < 6; ++j) {
        const int col = kOaColumns[j] < 0 ? p : kOaColumns[j];
        const int level = j == 0 ? (p - 1) / 2 * row[col] % p : row[col];
        u[j] = static_cast<double>(level) / (p - 1);
      }
      consider(from_unit(u, lim));
    }
    return d;
  }
  if (opt.points < 1) throw std::invalid_argument("--points must be at least 1");
  const long max_candidates = 100L * opt.points;
  if (opt.kind == DesignKind::random) {
    detail::Rng rng(opt.seed, 1);
    while (static_cast<int>(d.points_rad.size()) < opt.points && d.candidates < max_candidates) {
      std::array<double, 6> u{};
      for (double& x : u) x = rng.uniform();
      consider(from_unit(u, lim));
    }
  } else {
    std::array<std::uint32_t, 6> shift{};
    if (opt.seed != 0) {
      detail::Rng rng(opt.seed, 2);
      for (auto& s : shift) s = static_cast<std::uint32_t>(rng.bits() >> 32);
    }
    // Index 0 is the origin (every joint at its lower limit); start at 1.
    for (std::uint32_t i = 1;
         static_cast<int>(d.points_rad.size()) < opt.points && d.candidates < max_candidates; ++i) {
      std::array<double, 6> u = sobol_point(i);
      for (int j = 0; j < 6; ++j) {
        const auto bitsj = static_cast<std::uint32_t>(u[j] * 0x1.0p32);
        u[j] = static_cast<double>(bitsj ^ shift[j]) * 0x1.0p-32;
      }
      consider(from_unit(u, lim));
    }
  }
  if (static_cast<int>(d.points_rad.size()) < opt.points)
    throw std::runtime_error("only " + std::to_string(d.points_rad.size()) + " of " +
                             std::to_string(opt.points) + " feasible points in " +
                             std::to_string(d.candidates) + " candidates; relax the floor");
  return d;
}

DesignMetrics design_metrics(const std::vector<JointVector>& points, const Workspace& ws,
                             int levels) {
  DesignMetrics m;
  m.points = static_cast<int>(points.size());
  m.levels = levels;
  if (points.empty()) return m;
  std::vector<std::array<double, 6>> unit;
  std::vector<std::array<int, 6>> bins;
  for (const auto& q : points) {
    unit.push_back(to_unit(q, ws.limits));
    std::array<int, 6> b{};
    for (int j = 0; j < 6; ++j)
      b[j] = std::clamp(static_cast<int>(std::floor(unit.back()[j] * levels)), 0, levels - 1);
    bins.push_back(b);
  }
  // Pair coverage.
  m.pair_coverage_min = 1.0;
  double sum = 0.0;
  int pairs = 0;
  for (int j = 0; j < 6; ++j) {
    for (int k = j + 1; k < 6; ++k) {
      std::vector<char> seen(static_cast<std::size_t>(levels * levels), 0);
      for (const auto& b : bins) seen[static_cast<std::size_t>(b[j] * levels + b[k])] = 1;
      const double frac =
          static_cast<double>(std::count(seen.begin(), seen.end(), 1)) / (levels * levels);
      m.pair_coverage_min = std::min(m.pair_coverage_min, frac);
      sum += frac;
      ++pairs;
    }
  }
  m.pair_coverage_mean = sum / pairs;
  // Distances in the unit cube.
  m.min_distance = std::numeric_limits<double>::infinity();
  double nn_sum = 0.0;
  for (std::size_t i = 0; i < unit.size(); ++i) {
    double nn = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < unit.size(); ++k) {
      if (k == i) continue;
      double d2 = 0.0;
      for (int j = 0; j < 6; ++j) d2 += (unit[i][j] - unit[k][j]) * (unit[i][j] - unit[k][j]);
      nn = std::min(nn, std::sqrt(d2));
    }
    m.min_distance = std::min(m.min_distance, nn);
    nn_sum += nn;
  }
  m.mean_nearest_distance = unit.size() > 1 ? nn_sum / static_cast<double>(unit.size()) : 0.0;
  if (unit.size() < 2) m.min_distance = 0.0;
  // Static regressor for bias + m g + m c.
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(6 * static_cast<Eigen::Index>(points.size()), 10);
  const Eigen::Vector3d g_base(0.0, 0.0, -model::kStandardGravity);
  for (std::size_t k = 0; k < points.size(); ++k) {
    const robot::Pose f = robot::flange_pose(kr210(), points[k]);
    const Eigen::Vector3d g_s = (f.R * ws.R_flange_sensor).transpose() * g_base;
    const auto r = static_cast<Eigen::Index>(6 * k);
    A.block<3, 3>(r, 0).setIdentity();
    A.block<3, 3>(r + 3, 3).setIdentity();
    A.block<3, 1>(r, 6) = g_s;
    A.block<3, 3>(r + 3, 7) = -model::skew(g_s);
  }
  for (Eigen::Index c = 0; c < A.cols(); ++c) {
    const double n = A.col(c).norm();
    if (n > 0.0) A.col(c) /= n;
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(A);
  const auto& sv = svd.singularValues();
  const double smin = sv(sv.size() - 1);
  m.condition_number =
      smin > 1e-12 * sv(0) ? sv(0) / smin : std::numeric_limits<double>::infinity();
  return m;
}

std::vector<Eigen::Vector3d> read_attitudes(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw formats::InputError(path, 0, 0, "cannot open attitude file");
  int line_no = 0;
  std::array<int, 3> col{-1, -1, -1};  // cell index of rx_rad, ry_rad, rz_rad
  std::size_t num_cells = 0;
  std::vector<Eigen::Vector3d> out;
  std::vector<std::string> cells;
  std::vector<int> columns;
  while (formats::read_design_line(in, line_no, cells, columns)) {
    if (num_cells == 0) {
      constexpr const char* kNames[3] = {"rx_rad", "ry_rad", "rz_rad"};
      for (int k = 0; k < 3; ++k) {
        for (std::size_t c = 0; c < cells.size(); ++c)
          if (cells[c] == kNames[k]) col[k] = static_cast<int>(c);
        if (col[k] < 0)
          throw formats::InputError(path, line_no, 1,
                                    std::string("the header must name the columns rx_rad, ry_rad, "
                                                "rz_rad (rotation vector, rad); '") +
                                        kNames[k] + "' is missing");
      }
      num_cells = cells.size();
      continue;
    }
    if (cells.size() != num_cells)
      throw formats::InputError(path, line_no, 1,
                                "expected " + std::to_string(num_cells) + " columns, found " +
                                    std::to_string(cells.size()));
    Eigen::Vector3d r;
    for (int k = 0; k < 3; ++k) {
      const std::string& cell_text = cells[static_cast<std::size_t>(col[k])];
      std::istringstream cell(cell_text);
      cell.imbue(std::locale::classic());
      double x = 0.0;
      if (!(cell >> x) || !(cell >> std::ws).eof() || !std::isfinite(x))
        throw formats::InputError(path, line_no, columns[static_cast<std::size_t>(col[k])],
                                  "not a finite number: '" + cell_text + "'");
      r[k] = x;
    }
    out.push_back(r);
  }
  if (num_cells == 0) throw formats::InputError(path, line_no, 0, "no header line");
  if (out.empty()) throw formats::InputError(path, line_no, 0, "no attitudes");
  return out;
}

AttitudeDesign design_from_attitudes(const std::vector<Eigen::Vector3d>& rotvecs,
                                     const AttitudeDesignOptions& opt) {
  const Workspace& ws = opt.workspace;
  JointVector previous = {opt.arm_rad[0], opt.arm_rad[1], opt.arm_rad[2], 0.0, 0.0, 0.0};
  for (int j = 0; j < 3; ++j)
    if (!(previous[j] >= ws.limits.lower_rad[j] && previous[j] <= ws.limits.upper_rad[j]))
      throw std::invalid_argument("arm pose: A" + std::to_string(j + 1) +
                                  " is outside its joint range");
  AttitudeDesign out;
  out.design.kind = DesignKind::attitudes;
  out.design.seed = 0;
  constexpr double kTwoPi = 2.0 * 3.141592653589793;
  for (std::size_t a = 0; a < rotvecs.size(); ++a) {
    ++out.design.candidates;
    const Eigen::Matrix3d R_base_flange =
        model::rotation_from_vector(rotvecs[a]) * ws.R_flange_sensor.transpose();
    const auto solutions = robot::wrist_inverse_kinematics(kr210(), previous, R_base_flange);
    std::optional<JointVector> best;
    double best_move = std::numeric_limits<double>::infinity();
    bool any_in_range = false;
    double lowest = -std::numeric_limits<double>::infinity();
    for (const JointVector& sol : solutions) {
      for (int k4 = -1; k4 <= 1; ++k4) {
        for (int k6 = -1; k6 <= 1; ++k6) {
          JointVector q = sol;
          q[3] += k4 * kTwoPi;
          q[5] += k6 * kTwoPi;
          if (!within_limits(q, ws.limits)) continue;
          any_in_range = true;
          const double z = lowest_point_z(q, ws);
          lowest = std::max(lowest, z);
          if (z < ws.floor_z_m + ws.clearance_m) continue;
          double move = 0.0;
          for (int j = 0; j < 6; ++j) move = std::max(move, std::abs(q[j] - previous[j]));
          if (move < best_move) best_move = move, best = q;
        }
      }
    }
    if (!best) {
      ++out.design.rejected;
      char why[160];
      if (any_in_range) {
        std::snprintf(why, sizeof why,
                      "below the floor: lowest point z %.3f m < floor %.3f m + clearance %.3f m",
                      lowest, ws.floor_z_m, ws.clearance_m);
      } else {
        const double kDeg = 180.0 / 3.141592653589793;
        std::snprintf(
            why, sizeof why,
            "outside the joint ranges: the wrist needs |A5| = %.1f deg (range %+.0f..%+.0f "
            "deg) from this arm pose",
            std::abs(solutions[0][4]) * kDeg, ws.limits.lower_rad[4] * kDeg,
            ws.limits.upper_rad[4] * kDeg);
      }
      out.unreachable.emplace_back(static_cast<int>(a), why);
      continue;
    }
    out.design.points_rad.push_back(*best);
    out.attitude_index.push_back(static_cast<int>(a));
    previous = *best;
  }
  return out;
}

void write_design(const Design& design, const std::filesystem::path& path,
                  const std::vector<std::filesystem::path>& inputs) {
  std::ostringstream comment;
  comment << "kind=" << design_kind_name(design.kind) << " seed=" << design.seed
          << " points=" << design.points_rad.size() << " candidates=" << design.candidates
          << " rejected=" << design.rejected;
  if (design.kind == DesignKind::oa) comment << " levels=" << design.levels;
  formats::write_file_atomic(path, formats::design_csv_text(comment.str(), design.points_rad),
                             inputs);
}

}  // namespace zerog::sim
