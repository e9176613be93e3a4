#pragma once
// Path-point designs for identification runs (paper 000_… §4.2): an orthogonal array, uniform
// random points or a Sobol sequence over the joint ranges, with a floor check, coverage and
// conditioning figures, and the design CSV (proto/design_format.md).
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "zerog/formats/design_csv.hpp"
#include "zerog/sim/robot.hpp"

namespace zerog::sim {

/// attitudes: from a list of sensor attitudes by wrist inverse kinematics (design_from_attitudes;
/// make_design refuses it).
enum class DesignKind { oa, random, sobol, attitudes };
const char* design_kind_name(DesignKind kind);
std::optional<DesignKind> design_kind_from_name(std::string_view name);

/// Where path points may lie: joint ranges and a floor the flange and payload must clear.
struct Workspace {
  JointLimits limits = kr210_table4_limits();
  double floor_z_m = -0.675;   ///< floor height in the base frame (base 0.675 m above the floor)
  double clearance_m = 0.175;  ///< required height above the floor: z ≥ floor + clearance
  Eigen::Vector3d p_flange_sensor_m{0.0, 0.0, 0.06};  ///< sensor origin in the flange frame
  Eigen::Matrix3d R_flange_sensor = Eigen::Matrix3d::Identity();
  Eigen::Vector3d com_sensor_m{0.03, -0.02, 0.25};  ///< payload centre of mass in S
  double payload_radius_m = 0.39;  ///< sphere about the centre of mass enclosing the payload
};

/// Lowest point (z in B, m) of the things that must clear the floor at joint angles q: the wrist
/// centre, the flange centre, the sensor origin and the payload's enclosing sphere.
double lowest_point_z(const JointVector& q_rad, const Workspace& ws);
bool within_limits(const JointVector& q_rad, const JointLimits& limits);
/// Within the joint ranges and lowest_point_z ≥ floor_z_m + clearance_m.
bool is_feasible(const JointVector& q_rad, const Workspace& ws);

/// Orthogonal array OA(p², p + 1, p, 2) by Bose's construction over GF(p), p prime: row (a, b)
/// for a, b = 0..p−1 (a slowest), columns a + j·b mod p for j = 0..p−1, then b (column p).
/// Every pair of columns holds every ordered pair of levels exactly once.
std::vector<std::vector<int>> bose_oa(int p);
/// The 6 columns of the Bose array used for A1..A6: a, b, a + b, a + 2b, a + 3b, a + 4b. A1, the
/// slowest axis, takes `a`, which changes only every p rows; its levels are relabelled
/// ℓ → (p − 1)/2 · ℓ mod p (0, 5, 10, 4, 9, 3, … for p = 11) so that A1 is not monotone in time
/// (uncorrelated with the run time, which would confound bias_drift with A1). Relabelling the
/// levels of a column keeps the orthogonal array.
inline constexpr std::array<int, 6> kOaColumns = {0, -1, 1, 2, 3, 4};  // −1 means column "b"

/// Point `index` of the 6-dimensional Sobol sequence (Gray-code order, index 0 is the origin),
/// in [0, 1)^6, with the direction numbers of Joe & Kuo (2008), new-joe-kuo-6.21201.
std::array<double, 6> sobol_point(std::uint32_t index);

struct DesignOptions {
  DesignKind kind = DesignKind::oa;
  int points = 121;  ///< oa: must be levels² (or 0 = levels²)
  int levels = 11;   ///< oa: prime number of levels per joint
  std::uint64_t seed =
      1;  ///< random: the points; sobol: random digital shift (0 = none); oa: unused
  Workspace workspace;
};

struct Design {
  DesignKind kind = DesignKind::oa;
  std::uint64_t seed = 0;
  int levels = 11;
  std::vector<JointVector> points_rad;
  int candidates = 0;  ///< points generated
  int rejected = 0;    ///< of those, dropped as infeasible (floor)
};

/// Builds a design. oa: the p² rows in order, levels mapped uniformly onto the joint ranges
/// (level ℓ → lower + ℓ (upper − lower) / (p − 1)), infeasible rows dropped. random/sobol:
/// candidates are drawn until `points` feasible ones are found (at most 100× as many tries).
/// Throws std::invalid_argument on bad options.
Design make_design(const DesignOptions& options);

/// Figures to compare designs.
struct DesignMetrics {
  int points = 0;
  int levels = 11;
  /// Each joint range is cut into `levels` equal bins; for every one of the 15 joint pairs, the
  /// fraction of the levels × levels bin pairs holding at least one point. Min and mean over pairs.
  double pair_coverage_min = 0.0;
  double pair_coverage_mean = 0.0;
  /// Distances between points in joint space normalized to [0, 1]^6 by the ranges.
  double min_distance = 0.0;           ///< closest pair
  double mean_nearest_distance = 0.0;  ///< mean over points of the distance to the nearest other
  /// 2-norm condition number of A·D, where A stacks for each pose k the 6 × 10 block
  ///   [ I3  0   g_S,k   0        ]
  ///   [ 0   I3  0      −[g_S,k]× ]
  /// (unknowns F0, M0, m, m·c; g_S,k = R_base_sensor,kᵀ (0, 0, −9.80665)) and D scales each
  /// column of A to unit 2-norm. Infinity when rank-deficient.
  double condition_number = 0.0;
};
DesignMetrics design_metrics(const std::vector<JointVector>& points_rad, const Workspace& ws,
                             int levels = 11);

/// Attitudes for a static identification run (e.g. a tool change, paper 001_… §4.2, Appendix C):
/// rotation vectors r (rad) of the F/T sensor frame S in the robot base frame B,
/// R_base_sensor = Exp(r). CSV: `#` comment lines, a header naming the columns `rx_rad`,
/// `ry_rad`, `rz_rad` (other columns, e.g. `number`, are ignored), one attitude per row
/// (calib/poses/README.md). Throws formats::InputError naming file, line and column.
std::vector<Eigen::Vector3d> read_attitudes(const std::filesystem::path& path);

struct AttitudeDesignOptions {
  /// A1..A3 held for every point (rad): the forearm pose the wrist turns from. Default: home,
  /// A2 = −90°, A3 = +90° (forearm horizontal, wrist centre 1.78 m above the base).
  std::array<double, 3> arm_rad = {0.0, -1.5707963267948966, 1.5707963267948966};
  Workspace workspace;  ///< joint ranges, floor, and the sensor's mounting R_flange_sensor
};

struct AttitudeDesign {
  Design design;                    ///< kind attitudes: one point per reachable attitude, in order
  std::vector<int> attitude_index;  ///< for each point, the 0-based index of its attitude
  /// For each attitude that cannot be reached: its index and why (joint range or floor).
  std::vector<std::pair<int, std::string>> unreachable;
};

/// Path points that give the sensor the requested attitudes R_base_sensor = Exp(r): A1..A3 fixed
/// at `arm_rad`, A4..A6 by wrist_inverse_kinematics for R_base_flange = R_base_sensor ·
/// R_flange_sensorᵀ. Of the solutions (wrist flip, A4/A6 ± 2π) within the joint ranges and above
/// the floor, the one nearest the previous point (largest joint move smallest) is taken; the
/// first point is compared with the arm pose and a straight wrist. Throws std::invalid_argument
/// if the arm pose is outside the joint ranges.
AttitudeDesign design_from_attitudes(const std::vector<Eigen::Vector3d>& rotvecs_base_sensor,
                                     const AttitudeDesignOptions& options);

/// Design CSV (proto/design_format.md). Written atomically; refuses to overwrite `inputs`.
void write_design(const Design& design, const std::filesystem::path& path,
                  const std::vector<std::filesystem::path>& inputs = {});
/// Reads a design CSV; throws formats::InputError naming file, line and column. The reader lives
/// with the writer's format in zerog::formats (zerog-rt reads designs too).
using formats::read_design;

}  // namespace zerog::sim
