#include "zerog/model/signals.hpp"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <vector>

namespace zerog::model {
namespace {

TEST(Signals, InterpolatesLinearlyAndClampsAtTheEnds) {
  std::vector<double> data;
  for (int i = 0; i < 10; ++i) data.insert(data.end(), {double(i), 2.0 * i});
  const auto v = interpolate_uniform<2>(data.data(), 10, 3.25);
  EXPECT_DOUBLE_EQ(v[0], 3.25);
  EXPECT_DOUBLE_EQ(v[1], 6.5);
  EXPECT_DOUBLE_EQ((interpolate_uniform<2>(data.data(), 10, -4.0))[0], 0.0);
  EXPECT_DOUBLE_EQ((interpolate_uniform<2>(data.data(), 10, 42.0))[1], 18.0);
  EXPECT_DOUBLE_EQ((interpolate_uniform<2>(data.data(), 10, 9.0))[0], 9.0);
}

TEST(Signals, InterpolationDerivativeWithRespectToIndexIsTheSlope) {
  using J = ceres::Jet<double, 1>;
  std::vector<double> data;
  for (int i = 0; i < 10; ++i) data.push_back(double(i * i));
  J idx(4.5);
  idx.v[0] = 1.0;
  const auto v = interpolate_uniform<1>(data.data(), 10, idx);
  EXPECT_DOUBLE_EQ(v[0].a, 20.5);
  EXPECT_DOUBLE_EQ(v[0].v[0], 25.0 - 16.0);
}

TEST(Signals, CentralDifferencesAreExactToTheirOrder) {
  // omega(t) = (t^4, t^2, -t): the 5-point rule is exact up to quartics, the 3-point one up to
  // quadratics; derivative at the centre (4t^3, 2t, -1).
  const double dt = 0.01;
  std::vector<double> rows;  // stride 9, rate in columns 3..5 like the host dataset
  for (int i = 0; i < 5; ++i) {
    const double t = 0.3 + i * dt;
    rows.insert(rows.end(), {0, 0, 0, t * t * t * t, t * t, -t, 0, 0, 0});
  }
  const double tc = 0.3 + 2 * dt;
  const Eigen::Vector3d d4 = angular_accel_central(&rows[2 * 9 + 3], 9, 4, dt);
  EXPECT_NEAR(d4.x(), 4 * tc * tc * tc, 1e-9);
  EXPECT_NEAR(d4.y(), 2 * tc, 1e-9);
  EXPECT_NEAR(d4.z(), -1.0, 1e-9);
  const Eigen::Vector3d d2 = angular_accel_central(&rows[2 * 9 + 3], 9, 2, dt);
  EXPECT_NEAR(d2.y(), 2 * tc, 1e-9);
  EXPECT_NEAR(d2.x(), 4 * tc * tc * tc + 4 * tc * dt * dt, 1e-9);  // (dt²/6) ω''' = 4 t dt²
}

}  // namespace
}  // namespace zerog::model
