// A 7-axis arm's joints-only recording (issue 13 item 2: "a 7-axis arm must be describable"):
// the LBR iiwa 14 R820 (calib/robots/lbr_iiwa14_r820.robot.toml) moves its seven joints
// smoothly, the sensor's motion comes from the robot library (forward kinematics and the
// differentiator on a 1 ms grid), the wrench of a payload with known mass, centre of mass and
// inertia from the model's one formula (model::predict_wrench) plus noise. The recording holds
// the time, the wrench and A1..A7 only: zerog import with kinematics = "robot" takes the pose and
// ω, ω̇, specific force from the seven joints (the log cannot hold them: it has q1..q6), and
// the fit recovers the payload. Also the refusals of a joints-only mapping.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "zerog/formats/log.hpp"
#include "zerog/formats/robot_toml.hpp"
#include "zerog/ident/dataset.hpp"
#include "zerog/ident/fit.hpp"
#include "zerog/io/import.hpp"
#include "zerog/model/predict.hpp"
#include "zerog/robot/derive_kinematics.hpp"
#include "zerog/robot/forward_kinematics.hpp"

namespace zerog::ident {
namespace {

namespace fs = std::filesystem;
using model::Effect;
using ::testing::HasSubstr;

const fs::path kIiwaFile = fs::path(ZEROG_SOURCE_DIR) / "calib/robots/lbr_iiwa14_r820.robot.toml";
constexpr int kJoints = 7;

void write_text(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << p;
}

std::string cell(double v) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.10g", v);
  return buffer;
}

// The payload: about what an iiwa 14 carries (kg, m, kg·m²), and the sensor's zero offset.
struct Payload {
  double mass_kg = 11.5;
  Eigen::Vector3d com_m{0.012, -0.018, 0.085};
  std::array<double, 6> inertia{0.09, 0.12, 0.06, 0.008, -0.006, 0.004};  // xx yy zz xy xz yz
  std::array<double, 6> bias{4.0, -3.0, 6.5, 0.3, -0.2, 0.15};
};

const model::EffectSet kDynamicModel = {Effect::bias, Effect::gravity, Effect::linear_inertia,
                                        Effect::rotational_inertia};

struct Recording {
  formats::Rig rig;
  robot::RobotModel model;  ///< with the rig's flange_sensor
  std::vector<double> t_s;
  std::vector<std::array<double, kJoints>> joints_rad;  ///< as recorded (with noise)
  std::vector<robot::Pose> pose;                        ///< true pose of S at t_s
  std::vector<model::Wrench<double>> wrench;            ///< as recorded (with noise)
};

// Smooth motion of every joint (sums of two sines, 0.07–0.35 Hz, within the iiwa's ranges),
// the sensor's motion on a 1 ms grid from the robot library, the recording every `step` ms.
Recording simulate(std::uint64_t seed, double duration_s, int step) {
  Recording r;
  r.rig.name = "iiwa cell";
  r.rig.flange_sensor.p_m = {0.0, 0.0, 0.035};
  r.rig.flange_sensor.q = Eigen::Quaterniond(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()));
  const formats::RobotDescription iiwa = formats::read_robot_file(kIiwaFile, r.rig.flange_sensor);
  r.rig.robot = iiwa.name;
  r.rig.robot_model = iiwa.model;
  r.model = iiwa.model;
  r.rig.sample_period_s = 1e-3 * step;

  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::array<std::array<double, 5>, kJoints> wave{};  // centre, a1, f1, a2, f2 (phases below)
  std::array<std::array<double, 2>, kJoints> phase{};
  for (int j = 0; j < kJoints; ++j) {
    const double centre = j == 1 ? 0.6 : j == 3 ? -1.0 : 0.0;  // A2, A4 bent: off the singularity
    wave[j] = {centre, 0.5 + 0.4 * unit(rng), 0.07 + 0.15 * unit(rng), 0.2 + 0.2 * unit(rng),
               0.2 + 0.15 * unit(rng)};
    phase[j] = {2.0 * std::numbers::pi * unit(rng), 2.0 * std::numbers::pi * unit(rng)};
  }
  const double dt = 1e-3;
  const auto n = static_cast<std::size_t>(duration_s / dt) + 1;
  std::vector<double> t(n), q(n * kJoints);
  for (std::size_t i = 0; i < n; ++i) {
    t[i] = static_cast<double>(i) * dt;
    for (int j = 0; j < kJoints; ++j) {
      const auto& w = wave[j];
      q[i * kJoints + j] = w[0] +
                           w[1] * std::sin(2.0 * std::numbers::pi * w[2] * t[i] + phase[j][0]) +
                           w[3] * std::sin(2.0 * std::numbers::pi * w[4] * t[i] + phase[j][1]);
    }
  }
  // The truth's motion: forward kinematics and the differentiator, 1 ms, 20 Hz bandwidth (the
  // motion is below 0.4 Hz: the smoothing bias is negligible).
  robot::DifferentiatorSettings settings;
  settings.sg = robot::choose_sg_window(dt, 20.0, robot::kMaxSgOrder, 2);
  std::vector<robot::SensorKinematics> motion(n);
  const robot::DeriveStatus status =
      robot::derive_kinematics(r.model, t, q, kJoints, settings, motion);
  EXPECT_TRUE(status.ok());

  const Payload payload;
  model::ModelParams params;
  params.effects = kDynamicModel;
  std::copy(payload.bias.begin(), payload.bias.end(), params.block(Effect::bias));
  double* g = params.block(Effect::gravity);
  g[0] = payload.mass_kg;
  for (int k = 0; k < 3; ++k) g[1 + k] = payload.com_m[k];
  std::copy(payload.inertia.begin(), payload.inertia.end(),
            params.block(Effect::rotational_inertia));
  const model::ParamPointers<double> p = model::pointers(params);
  std::normal_distribution<double> force_noise(0.0, 0.1), torque_noise(0.0, 0.01),
      joint_noise(0.0, 1e-5);  // N, N·m, rad
  for (std::size_t i = 0; i < n; i += static_cast<std::size_t>(step)) {
    const robot::SensorKinematics& m = motion[i];
    model::PoseSignals pose;
    pose.R_base_sensor = m.pose_base_sensor.R;
    pose.t_rel_s = t[i];
    model::ImuSignals<double> imu;  // the IMU frame is S (the rig's sensor_imu is identity)
    imu.specific_force_imu = m.specific_force_sensor_mps2;
    imu.angular_rate_imu = m.omega_sensor_radps;
    imu.angular_accel_imu = m.omega_dot_sensor_radps2;
    model::Wrench<double> w =
        model::predict_wrench<double>(kDynamicModel, p, pose, imu, model::RigGeometry{});
    for (int k = 0; k < 3; ++k) w[k] += force_noise(rng);
    for (int k = 3; k < 6; ++k) w[k] += torque_noise(rng);
    std::array<double, kJoints> joints{};
    for (int j = 0; j < kJoints; ++j) joints[j] = q[i * kJoints + j] + joint_noise(rng);
    r.t_s.push_back(t[i]);
    r.joints_rad.push_back(joints);
    r.pose.push_back(m.pose_base_sensor);
    r.wrench.push_back(w);
  }
  return r;
}

fs::path fresh_dir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("zerog_7axis_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

void write_recording(const Recording& r, const fs::path& file) {
  std::string text = "t,Fx,Fy,Fz,Mx,My,Mz,A1,A2,A3,A4,A5,A6,A7\n";
  for (std::size_t i = 0; i < r.t_s.size(); ++i) {
    text += cell(r.t_s[i]);
    for (int k = 0; k < 6; ++k) text += "," + cell(r.wrench[i][k]);
    for (int j = 0; j < kJoints; ++j) text += "," + cell(r.joints_rad[i][j]);
    text += "\n";
  }
  write_text(file, text);
}

const std::string kMappingHead =
    "format = \"zerog-import\"\nversion = 1\nrig_file = \"cell.rig.toml\"\n";
const std::string kFileKeys =
    "[files.arm]\npath = \"arm.csv\"\ntime = { column = \"t\", unit = \"s\" }\n"
    "force = { columns = [\"Fx\", \"Fy\", \"Fz\"], unit = \"N\" }\n"
    "torque = { columns = [\"Mx\", \"My\", \"Mz\"], unit = \"N*m\" }\n";
const std::string kSevenJoints =
    "joints = { columns = [\"A1\", \"A2\", \"A3\", \"A4\", \"A5\", \"A6\", \"A7\"], unit = "
    "\"rad\" }\n";

double relative(double value, double truth) { return std::abs(value / truth - 1.0); }

// Acceptance: mass within 0.5 %, centre of mass within 2 mm, inertia diagonal within 5 % (products
// within 5 % of the largest diagonal element), on three seeds (motion and noise).
TEST(SevenAxis, JointsOnlyRecordingImportsAndFitsThePayload) {
  const fs::path dir = fresh_dir("fit");
  const Payload truth;
  for (std::uint64_t seed : {11u, 12u, 13u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const Recording rec = simulate(seed, 60.0, 4);  // 60 s at 4 ms (250 Hz)
    write_recording(rec, dir / "arm.csv");
    formats::write_rig(rec.rig, dir / "cell.rig.toml");  // the iiwa inline, as a [robot] table
    write_text(dir / "mapping.toml",
               kMappingHead + "kinematics = \"robot\"\n" + kFileKeys + kSevenJoints);
    const io::ImportResult imported = io::import_recordings(dir / "mapping.toml");
    const std::string summary = imported.report.summary();
    std::printf("%s", summary.c_str());
    const formats::Log& log = imported.log;
    // Seven joints: not in the log (it holds q1..q6), and the summary says so.
    EXPECT_FALSE(log.columns.joints);
    EXPECT_THAT(summary, HasSubstr("joints: 7 columns"));
    EXPECT_THAT(summary, HasSubstr("not written to the log"));
    EXPECT_THAT(summary, HasSubstr("pose from them through LBR iiwa 14 R820"));
    ASSERT_TRUE(log.columns.position && log.columns.angular_rate && log.columns.specific_force);
    EXPECT_EQ(log.rig.kinematics.angular_rate, formats::KinematicsOrigin::joints);
    EXPECT_EQ(log.rig.kinematics.specific_force, formats::KinematicsOrigin::joints);
    // The pose is the forward kinematics of the recorded joints (noise 1e-5 rad).
    ASSERT_EQ(log.samples.size(), rec.t_s.size());
    double pose_error_m = 0.0, pose_error_rad = 0.0;
    for (std::size_t i = 0; i < rec.t_s.size(); ++i) {
      const formats::Sample& s = log.samples[i];
      pose_error_m = std::max(pose_error_m, (s.p_base_sensor_m - rec.pose[i].p_m).norm());
      const Eigen::AngleAxisd d(rec.pose[i].R.transpose() * s.q_base_sensor.toRotationMatrix());
      pose_error_rad = std::max(pose_error_rad, std::abs(d.angle()));
    }
    EXPECT_LT(pose_error_m, 1e-4);
    EXPECT_LT(pose_error_rad, 1e-4);

    // Through the log format (with the 7-axis robot in the rig) and the fit.
    formats::write_log(log, dir / "run.csv");
    const formats::Log read = formats::read_log(dir / "run.csv");
    ASSERT_TRUE(read.rig.robot_model.has_value());
    EXPECT_EQ(read.rig.robot_model->joint_count, kJoints);
    FitOptions fo;
    fo.effects = kDynamicModel;
    const FitResult fitted = fit(make_dataset(read), fo);
    ASSERT_TRUE(fitted.usable) << fitted.termination;
    const double* g = fitted.params.block(Effect::gravity);
    const double* I = fitted.params.block(Effect::rotational_inertia);
    const double mass_error = relative(g[0], truth.mass_kg);
    const double com_error_m =
        (Eigen::Vector3d(g[1], g[2], g[3]) - truth.com_m).cwiseAbs().maxCoeff();
    double diagonal_error = 0.0, product_error = 0.0;
    const double largest = std::max({truth.inertia[0], truth.inertia[1], truth.inertia[2]});
    for (int k = 0; k < 3; ++k)
      diagonal_error = std::max(diagonal_error, relative(I[k], truth.inertia[k]));
    for (int k = 3; k < 6; ++k)
      product_error = std::max(product_error, std::abs(I[k] - truth.inertia[k]) / largest);
    std::printf(
        "7-axis joints only, seed %llu: mass %.4f kg (error %.3f %%), centre of mass error "
        "%.3f mm, inertia error %.2f %% (diagonal), %.2f %% (products, of the largest)\n",
        static_cast<unsigned long long>(seed), g[0], 100.0 * mass_error, 1e3 * com_error_m,
        100.0 * diagonal_error, 100.0 * product_error);
    EXPECT_LT(mass_error, 0.005);
    EXPECT_LT(com_error_m, 0.002);
    EXPECT_LT(diagonal_error, 0.05);
    EXPECT_LT(product_error, 0.05);
  }
  fs::remove_all(dir);
}

// The joints-only mapping's refusals name the key and what would work.
TEST(SevenAxis, JointsOnlyRefusalsNameTheKeyAndWhatWouldWork) {
  const fs::path dir = fresh_dir("refuse");
  const Recording rec = simulate(3, 1.0, 4);
  write_recording(rec, dir / "arm.csv");
  auto refusal = [&](const formats::Rig& rig, const std::string& keys) {
    formats::write_rig(rig, dir / "cell.rig.toml");
    write_text(dir / "mapping.toml", kMappingHead + kFileKeys + keys);
    try {
      (void)io::import_recordings(dir / "mapping.toml");
    } catch (const formats::InputError& e) {
      EXPECT_EQ(e.file(), dir / "mapping.toml");
      return std::string(e.what());
    }
    ADD_FAILURE() << "no refusal for " << keys;
    return std::string();
  };
  // No orientation and a rig that names its robot only: the pose cannot be computed.
  formats::Rig named = rec.rig;
  named.robot_model.reset();
  const std::string no_robot = refusal(named, kSevenJoints);
  EXPECT_THAT(no_robot, HasSubstr("no 'orientation' is mapped"));
  EXPECT_THAT(no_robot, HasSubstr("files.arm.joints"));
  EXPECT_THAT(no_robot, HasSubstr("robot_file ="));
  // Six columns for a seven-joint robot.
  const std::string six = refusal(
      rec.rig,
      "joints = { columns = [\"A1\", \"A2\", \"A3\", \"A4\", \"A5\", \"A6\"], unit = \"rad\" }\n");
  EXPECT_THAT(six, HasSubstr("maps 6 columns, but the rig's robot (LBR iiwa 14 R820) has 7"));
  // More joints than any robot has.
  EXPECT_THAT(refusal(rec.rig,
                      "joints = { columns = [1, 2, 3, 4, 5, 6, 7, 8, 9], unit = "
                      "\"rad\" }\n"),
              HasSubstr("must be a list of 1 to 8 joint columns"));
  // A position without an orientation is no pose.
  EXPECT_THAT(refusal(rec.rig, kSevenJoints + "position = { columns = [2, 3, 4], unit = \"m\" }\n"),
              HasSubstr("'position' is mapped without 'orientation'"));
  // Neither joints nor an orientation.
  EXPECT_THAT(refusal(rec.rig, ""), HasSubstr("no file maps 'orientation'"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace zerog::ident
