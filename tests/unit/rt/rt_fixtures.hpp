#pragma once
// Shared by the zerog::rt tests: a payload model and its rig (as files, for the configuration),
// a static robot whose F/T samples are the model's payload wrench plus a chosen contact, and a
// temporary folder. Test code; header-only.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <Eigen/Core>
#include <array>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "zerog/infer/deploy_file.hpp"
#include "zerog/infer/inference.hpp"
#include "zerog/io/log.hpp"
#include "zerog/loop/cycle.hpp"
#include "zerog/model/rotation.hpp"
#include "zerog/proto/rsi.hpp"
#include "zerog/rt/setup.hpp"
#include "zerog/rtio/ft_sensor.hpp"
#include "zerog/rtio/imu.hpp"

namespace zerog::rt::test {

namespace fs = std::filesystem;

inline constexpr double kMass = 100.0;
inline constexpr double kPeriod = 0.012;

class TempDir {
 public:
  TempDir() {
    std::string pattern = (fs::temp_directory_path() / "zerog-rt-test-XXXXXX").string();
    if (::mkdtemp(pattern.data()) != nullptr) path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    if (!path_.empty()) fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

inline std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

inline void write_text(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
}

/// The rig of the sample configuration (firmware/rt/zerog-rt.sample.toml names its files).
inline io::Rig test_rig() {
  io::Rig rig;
  rig.name = "kr210-omega191-stim300";
  rig.robot = "KR 210 R2700";
  rig.flange_sensor.p_m = {0.0, 0.0, 0.06};
  rig.sensor_imu.p_m = {0.0, 0.0, -0.03};
  rig.sample_period_s = kPeriod;
  rig.floor_z_m = -0.675;
  return rig;
}

/// Bias, 100 kg payload (centre of mass off the sensor axis), rotational inertia.
inline infer::DeployedModel payload_model(const io::Rig& rig = test_rig()) {
  infer::DeployedModel m;
  m.rig = running_rig(rig, rig.sample_period_s);
  m.physics.effects = model::kDefaultModel;
  double* bias = m.physics.block(model::Effect::bias);
  const double b[6] = {12.0, -7.0, 30.0, 1.5, -0.5, 0.25};
  for (int k = 0; k < 6; ++k) bias[k] = b[k];
  double* g = m.physics.block(model::Effect::gravity);
  g[0] = kMass;
  g[1] = 0.03;
  g[2] = -0.02;
  g[3] = 0.25;
  double* I = m.physics.block(model::Effect::rotational_inertia);
  I[0] = 4.0;
  I[1] = 5.0;
  I[2] = 6.0;
  return m;
}

/// Writes `deploy.zgm` and `rig.rig.toml` (the sample configuration's names) into `dir`.
inline void write_model_and_rig(const fs::path& dir, const io::Rig& rig = test_rig()) {
  write_text(dir / "deploy.zgm", infer::serialise_deployed_model(payload_model(rig)));
  io::write_rig(rig, dir / "rig.rig.toml");
}

inline loop::CycleConfig test_cycle_config() {
  loop::CycleConfig c;
  c.period_s = kPeriod;
  c.body.mass_kg = kMass;
  c.body.inertia_body_kgm2 = Eigen::Vector3d(4.0, 5.0, 6.0).asDiagonal();
  c.p_sensor_com_m = Eigen::Vector3d(0.03, -0.02, 0.25);
  return c;
}

/// A robot standing still at one pose; F/T samples are the payload's wrench (as the model
/// predicts it) plus a contact wrench the test chooses, IMU samples measure gravity only.
class StaticRobot {
 public:
  StaticRobot() {
    EXPECT_EQ(truth_.configure(payload_model()), "");
    message.actual_pose = {1500.0, 200.0, 1200.0, 10.0, 20.0, -30.0};
    message.joints_deg = {5.0, -80.0, 95.0, 10.0, 40.0, -20.0};
    message.has_delay = true;
    message.ipoc = 1'000'000;
    const proto::rsi::PoseSi pose = proto::rsi::to_si(message.actual_pose);
    R = model::rotation_from_kuka_abc(pose.abc_rad[0], pose.abc_rad[1], pose.abc_rad[2]);
    model::FeatureSignals s;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) s.R_base_sensor[3 * r + c] = R(r, c);
    }
    const Eigen::Vector3d f_imu = R.transpose() * Eigen::Vector3d(0, 0, model::kStandardGravity);
    for (int k = 0; k < 3; ++k) s.imu[k] = f_imu[k];
    infer::Wrench w;
    EXPECT_TRUE(truth_.evaluate_physics(s, w).written());
    for (int k = 0; k < 6; ++k) payload[k] = w[k];
    imu_sample.rate_valid = imu_sample.accel_valid = true;
    for (int k = 0; k < 3; ++k) imu_sample.accel_m_s2[k] = f_imu[k];
  }

  /// An F/T sample: payload + `contact` (sensor frame; torque about the sensor origin).
  rtio::FtSample ft(const Eigen::Matrix<double, 6, 1>& contact) const {
    rtio::FtSample s;
    s.valid = true;
    for (int k = 0; k < 6; ++k) s.wrench_si[k] = payload[k] + contact[k];
    return s;
  }

  proto::rsi::RobotMessage message;
  Eigen::Matrix3d R;
  std::array<double, 6> payload{};
  rtio::ImuSample imu_sample;

 private:
  infer::Inference truth_;
};

/// A push through the virtual centre of mass (sensor frame).
inline Eigen::Matrix<double, 6, 1> push(double fx, double fy, double fz) {
  const Eigen::Vector3d F(fx, fy, fz);
  Eigen::Matrix<double, 6, 1> w;
  w << F, test_cycle_config().p_sensor_com_m.cross(F);
  return w;
}

}  // namespace zerog::rt::test
