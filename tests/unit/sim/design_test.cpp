// Path-point designs: orthogonal array strength, Sobol points, ranges, floor, determinism, CSV.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include "zerog/formats/log.hpp"
#include "zerog/model/rotation.hpp"
#include "zerog/sim/design.hpp"

namespace zerog::sim {
namespace {

namespace fs = std::filesystem;

TEST(Design, BoseArrayHasStrengthTwo) {
  const auto rows = bose_oa(11);
  ASSERT_EQ(rows.size(), 121u);
  for (std::size_t c1 = 0; c1 < 12; ++c1) {
    for (std::size_t c2 = c1 + 1; c2 < 12; ++c2) {
      std::set<std::pair<int, int>> pairs;
      for (const auto& r : rows) pairs.insert({r[c1], r[c2]});
      EXPECT_EQ(pairs.size(), 121u) << "columns " << c1 << ", " << c2;  // each pair exactly once
    }
  }
  EXPECT_THROW(bose_oa(12), std::invalid_argument);
}

TEST(Design, OaUsesTheSixColumnsAndTheRanges) {
  DesignOptions o;
  o.kind = DesignKind::oa;
  o.workspace.clearance_m = -10.0;  // no floor: all 121 rows
  const Design d = make_design(o);
  ASSERT_EQ(d.points_rad.size(), 121u);
  EXPECT_EQ(d.rejected, 0);
  const JointLimits& lim = o.workspace.limits;
  std::vector<std::array<int, 6>> levels;
  for (const auto& q : d.points_rad) {
    std::array<int, 6> lv{};
    for (int j = 0; j < 6; ++j) {
      const double x = (q[j] - lim.lower_rad[j]) / (lim.upper_rad[j] - lim.lower_rad[j]) * 10.0;
      lv[j] = static_cast<int>(std::lround(x));
      EXPECT_NEAR(x, lv[j], 1e-9);  // exactly on one of the 11 levels
    }
    levels.push_back(lv);
  }
  for (int j = 0; j < 6; ++j) {
    for (int k = j + 1; k < 6; ++k) {
      std::set<std::pair<int, int>> pairs;
      for (const auto& lv : levels) pairs.insert({lv[j], lv[k]});
      EXPECT_EQ(pairs.size(), 121u) << "joints " << j + 1 << ", " << k + 1;
    }
  }
  const DesignMetrics m = design_metrics(d.points_rad, o.workspace);
  EXPECT_DOUBLE_EQ(m.pair_coverage_min, 1.0);
  EXPECT_GT(m.condition_number, 1.0);
  EXPECT_LT(m.condition_number, 10.0);
  EXPECT_THROW(make_design({DesignKind::oa, 100, 11, 1, {}}), std::invalid_argument);
}

TEST(Design, SobolKnownPointsAndStratification) {
  // Dimension 1 is van der Corput in Gray-code order, dimension 2 (x + 1) its known companion.
  const double d1[8] = {0, 0.5, 0.75, 0.25, 0.375, 0.875, 0.625, 0.125};
  const double d2[8] = {0, 0.5, 0.25, 0.75, 0.375, 0.875, 0.125, 0.625};
  for (std::uint32_t i = 0; i < 8; ++i) {
    EXPECT_DOUBLE_EQ(sobol_point(i)[0], d1[i]) << i;
    EXPECT_DOUBLE_EQ(sobol_point(i)[1], d2[i]) << i;
  }
  // Joe–Kuo dimension 3 (x² + x + 1, m = 1, 3): point 5 is (0.875, 0.625, 0.125) in dims 1..3.
  EXPECT_DOUBLE_EQ(sobol_point(5)[2], 0.125);
  // Every block of 2^m points from index 0 puts one point in each interval of width 2^−m, in
  // every dimension, and 2-D pairs are (0, m, 2)-nets in dimensions 1 and 2.
  for (int m = 1; m <= 10; ++m) {
    const std::uint32_t n = 1u << m;
    for (int d = 0; d < 6; ++d) {
      std::set<std::uint32_t> cells;
      for (std::uint32_t i = 0; i < n; ++i)
        cells.insert(static_cast<std::uint32_t>(sobol_point(i)[d] * n));
      EXPECT_EQ(cells.size(), n) << "dim " << d + 1 << ", m " << m;
    }
  }
}

TEST(Design, RandomAndSobolRespectRangesFloorAndSeed) {
  for (DesignKind kind : {DesignKind::random, DesignKind::sobol}) {
    DesignOptions o;
    o.kind = kind;
    o.points = 80;
    o.seed = 5;
    o.workspace.clearance_m = 1.0;  // a high floor: z ≥ 0.325 m in base rejects some points
    const Design a = make_design(o);
    ASSERT_EQ(a.points_rad.size(), 80u);
    EXPECT_GT(a.rejected, 0) << design_kind_name(kind);
    EXPECT_EQ(a.candidates, 80 + a.rejected);
    for (const auto& q : a.points_rad) {
      EXPECT_TRUE(within_limits(q, o.workspace.limits));
      EXPECT_GE(lowest_point_z(q, o.workspace), o.workspace.floor_z_m + 1.0);
    }
    const Design b = make_design(o);
    EXPECT_EQ(a.points_rad, b.points_rad);  // deterministic for a seed
    o.seed = 6;
    EXPECT_NE(make_design(o).points_rad, a.points_rad);
  }
}

TEST(Design, OaDropsRowsBelowTheFloor) {
  DesignOptions o;
  o.workspace.clearance_m = 1.0;
  const Design d = make_design(o);
  EXPECT_GT(d.rejected, 0);
  EXPECT_EQ(d.points_rad.size() + static_cast<std::size_t>(d.rejected), 121u);
  for (const auto& q : d.points_rad) EXPECT_TRUE(is_feasible(q, o.workspace));
}

TEST(Design, LowestPointOfKnownPose) {
  Workspace ws;
  JointVector q = kr210_home();
  q[4] = 1.5707963267948966;  // flange straight down at (1.55, 0, 1.569)
  // Payload centre 0.06 + 0.25 below the flange, its sphere 0.39 further down.
  EXPECT_NEAR(lowest_point_z(q, ws), 1.569 - 0.06 - 0.25 - 0.39, 1e-9);
}

TEST(Design, CsvRoundTrip) {
  const fs::path dir = fs::temp_directory_path() / "zerog_sim_design_test";
  fs::create_directories(dir);
  DesignOptions o;
  o.kind = DesignKind::sobol;
  o.points = 10;
  const Design d = make_design(o);
  const fs::path file = dir / "design.csv";
  write_design(d, file);
  const auto back = read_design(file);
  ASSERT_EQ(back.size(), d.points_rad.size());
  for (std::size_t k = 0; k < back.size(); ++k)
    for (int j = 0; j < 6; ++j) EXPECT_NEAR(back[k][j], d.points_rad[k][j], 1e-11);
  EXPECT_THROW(write_design(d, file, {file}), std::runtime_error);  // never over an input
  {
    std::ofstream bad(dir / "bad.csv");
    bad << "# zerog-design 1\nq1_rad,q2_rad,q3_rad,q4_rad,q5_rad,q6_rad\n0,0,0,x,0,0\n";
  }
  try {
    read_design(dir / "bad.csv");
    FAIL() << "expected an InputError";
  } catch (const formats::InputError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.column(), 7);
  }
  fs::remove_all(dir);
}

TEST(Design, AppendixCAttitudesByWristInverseKinematics) {
  const auto attitudes =
      read_attitudes(std::string(ZEROG_SOURCE_DIR) + "/calib/poses/001_appendix_c_attitudes.csv");
  ASSERT_EQ(attitudes.size(), 15u);
  EXPECT_EQ(attitudes[0], Eigen::Vector3d(2.0592, 0.6381, -0.0558));
  EXPECT_EQ(attitudes[14], Eigen::Vector3d(-0.8525, -2.4366, 0.7001));
  constexpr double kDeg = 3.141592653589793 / 180.0;
  AttitudeDesignOptions o;
  o.arm_rad = {-90 * kDeg, -80 * kDeg, 125 * kDeg};  // zerog design's default --arm
  o.workspace.R_flange_sensor = model::rot_z(0.3);   // a sensor turned on the flange
  const AttitudeDesign d = design_from_attitudes(attitudes, o);
  ASSERT_EQ(d.design.points_rad.size(), 15u);
  EXPECT_TRUE(d.unreachable.empty());
  EXPECT_EQ(d.design.kind, DesignKind::attitudes);
  for (std::size_t k = 0; k < 15; ++k) {
    const JointVector& q = d.design.points_rad[k];
    EXPECT_TRUE(is_feasible(q, o.workspace));
    for (int j = 0; j < 3; ++j) EXPECT_EQ(q[j], o.arm_rad[j]);
    // Forward kinematics of the solution reproduces the attitude R_base_sensor = Exp(r).
    const Eigen::Matrix3d R_base_sensor =
        robot::flange_pose(kr210(), q).R * o.workspace.R_flange_sensor;
    const Eigen::Matrix3d R_wanted =
        model::rotation_from_vector(attitudes[static_cast<std::size_t>(d.attitude_index[k])]);
    EXPECT_LT((R_base_sensor - R_wanted).cwiseAbs().maxCoeff(), 1e-9) << "attitude " << k + 1;
  }
  // From home (forearm horizontal along +x), three attitudes would need |A5| > 120°.
  o.arm_rad = {0.0, -90 * kDeg, 90 * kDeg};
  o.workspace.R_flange_sensor.setIdentity();
  const AttitudeDesign home = design_from_attitudes(attitudes, o);
  EXPECT_EQ(home.design.points_rad.size(), 12u);
  ASSERT_EQ(home.unreachable.size(), 3u);
  EXPECT_EQ(home.unreachable[0].first, 4);
  EXPECT_EQ(home.unreachable[1].first, 6);
  EXPECT_EQ(home.unreachable[2].first, 14);
  EXPECT_NE(home.unreachable[0].second.find("joint ranges"), std::string::npos);
  EXPECT_EQ(home.design.rejected, 3);
  o.arm_rad[1] = 0.0;  // A2 outside its range
  EXPECT_THROW(design_from_attitudes(attitudes, o), std::invalid_argument);
  EXPECT_THROW(make_design({DesignKind::attitudes, 10, 11, 1, {}}), std::invalid_argument);
}

TEST(Design, AttitudeCsvErrorsNameLineAndColumn) {
  const fs::path dir = fs::temp_directory_path() / "zerog_sim_attitude_test";
  fs::create_directories(dir);
  {
    std::ofstream f(dir / "a.csv");
    f << "# note\nrx_rad,ry_rad,rz_rad\n0.1,0.2,0.3\r\n\n0,0,1e\n";
  }
  try {
    read_attitudes(dir / "a.csv");
    FAIL() << "expected an InputError";
  } catch (const formats::InputError& e) {
    EXPECT_EQ(e.line(), 5);
    EXPECT_EQ(e.column(), 5);
  }
  {
    std::ofstream f(dir / "b.csv");
    f << "number,rx,ry,rz\n1,0,0,0\n";
  }
  EXPECT_THROW(read_attitudes(dir / "b.csv"), formats::InputError);
  {
    std::ofstream f(dir / "c.csv");
    f << "rz_rad,number,rx_rad,ry_rad\n0.3,1,0.1,0.2\n";  // columns by name, any order
  }
  const auto c = read_attitudes(dir / "c.csv");
  ASSERT_EQ(c.size(), 1u);
  EXPECT_EQ(c[0], Eigen::Vector3d(0.1, 0.2, 0.3));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace zerog::sim
