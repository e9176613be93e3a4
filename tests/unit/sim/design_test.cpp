// Path-point designs: orthogonal array strength, Sobol points, ranges, floor, determinism, CSV.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <set>

#include "zerog/io/log.hpp"
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
  } catch (const io::InputError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.column(), 7);
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace zerog::sim
