// The signal dictionary and user terms (proto/user_effects.md): bases read and write back, the
// signals agree with rigid-body kinematics computed here independently, term directions, and
// the real-time paths allocate nothing.
#include "zerog/model/dictionary.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <string>

#include "alloc_count.hpp"
#include "zerog/model/predict.hpp"
#include "zerog/model/user_effects.hpp"

namespace zerog::model {
namespace {

std::string format(const Basis& b) {
  char buf[128];
  format_basis(b, buf, sizeof buf);
  return buf;
}

Basis parse(const std::string& text) {
  Basis b;
  const char* error = nullptr;
  std::size_t pos = 0;
  EXPECT_TRUE(parse_basis(text, b, error, pos)) << text << ": " << (error ? error : "");
  return b;
}

double value_of(Signal s, const DictionarySignals& d) { return d[static_cast<std::size_t>(s)]; }

TEST(Dictionary, BasesReadBackAsWritten) {
  for (const char* text : {"wz_S", "tanh(qd6/0.02)", "sin(q5)*cos(q4)", "temperature*gz_S",
                           "sign(vx_B)", "wz_S*wz_S", "tanh(vy_S/0.005)*px_B", "time"}) {
    EXPECT_EQ(format(parse(text)), text);
  }
  // Blanks around '*' and inside the parentheses are allowed; the written form has none.
  EXPECT_EQ(format(parse(" sin( q5 ) * cos(q4)")), "sin(q5)*cos(q4)");
  const Basis b = parse("tanh(qd6/0.02)");
  EXPECT_EQ(b.a.signal, Signal::qd6);
  EXPECT_EQ(b.a.op, FactorOp::tanh);
  EXPECT_DOUBLE_EQ(b.a.eps, 0.02);
  EXPECT_FALSE(b.product);
}

TEST(Dictionary, BadBasesSayWhyAndWhere) {
  struct Case {
    const char* text;
    std::size_t pos;
    const char* why;  // a word of the reason
  };
  for (const Case& c : {Case{"wz", 0, "unknown signal"}, Case{"sin(qd6)", 0, "joint angles"},
                        Case{"tanh(qd6)", 8, "scale"}, Case{"tanh(qd6/-1)", 9, "> 0"},
                        Case{"tanh(q6/0.1)", 0, "velocities"}, Case{"wz_S*wy_S*wx_S", 9, "after"},
                        Case{"log(qd6)", 0, "unknown function"}, Case{"", 0, "expected"},
                        Case{"cos(q4", 6, "')'"}, Case{"sin(q9)", 4, "unknown signal"}}) {
    Basis b;
    const char* error = nullptr;
    std::size_t pos = 99;
    EXPECT_FALSE(parse_basis(c.text, b, error, pos)) << c.text;
    ASSERT_NE(error, nullptr) << c.text;
    EXPECT_EQ(pos, c.pos) << c.text << ": " << error;
    EXPECT_NE(std::string(error).find(c.why), std::string::npos) << c.text << ": " << error;
  }
}

TEST(Dictionary, UnitsOfBasesAndProducts) {
  auto unit = [](const char* text) {
    char buf[64];
    basis_unit(parse(text), buf, sizeof buf);
    return std::string(buf);
  };
  EXPECT_EQ(unit("wz_S"), "rad/s");
  EXPECT_EQ(unit("tanh(qd6/0.02)"), "1");
  EXPECT_EQ(unit("sin(q5)*cos(q4)"), "1");
  EXPECT_EQ(unit("temperature*gz_S"), "K");
  EXPECT_EQ(unit("vx_S*wz_S"), "m/s*rad/s");
}

// A rigid body moving with known ω, ω̇ (in S) and acceleration of the S origin; an IMU mounted at
// p_SI, turned by R_SI. The IMU's specific force is written here from the definition
// f = a_IMU − g in the IMU frame; the dictionary must recover the sensor-origin signals.
TEST(Dictionary, SignalsFollowRigidBodyKinematics) {
  RigGeometry rig;
  rig.R_sensor_imu = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, -1).normalized()).matrix();
  rig.p_sensor_imu_m = Eigen::Vector3d(0.045, -0.03, -0.035);
  const Eigen::Matrix3d R_BS =
      Eigen::AngleAxisd(1.1, Eigen::Vector3d(-0.2, 0.5, 0.8).normalized()).matrix();
  const Eigen::Vector3d w_S(0.3, -0.5, 0.7), wd_S(1.5, 0.2, -0.9), a_S(0.4, -1.2, 2.0);
  const Eigen::Vector3d g_S = R_BS.transpose() * Eigen::Vector3d(0, 0, -9.80665);
  const Eigen::Vector3d p = rig.p_sensor_imu_m;
  const Eigen::Vector3d a_imu_S = a_S + wd_S.cross(p) + w_S.cross(w_S.cross(p));
  KinematicInputs in;
  const Eigen::Vector3d f_I = rig.R_sensor_imu.transpose() * (a_imu_S - g_S);
  const Eigen::Vector3d w_I = rig.R_sensor_imu.transpose() * w_S;
  const Eigen::Vector3d wd_I = rig.R_sensor_imu.transpose() * wd_S;
  for (int k = 0; k < 3; ++k) {
    in.features.imu[static_cast<std::size_t>(k)] = f_I[k];
    in.features.imu[static_cast<std::size_t>(3 + k)] = w_I[k];
    in.features.imu[static_cast<std::size_t>(6 + k)] = wd_I[k];
  }
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      in.features.R_base_sensor[static_cast<std::size_t>(3 * r + c)] = R_BS(r, c);
  in.features.p_base_sensor_m = {1.2, -0.4, 0.9};
  in.features.joints_rad = {0.1, -0.2, 0.3, -0.4, 0.5, -0.6};
  in.features.joint_vel_radps = {1, 2, 3, 4, 5, 6};
  in.joint_acc_radps2 = {-1, -2, -3, -4, -5, -6};
  in.v_base_sensor_mps = {0.25, -0.5, 0.125};
  in.features.temperature_C = 31.5;
  in.features.t_s = 42.0;
  const DictionarySignals d = dictionary_signals(in, rig);

  const Eigen::Vector3d v_B(0.25, -0.5, 0.125);
  const Eigen::Vector3d v_S = R_BS.transpose() * v_B;
  for (int k = 0; k < 3; ++k) {
    const auto at = [&](Signal first) { return static_cast<Signal>(static_cast<int>(first) + k); };
    EXPECT_NEAR(value_of(at(Signal::wx_S), d), w_S[k], 1e-12);
    EXPECT_NEAR(value_of(at(Signal::wdx_S), d), wd_S[k], 1e-12);
    EXPECT_NEAR(value_of(at(Signal::ax_S), d), a_S[k], 1e-12);
    EXPECT_NEAR(value_of(at(Signal::wx_B), d), (R_BS * w_S)[k], 1e-12);
    EXPECT_NEAR(value_of(at(Signal::wdx_B), d), (R_BS * wd_S)[k], 1e-12);
    EXPECT_NEAR(value_of(at(Signal::ax_B), d), (R_BS * a_S)[k], 1e-12);
    EXPECT_NEAR(value_of(at(Signal::vx_S), d), v_S[k], 1e-12);
    EXPECT_NEAR(value_of(at(Signal::vx_B), d), v_B[k], 1e-12);
    EXPECT_NEAR(value_of(at(Signal::gx_S), d), g_S[k] / 9.80665, 1e-12);
  }
  EXPECT_DOUBLE_EQ(value_of(Signal::px_B, d), 1.2);
  EXPECT_DOUBLE_EQ(value_of(Signal::q4, d), -0.4);
  EXPECT_DOUBLE_EQ(value_of(Signal::qd6, d), 6.0);
  EXPECT_DOUBLE_EQ(value_of(Signal::qdd2, d), -2.0);
  EXPECT_DOUBLE_EQ(value_of(Signal::temperature, d), 6.5);
  EXPECT_DOUBLE_EQ(value_of(Signal::time, d), 42.0);

  EXPECT_NEAR(basis_value(parse("sin(q5)*cos(q4)"), d), std::sin(0.5) * std::cos(-0.4), 1e-15);
  EXPECT_NEAR(basis_value(parse("tanh(qd6/0.02)"), d), std::tanh(6.0 / 0.02), 1e-15);
  EXPECT_DOUBLE_EQ(basis_value(parse("sign(vy_B)"), d), -1.0);
  EXPECT_DOUBLE_EQ(basis_value(parse("temperature*time"), d), 6.5 * 42.0);
}

TEST(UserEffects, SensorAndBaseFrameTermsAddAlongTheirAxes) {
  UserEffects u;
  u.num_effects = 1;
  u.num_terms = 3;
  u.terms[0] = {parse("wz_S"), 5, TermFrame::sensor, 0};
  u.terms[1] = {parse("vx_B"), 0, TermFrame::base, 0};     // force along base x
  u.terms[2] = {parse("sin(q1)"), 4, TermFrame::base, 0};  // torque about base y
  u.coeff = {-2.0, -25.0, 0.6};
  DictionarySignals d{};
  d[static_cast<std::size_t>(Signal::wz_S)] = 0.5;
  d[static_cast<std::size_t>(Signal::vx_B)] = 0.2;
  d[static_cast<std::size_t>(Signal::q1)] = 0.7;
  const Eigen::Matrix3d R_BS =
      Eigen::AngleAxisd(0.8, Eigen::Vector3d(1, -1, 2).normalized()).matrix();
  Eigen::Matrix<double, 6, 1> expected = Eigen::Matrix<double, 6, 1>::Zero();
  expected[5] = -2.0 * 0.5;
  expected.head<3>() += -25.0 * 0.2 * (R_BS.transpose() * Eigen::Vector3d::UnitX());
  expected.tail<3>() += 0.6 * std::sin(0.7) * (R_BS.transpose() * Eigen::Vector3d::UnitY());
  const Eigen::Matrix<double, 6, 1> w = user_wrench(u, d, R_BS);
  EXPECT_LT((w - expected).norm(), 1e-12) << w.transpose();
  // The design's columns are each term's ∂w/∂c, checked against the same hand computation.
  std::array<double, 6 * kMaxUserTerms> D{};
  user_design(u, d, R_BS, D.data());
  EXPECT_NEAR(D[6 * 0 + 5], 0.5, 1e-15);
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(D[static_cast<std::size_t>(6 * 1 + k)], 0.2 * R_BS(0, k), 1e-15);
    EXPECT_NEAR(D[static_cast<std::size_t>(6 * 2 + 3 + k)], std::sin(0.7) * R_BS(1, k), 1e-15);
  }
}

TEST(UserEffects, TheRealTimePathsAllocateNothing) {
  UserEffects u;
  u.num_terms = 2;
  u.terms[0] = {parse("tanh(qd6/0.02)"), 5, TermFrame::sensor, 0};
  u.terms[1] = {parse("sin(q5)*cos(q4)"), 0, TermFrame::base, 0};
  u.coeff = {1.5, 3.0};
  KinematicInputs in;
  in.features.joint_vel_radps[5] = 0.1;
  const RigGeometry rig;
  test::AllocGuard guard("dictionary_signals, user_wrench, parse_basis, format_basis");
  double sum = 0.0;
  for (int i = 0; i < 100; ++i) {
    in.features.t_s = i;
    const DictionarySignals d = dictionary_signals(in, rig);
    sum += user_wrench(u, d, Eigen::Matrix3d::Identity()).sum();
    Basis b;
    const char* error = nullptr;
    std::size_t pos = 0;
    sum += parse_basis("sin(q5)*cos(q4)", b, error, pos) ? 1.0 : 0.0;
    char buf[64];
    format_basis(b, buf, sizeof buf);
  }
  guard.stop();
  EXPECT_EQ(guard.allocations(), 0u) << guard.first_call();
  EXPECT_EQ(guard.frees(), 0u) << guard.first_call();
  EXPECT_TRUE(std::isfinite(sum));
}

}  // namespace
}  // namespace zerog::model
