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

TEST(Signals, DifferencesGiveAngularAcceleration) {
  const Eigen::Vector3d a(1, 2, 3), b(2, 4, 9);
  EXPECT_NEAR((angular_accel_central(a, b, 0.5) - Eigen::Vector3d(1, 2, 6)).norm(), 0.0, 1e-15);
  EXPECT_NEAR((angular_accel_causal(a, b, 0.5) - Eigen::Vector3d(2, 4, 12)).norm(), 0.0, 1e-15);
}

}  // namespace
}  // namespace zerog::model
