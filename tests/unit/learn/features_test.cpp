// The feature catalogue (zerog/model/features.hpp) against hand computations, its names, and
// the host helpers that evaluate it on a log.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <string>
#include <vector>

#include "zerog/learn/signals.hpp"
#include "zerog/model/features.hpp"

namespace {
std::atomic<long> g_allocations{0};
}  // namespace

// Counts every allocation of this test program (to prove compute_features allocates nothing).
// GCC pairs the inlined free() with the `new` expressions that reach it and warns
// (-Wmismatched-new-delete); the pairing is right, since these replacements own both sides.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
void* operator new(std::size_t n) {
  ++g_allocations;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
#pragma GCC diagnostic pop

namespace zerog {
namespace {

using model::Feature;

model::FeatureSignals example() {
  model::FeatureSignals s;
  s.joints_rad = {0.1, -0.2, 0.3, -0.4, 0.5, -0.6};
  s.joint_vel_radps = {0.01, -0.02, 0.0, 0.5, -0.005, 0.03};
  const Eigen::Matrix3d R =
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) s.R_base_sensor[static_cast<std::size_t>(3 * r + c)] = R(r, c);
  s.p_base_sensor_m = {1.5, -0.25, 0.8};
  s.imu = {0.1, 0.2, 9.7, 0.01, -0.02, 0.03, 0.4, -0.5, 0.6};
  s.temperature_C = 31.5;
  s.t_s = 123.25;
  return s;
}

double value(const model::FeatureSignals& s, Feature f) {
  double out = 0.0;
  const Feature list[] = {f};
  model::compute_features(s, list, &out);
  return out;
}

TEST(Features, AgreeWithHandComputations) {
  const auto s = example();
  for (int j = 0; j < 6; ++j) {
    const auto k = static_cast<std::size_t>(j);
    EXPECT_DOUBLE_EQ(value(s, static_cast<Feature>(static_cast<int>(Feature::sin_q1) + j)),
                     std::sin(s.joints_rad[k]));
    EXPECT_DOUBLE_EQ(value(s, static_cast<Feature>(static_cast<int>(Feature::cos_q1) + j)),
                     std::cos(s.joints_rad[k]));
    EXPECT_DOUBLE_EQ(value(s, static_cast<Feature>(static_cast<int>(Feature::qd1) + j)),
                     s.joint_vel_radps[k]);
    EXPECT_DOUBLE_EQ(value(s, static_cast<Feature>(static_cast<int>(Feature::sign_qd1) + j)),
                     std::tanh(s.joint_vel_radps[k] / 0.02));
  }
  // A4 turns at 0.5 rad/s: its sign feature is saturated; A3 stands still: 0.
  EXPECT_NEAR(value(s, Feature::sign_qd4), 1.0, 1e-9);
  EXPECT_EQ(value(s, Feature::sign_qd3), 0.0);
  EXPECT_EQ(value(s, Feature::px), 1.5);
  EXPECT_EQ(value(s, Feature::py), -0.25);
  EXPECT_EQ(value(s, Feature::pz), 0.8);
  // Gravity direction in S: R_base_sensorᵀ (0, 0, −1).
  Eigen::Matrix3d R;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) R(r, c) = s.R_base_sensor[static_cast<std::size_t>(3 * r + c)];
  const Eigen::Vector3d g = R.transpose() * Eigen::Vector3d(0, 0, -1);
  EXPECT_NEAR(value(s, Feature::gx), g.x(), 1e-15);
  EXPECT_NEAR(value(s, Feature::gy), g.y(), 1e-15);
  EXPECT_NEAR(value(s, Feature::gz), g.z(), 1e-15);
  EXPECT_EQ(value(s, Feature::r12), R(0, 1));
  EXPECT_EQ(value(s, Feature::r21), R(1, 0));
  EXPECT_EQ(value(s, Feature::r33), R(2, 2));
  EXPECT_EQ(value(s, Feature::fz), 9.7);
  EXPECT_EQ(value(s, Feature::wy), -0.02);
  EXPECT_EQ(value(s, Feature::wdx), 0.4);
  EXPECT_EQ(value(s, Feature::wdz), 0.6);
  EXPECT_EQ(value(s, Feature::temperature), 31.5);
  EXPECT_EQ(value(s, Feature::time), 123.25);
}

TEST(Features, ComputeKeepsTheOrderAndDoesNotAllocate) {
  const auto s = example();
  const Feature list[] = {Feature::time, Feature::sin_q1, Feature::wz, Feature::r11};
  double out[4] = {};
  const long before = g_allocations.load();
  model::compute_features(s, list, out);
  EXPECT_EQ(g_allocations.load(), before);
  EXPECT_EQ(out[0], 123.25);
  EXPECT_DOUBLE_EQ(out[1], std::sin(0.1));
  EXPECT_EQ(out[2], 0.03);
  EXPECT_EQ(out[3], s.R_base_sensor[0]);
}

TEST(Features, NamesRoundTripAndUnknownNamesAreRejected) {
  for (int k = 0; k < model::kFeatureCount; ++k) {
    const auto f = static_cast<Feature>(k);
    Feature back = Feature::time;
    ASSERT_TRUE(model::feature_from_name(model::feature_name(f), back)) << model::feature_name(f);
    EXPECT_EQ(back, f);
  }
  EXPECT_STREQ(model::feature_name(Feature::sign_qd6), "sign_qd6");
  EXPECT_STREQ(model::feature_name(Feature::wdz), "wdz");
  Feature f = Feature::px;
  EXPECT_FALSE(model::feature_from_name("q7", f));
  EXPECT_FALSE(model::feature_from_name("", f));
  EXPECT_EQ(f, Feature::px);
}

TEST(Features, ParseListGivesClearErrors) {
  const auto list = learn::parse_features("sign_qd6, qd6,wz");
  ASSERT_EQ(list.size(), 3u);
  EXPECT_EQ(list[0], Feature::sign_qd6);
  EXPECT_EQ(learn::feature_list_string(list), "sign_qd6,qd6,wz");
  try {
    learn::parse_features("qd6,omega_z");
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("unknown feature 'omega_z'"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("sign_qd6"), std::string::npos);  // lists valid names
  }
  EXPECT_THROW(learn::parse_features("qd6,qd6"), std::invalid_argument);
  EXPECT_THROW(learn::parse_features(" , "), std::invalid_argument);
}

TEST(Features, DiagnoseSignalNamesMapToFeatures) {
  using V = std::vector<Feature>;
  EXPECT_EQ(learn::features_for_signal("joint A6 velocity direction (sign)"), V{Feature::sign_qd6});
  EXPECT_EQ(learn::features_for_signal("joint A6 velocity"), V{Feature::qd6});
  EXPECT_EQ(learn::features_for_signal("joint A2 angle (sine)"), V{Feature::sin_q2});
  EXPECT_EQ(learn::features_for_signal("joint A5 angle (cosine)"), V{Feature::cos_q5});
  EXPECT_EQ(learn::features_for_signal("angular rate about IMU z"), V{Feature::wz});
  EXPECT_EQ(learn::features_for_signal("angular acceleration about IMU y"), V{Feature::wdy});
  EXPECT_EQ(learn::features_for_signal("specific force along IMU x"), V{Feature::fx});
  EXPECT_EQ(learn::features_for_signal("gravity direction along sensor z"), V{Feature::gz});
  EXPECT_EQ(learn::features_for_signal("sensor temperature"), V{Feature::temperature});
  EXPECT_EQ(learn::features_for_signal("time since start"), V{Feature::time});
  EXPECT_TRUE(learn::features_for_signal("phase of the moon").empty());
}

}  // namespace
}  // namespace zerog
