// Streamed reading (issue 16): read_dataset (formats::LogReader a chunk of rows at a time, fed to
// DatasetBuilder) gives the Dataset that make_dataset(formats::read_log(...)) gives, bit for bit,
// and the same errors, on simulator logs with every column group, with optional groups missing,
// with the imu_dw* columns, and with static rows.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "zerog/ident/dataset.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::ident {
namespace {

namespace fs = std::filesystem;

// The first row where two per-row vectors differ (exact comparison); -1 if none.
template <typename V>
long first_difference(const V& a, const V& b) {
  if (a.size() != b.size()) return 0;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (!(a[i] == b[i])) return static_cast<long>(i);
  return -1;
}

void expect_identical(const Dataset& got, const Dataset& want) {
  EXPECT_EQ(got.columns, want.columns);
  EXPECT_EQ(got.dt_s, want.dt_s);
  EXPECT_TRUE(got.rig.R_sensor_imu == want.rig.R_sensor_imu);
  EXPECT_TRUE(got.rig.p_sensor_imu_m == want.rig.p_sensor_imu_m);
  EXPECT_EQ(got.kinematics.mode, want.kinematics.mode);
  EXPECT_EQ(got.kinematics.angular_accel, want.kinematics.angular_accel);
  ASSERT_EQ(got.size(), want.size());
  EXPECT_EQ(first_difference(got.t_s, want.t_s), -1) << "t_s";
  long pose = -1;
  for (std::size_t i = 0; i < got.size() && pose < 0; ++i) {
    const model::PoseSignals g = got.pose(i), w = want.pose(i);
    if (!(g.R_base_sensor == w.R_base_sensor && g.t_rel_s == w.t_rel_s &&
          g.temperature_C == w.temperature_C && g.joints_rad == w.joints_rad))
      pose = static_cast<long>(i);
  }
  EXPECT_EQ(pose, -1) << "pose";
  EXPECT_EQ(first_difference(got.imu, want.imu), -1) << "imu (index of the value, 9 a row)";
  EXPECT_EQ(first_difference(got.measured, want.measured), -1) << "measured";
  EXPECT_EQ(first_difference(got.moving, want.moving), -1) << "moving";
  long joint_vel = -1;
  for (std::size_t i = 0; i < got.size() && joint_vel < 0; ++i)
    if (got.joint_vel_radps(i) != want.joint_vel_radps(i)) joint_vel = static_cast<long>(i);
  EXPECT_EQ(joint_vel, -1) << "joint_vel";
  EXPECT_EQ(first_difference(got.p_base_sensor_m, want.p_base_sensor_m), -1) << "p";
  long dictionary = -1;
  for (std::size_t i = 0; i < got.size() && dictionary < 0; ++i)
    if (!(got.dictionary(i) == want.dictionary(i))) dictionary = static_cast<long>(i);
  EXPECT_EQ(dictionary, -1) << "dictionary signals";
}

// make_dataset and read_dataset share DatasetBuilder, so their equality does not check it: here
// its differences (and the dictionary's, Dataset::dictionary) against motion whose derivatives
// are known. Position and joint angles
// quadratic in time, the gyro linear: the 3-point central differences are exact on every row
// (the first and last take their neighbour's: its slope), the joint velocity by
// forward differences is the chord's slope, ω̇ by differencing the gyro is its slope (zero on
// the first and last row), and the sensor moves on every row.
TEST(DatasetBuilder, DerivativesAreExactOnPolynomialMotion) {
  formats::Columns columns{.joints = true, .specific_force = true, .angular_rate = true};
  const std::size_t n = 40;
  const double t0 = 3.0, dt = 0.012;
  const Eigen::Vector3d pa(0.5, -0.25, 0.125), pb(0.1, 0.2, -0.3);  // p = pa t² + pb t
  const Eigen::Vector3d w0(0.1, -0.2, 0.3), w1(0.5, 0.25, -1.0);    // ω = w0 + w1 t
  auto joint = [](int j, double t) { return 0.1 * (j + 1) * t * t - 0.2 * j * t; };
  DatasetBuilder builder(columns);
  for (std::size_t i = 0; i < n; ++i) {
    formats::Sample s;
    s.t_s = t0 + dt * static_cast<double>(i);
    s.p_base_sensor_m = pa * s.t_s * s.t_s + pb * s.t_s;
    for (int j = 0; j < 6; ++j) s.joints_rad[static_cast<std::size_t>(j)] = joint(j, s.t_s);
    s.angular_rate_imu_radps = w0 + w1 * s.t_s;
    builder.add(s);
  }
  const Dataset d = builder.finish(formats::Rig{});
  ASSERT_EQ(d.size(), n);
  using model::Signal;
  const auto at = [](Signal s) { return static_cast<std::size_t>(s); };
  for (std::size_t i = 0; i < n; ++i) {
    SCOPED_TRACE("row " + std::to_string(i));
    // The first and last row take their neighbour's differences (the slope there).
    const double t = d.t_s[std::clamp<std::size_t>(i, 1, n - 2)];
    const model::DictionarySignals sig = d.dictionary(i);
    const Eigen::Vector3d v_B(sig[at(Signal::vx_B)], sig[at(Signal::vy_B)], sig[at(Signal::vz_B)]);
    EXPECT_LT((v_B - (2.0 * pa * t + pb)).norm(), 1e-9);
    for (int j = 0; j < 6; ++j) {
      const auto k = static_cast<std::size_t>(j);
      EXPECT_NEAR(sig[at(Signal::qd1) + k], 0.2 * (j + 1) * t - 0.2 * j, 1e-9);
      EXPECT_NEAR(sig[at(Signal::qdd1) + k], 0.2 * (j + 1), 1e-6);
      const std::size_t r = std::max<std::size_t>(i, 1);  // row 0 takes row 1's
      const double chord =
          (joint(j, d.t_s[r]) - joint(j, d.t_s[r - 1])) / (d.t_s[r] - d.t_s[r - 1]);
      EXPECT_NEAR(d.joint_vel_radps(i)[k], chord, 1e-9);
    }
    const Eigen::Vector3d dw = Eigen::Map<const Eigen::Vector3d>(&d.imu[i * 9 + 6]);
    EXPECT_LT((dw - (i == 0 || i + 1 == n ? Eigen::Vector3d::Zero() : w1)).norm(), 1e-9);
    EXPECT_EQ(d.moving[i], 1);
    EXPECT_EQ(d.pose(i).t_rel_s, d.t_s[i] - t0);
  }
  EXPECT_NEAR(d.dt_s, dt, 1e-15);
}

class StreamedDataset : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("zerog_streamed_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  // A simulator run of `seconds` (seed `seed`).
  static formats::Log sim_log(unsigned seed, double seconds) {
    sim::SimConfig c = sim::default_sim_config(seed);
    c.duration_limit_s = seconds;
    return sim::RigSimulator(c, sim::make_design(sim::DesignOptions{}).points_rad).run().log;
  }
  // Writes `log`, then reads it both ways (small chunks and buffers, and the defaults) and
  // compares.
  void expect_both_paths_equal(const formats::Log& log, const std::string& name) {
    SCOPED_TRACE(name);
    const fs::path csv = dir_ / (name + ".csv");
    formats::write_log(log, csv);
    const Dataset whole = make_dataset(formats::read_log(csv));
    formats::Rig rig;
    // 7 rows a chunk, 100 bytes a read (shorter than a row): every boundary is crossed.
    expect_identical(read_dataset(csv, &rig, 7, 100), whole);
    EXPECT_EQ(rig.name, log.rig.name);
    expect_identical(read_dataset(csv), whole);
  }
  fs::path dir_;
};

TEST_F(StreamedDataset, EqualsTheWholeFilePathOnSimulatorLogs) {
  formats::Log full = sim_log(4, 40.0);
  ASSERT_TRUE(full.columns.full_imu() && full.columns.joints && full.columns.position);
  ASSERT_GT(full.samples.size(), 3000u);
  expect_both_paths_equal(full, "all_columns");

  // Optional groups missing: no joints, temperature or position; the accelerometer alone.
  formats::Log partial = full;
  partial.columns.joints = false;
  partial.columns.temperature = false;
  partial.columns.position = false;
  partial.columns.angular_rate = false;
  expect_both_paths_equal(partial, "no_joints_temperature_position_gyro");

  // The gyro alone with the angular acceleration logged (imu_dw*_radps2, format version 2).
  formats::Log accel = sim_log(7, 20.0);
  accel.columns.specific_force = false;
  accel.columns.angular_accel = true;
  for (std::size_t i = 0; i < accel.samples.size(); ++i)
    accel.samples[i].angular_accel_imu_radps2 = {std::sin(0.01 * static_cast<double>(i)), 0.5,
                                                 -0.25 * std::cos(0.02 * static_cast<double>(i))};
  expect_both_paths_equal(accel, "gyro_and_imu_dw");

  // Static rows (no t_s): nothing differenced across rows.
  formats::Log held = sim_log(5, 5.0);
  held.columns.static_rows = true;
  held.columns.angular_rate = false;
  held.columns.specific_force = false;
  for (std::size_t i = 0; i < held.samples.size(); ++i)
    held.samples[i].t_s = static_cast<double>(i);
  expect_both_paths_equal(held, "static_rows");

  // The shortest log it takes, and one too short (the same error both ways).
  formats::Log three = full;
  three.samples.resize(3);
  expect_both_paths_equal(three, "three_rows");
  formats::Log two = full;
  two.samples.resize(2);
  const fs::path csv = dir_ / "two_rows.csv";
  formats::write_log(two, csv);
  EXPECT_THROW((void)read_dataset(csv), std::runtime_error);
}

// A bad cell far into a log (past many chunks and buffers): the error names the same file, line
// and column, with the same words, as the whole-file reader.
TEST_F(StreamedDataset, ErrorsAreTheWholeFileReadersErrors) {
  const formats::Log log = sim_log(4, 10.0);
  const fs::path csv = dir_ / "bad.csv";
  formats::write_log(log, csv);
  std::ifstream in(csv);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  // Line 501 (version line, header, then rows): its third cell becomes "abc".
  std::size_t at = 0;
  for (int line = 1; line < 501; ++line) at = text.find('\n', at) + 1;
  const std::size_t cell = text.find(',', text.find(',', at) + 1) + 1;
  text.replace(cell, text.find(',', cell) - cell, "abc");
  std::ofstream(csv, std::ios::binary) << text;
  std::string whole, streamed;
  try {
    (void)formats::read_log(csv);
  } catch (const formats::InputError& e) {
    whole = e.what();
    EXPECT_EQ(e.line(), 501);
  }
  try {
    (void)read_dataset(csv, nullptr, 7, 100);
  } catch (const formats::InputError& e) {
    streamed = e.what();
  }
  EXPECT_NE(whole.find(":501:"), std::string::npos) << whole;
  EXPECT_NE(whole.find("not a number: 'abc'"), std::string::npos) << whole;
  EXPECT_EQ(streamed, whole);
}

}  // namespace
}  // namespace zerog::ident
