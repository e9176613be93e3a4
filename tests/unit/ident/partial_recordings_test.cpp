// Recordings as real cells give them (issue 13, items 1 and 3), all written by the tests from the
// independent simulator: a static calibration table (no time, no header, comma-space, the 15
// attitudes of 001_… Appendix C) → import → bias + gravity and a tool change; and a moving run
// split into partial files (F/T at 700 Hz with base-frame axes, accelerometer only in g at
// 250 Hz, orientation only as a rotation matrix at 100 Hz) → import → fit, against the truth.
//
// The example table calib/static_table/table.csv is written by this test:
//   ZEROG_WRITE_CALIB=1 build/ci/tests/unit/ident_test --gtest_filter='StaticTable.*'
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>
#include <string>

#include "zerog/formats/log.hpp"
#include "zerog/ident/compare.hpp"
#include "zerog/ident/fit.hpp"
#include "zerog/io/import.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::ident {
namespace {

namespace fs = std::filesystem;
using model::Effect;
using ::testing::AllOf;
using ::testing::HasSubstr;
constexpr double kDeg = std::numbers::pi / 180.0;
constexpr double kG = model::kStandardGravity;

const fs::path kCalibDir = fs::path(ZEROG_SOURCE_DIR) / "calib/static_table";

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void write_text(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << p;
}

fs::path fresh_dir(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("zerog_partial_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::string cell(double v) {
  char buffer[40];
  std::snprintf(buffer, sizeof buffer, "%.9g", v);
  return buffer;
}

// The 15 attitudes of 001_… Appendix C as path points (zerog design --attitudes' default --arm).
std::vector<sim::JointVector> appendix_c_points() {
  sim::AttitudeDesignOptions o;
  o.arm_rad = {-90 * kDeg, -80 * kDeg, 125 * kDeg};
  return sim::design_from_attitudes(sim::read_attitudes(fs::path(ZEROG_SOURCE_DIR) /
                                                        "calib/poses/001_appendix_c_attitudes.csv"),
                                    o)
      .design.points_rad;
}

// A static table as a cell's calibration software writes it: one row per pose held still, the
// simulator's reading plus its F/T and accelerometer noise (config.noise, Omega191 quantisation),
// no time, no header, ", " between cells. Cells: Fx Fy Fz (N), Mx My Mz (N*m, about the sensor
// origin, sensor frame S), r11..r33 (R_base_sensor, row-major), ax ay az (accelerometer in g, IMU
// frame I).
std::string static_table(const sim::RigSimulator& simulator,
                         const std::vector<sim::JointVector>& points, std::uint64_t noise_seed) {
  const sim::NoiseConfig& noise = simulator.config().noise;
  std::mt19937_64 rng(noise_seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::string text =
      "# static calibration table: Fx, Fy, Fz [N], Mx, My, Mz [N*m], r11..r33, ax, ay, az [g]\n";
  for (const sim::JointVector& q : points) {
    sim::JointState js;
    js.q_rad = q;
    const sim::Measurement m = simulator.measure(js, 0.0);
    std::string line;
    auto put = [&](double v) { line += (line.empty() ? "" : ", ") + cell(v); };
    for (int k = 0; k < 6; ++k) {
      double v = m.wrench_sensor[k] + (k < 3 ? noise.force_N : noise.torque_Nm) * gauss(rng);
      if (noise.quantize)
        v = std::round(v / sim::kOmega191Resolution[k]) * sim::kOmega191Resolution[k];
      put(v);
    }
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) put(m.R_base_sensor(r, c));
    for (int k = 0; k < 3; ++k)
      put((m.imu.specific_force_imu_mps2[k] + noise.accel_mps2 * gauss(rng)) / kG);
    text += line + "\n";
  }
  return text;
}

struct Truth {
  double mass_kg;
  Eigen::Vector3d com_sensor_m;
  Eigen::Matrix<double, 6, 1> bias;
};
Truth truth_of(const sim::SimConfig& c) {
  Truth t{c.payload.mass_kg, c.payload.com_sensor_m, {}};
  for (int k = 0; k < 6; ++k) t.bias[k] = c.params.block(Effect::bias)[k];
  return t;
}

// Imports a static table with the example's mapping (copied beside it).
formats::Log import_table(const fs::path& dir, const std::string& table) {
  fs::copy_file(kCalibDir / "mapping.toml", dir / "mapping.toml",
                fs::copy_options::overwrite_existing);
  fs::copy_file(kCalibDir / "rig.rig.toml", dir / "rig.rig.toml",
                fs::copy_options::overwrite_existing);
  write_text(dir / "table.csv", table);
  return io::import_recordings(dir / "mapping.toml").log;
}

// Tolerances for a table of 15 single noisy rows (F/T σ 0.25 N / 0.03 N*m plus quantisation):
// the standard deviations of the least-squares fit are about 0.01 kg and 0.02 mm; the bounds
// below are > 10 σ, and far below what a wrong frame or a wrong row pairing would give (kg, cm).
constexpr double kMassTolerance = 1e-3;  // relative
constexpr double kComTolerance_m = 5e-4;
constexpr double kForceBiasTolerance_N = 1.0;
constexpr double kTorqueBiasTolerance_Nm = 0.1;

TEST(StaticTable, CalibExampleIsTheSimulatorsTableAndFits) {
  const sim::SimConfig config = sim::default_sim_config(1);
  const sim::RigSimulator simulator(config);
  const auto points = appendix_c_points();
  ASSERT_EQ(points.size(), 15u);
  const std::string table = static_table(simulator, points, 1001);
  if (std::getenv("ZEROG_WRITE_CALIB") != nullptr) {
    write_text(kCalibDir / "table.csv", table);
    formats::write_rig(simulator.rig(), kCalibDir / "rig.rig.toml");
    std::printf("wrote %s and its rig\n", (kCalibDir / "table.csv").c_str());
  }
  // The committed example is what this generator writes (regenerate as in the file comment).
  EXPECT_EQ(read_text(kCalibDir / "table.csv"), table)
      << "calib/static_table/table.csv is out of date: ZEROG_WRITE_CALIB=1 ident_test "
         "--gtest_filter='StaticTable.*'";
  const formats::Log log = io::import_recordings(kCalibDir / "mapping.toml").log;
  EXPECT_TRUE(log.columns.static_rows);
  EXPECT_FALSE(log.columns.position);
  EXPECT_TRUE(log.columns.specific_force);
  EXPECT_FALSE(log.columns.angular_rate);
  ASSERT_EQ(log.samples.size(), 15u);
}

TEST(StaticTable, BiasAndGravityFromTheTableOnSeveralSeeds) {
  const auto points = appendix_c_points();
  const fs::path dir = fresh_dir("static");
  for (std::uint64_t seed : {1u, 2u, 3u, 4u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const sim::SimConfig config = sim::default_sim_config(seed);
    const sim::RigSimulator simulator(config);
    const Dataset data = make_dataset(import_table(dir, static_table(simulator, points, seed)));
    ASSERT_EQ(data.size(), 15u);
    EXPECT_EQ(std::count(data.moving.begin(), data.moving.end(), 1), 0);  // held poses

    FitOptions fo;
    fo.effects = {Effect::bias, Effect::gravity};
    const FitResult r = fit(data, fo);
    ASSERT_TRUE(r.usable) << r.termination;
    const Truth truth = truth_of(config);
    const double* g = r.params.block(Effect::gravity);
    const double* b = r.params.block(Effect::bias);
    const double mass_error = g[0] / truth.mass_kg - 1.0;
    const Eigen::Vector3d com_error = Eigen::Vector3d(g[1], g[2], g[3]) - truth.com_sensor_m;
    double force_bias_error = 0.0, torque_bias_error = 0.0;
    for (int k = 0; k < 3; ++k) {
      force_bias_error = std::max(force_bias_error, std::abs(b[k] - truth.bias[k]));
      torque_bias_error = std::max(torque_bias_error, std::abs(b[3 + k] - truth.bias[3 + k]));
    }
    std::printf(
        "static table seed %llu: mass %.4f kg (error %+.4f %%), centre of mass error %.4f mm, "
        "bias error %.3f N / %.4f N*m\n",
        static_cast<unsigned long long>(seed), g[0], 100.0 * mass_error, 1e3 * com_error.norm(),
        force_bias_error, torque_bias_error);
    EXPECT_LT(std::abs(mass_error), kMassTolerance);
    EXPECT_LT(com_error.cwiseAbs().maxCoeff(), kComTolerance_m);
    EXPECT_LT(force_bias_error, kForceBiasTolerance_N);
    EXPECT_LT(torque_bias_error, kTorqueBiasTolerance_Nm);

    // What the table cannot feed is refused, naming what would make it work.
    fo.effects = {Effect::bias, Effect::gravity, Effect::imu_time_offset};
    EXPECT_THAT([&] { (void)fit(data, fo); },
                ::testing::ThrowsMessage<std::runtime_error>(HasSubstr("needs time (t_s)")));
    // A drift over the rows (their order is the table's time order) is fitted, per row; this
    // table has none.
    fo.effects = {Effect::bias, Effect::gravity, Effect::bias_drift};
    const FitResult drift = fit(data, fo);
    ASSERT_TRUE(drift.usable) << drift.termination;
    EXPECT_LT(std::abs(drift.params.block(Effect::bias_drift)[0]) * 14.0, 1.0);
    fo.effects = {Effect::bias, Effect::gravity, Effect::linear_inertia,
                  Effect::rotational_inertia};
    EXPECT_THAT([&] { (void)fit(data, fo); },
                ::testing::ThrowsMessage<std::runtime_error>(HasSubstr("map 'angular_rate'")));
    // The accelerometer alone feeds linear_inertia: gravity then comes from the accelerometer.
    fo.effects = {Effect::bias, Effect::gravity, Effect::linear_inertia};
    const FitResult li = fit(data, fo);
    ASSERT_TRUE(li.usable) << li.termination;
    EXPECT_LT(std::abs(li.params.block(Effect::gravity)[0] / truth.mass_kg - 1.0), 0.01);
  }
  fs::remove_all(dir);
}

// A static table split over two headerless files, row for row (issue 25, item 7): the wrenches
// in one, the poses and accelerations in the other, as many cells record them. Joined, it is the
// one-file table; a file with a row missing, or one file with time and one without, is refused
// with a message that says what would make it work.
// The table's data lines (comments dropped) cut after the sixth cell: the wrench part and the
// pose part (orientation matrix and specific force) of each row.
std::vector<std::pair<std::string, std::string>> split_rows(const std::string& table) {
  std::vector<std::pair<std::string, std::string>> rows;
  std::istringstream in(table);
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::size_t cut = 0;
    for (int k = 0; k < 6; ++k) cut = line.find(", ", cut) + 2;
    rows.emplace_back(line.substr(0, cut - 2), line.substr(cut));
  }
  return rows;
}

TEST(StaticTable, SplitOverTwoFilesIsJoinedRowByRow) {
  const auto points = appendix_c_points();
  const fs::path dir = fresh_dir("split");
  const sim::RigSimulator simulator(sim::default_sim_config(5));
  const std::string table = static_table(simulator, points, 5);
  const formats::Log whole = import_table(dir, table);
  // Cells 1-6 into wrench.csv, 7-18 into pose.csv (the comment line dropped: headerless).
  std::string wrench, pose;
  for (const auto& [w, p] : split_rows(table)) {
    wrench += w + "\n";
    pose += p + "\n";
  }
  write_text(dir / "wrench.csv", wrench);
  write_text(dir / "pose.csv", pose);
  const std::string mapping =
      "format = \"zerog-import\"\nversion = 1\nrig_file = \"rig.rig.toml\"\nmaster = \"ft\"\n\n"
      "[files.ft]\npath = \"wrench.csv\"\nheader = false\ndelimiter = \", \"\n"
      "force = { columns = [1, 2, 3], unit = \"N\" }\n"
      "torque = { columns = [4, 5, 6], unit = \"N*m\" }\n\n"
      "[files.pose]\npath = \"pose.csv\"\nheader = false\ndelimiter = \", \"\n"
      "orientation = { type = \"matrix\", columns = [1, 2, 3, 4, 5, 6, 7, 8, 9] }\n"
      "specific_force = { columns = [10, 11, 12], unit = \"g\" }\n";
  write_text(dir / "split.toml", mapping);
  const io::ImportResult joined = io::import_recordings(dir / "split.toml");
  ASSERT_TRUE(joined.log.columns.static_rows);
  ASSERT_EQ(joined.log.samples.size(), whole.samples.size());
  for (std::size_t i = 0; i < whole.samples.size(); ++i) {
    EXPECT_EQ(joined.log.samples[i].force_sensor_N, whole.samples[i].force_sensor_N) << i;
    EXPECT_EQ(joined.log.samples[i].torque_sensor_Nm, whole.samples[i].torque_sensor_Nm) << i;
    // The rows of a second file pass the merge's bracket (weight 0 on the next row): equal
    // within rounding.
    EXPECT_LT(
        (joined.log.samples[i].q_base_sensor.coeffs() - whole.samples[i].q_base_sensor.coeffs())
            .norm(),
        1e-12)
        << i;
    EXPECT_LT(
        (joined.log.samples[i].specific_force_imu_mps2 - whole.samples[i].specific_force_imu_mps2)
            .norm(),
        1e-12)
        << i;
  }
  EXPECT_THAT(joined.report.summary(), HasSubstr("joined row by row with 'pose'"));

  // One pose short: refused, naming both files' rows.
  write_text(dir / "pose.csv", pose.substr(0, pose.rfind('\n', pose.size() - 2) + 1));
  EXPECT_THAT([&] { (void)io::import_recordings(dir / "split.toml"); },
              ::testing::ThrowsMessage<formats::InputError>(
                  AllOf(HasSubstr("files.pose has 14 rows and files.ft (wrench.csv) 15"),
                        HasSubstr("one row per pose, in the same order"))));
  // Time in one file only: refused, saying give time to all or none.
  write_text(dir / "pose.csv", pose);
  std::string timed = mapping;
  timed.insert(timed.find("force = "), "time = { column = 1, unit = \"s\" }\n");
  write_text(dir / "timed.toml", timed);
  EXPECT_THAT([&] { (void)io::import_recordings(dir / "timed.toml"); },
              ::testing::ThrowsMessage<formats::InputError>(
                  HasSubstr("files.pose has no 'time' but files.ft has")));
  fs::remove_all(dir);
}

TEST(StaticTable, SplitByPoseIndexIsJoinedByIt) {
  // The wrench file numbers its poses 1..15 in order but pose 9 failed (no wrench); the pose file
  // lists all 15 in another order. Joined by the index: 14 rows, each with its own pose.
  const auto points = appendix_c_points();
  const fs::path dir = fresh_dir("pose_index");
  const sim::RigSimulator simulator(sim::default_sim_config(5));
  const std::string table = static_table(simulator, points, 5);
  const formats::Log whole = import_table(dir, table);
  std::vector<std::string> wrench, pose;
  for (const auto& [w, p] : split_rows(table)) {
    const std::string index = std::to_string(wrench.size() + 1);
    wrench.push_back(index + ", " + w + "\n");
    pose.push_back(p + ", " + index + "\n");
  }
  ASSERT_EQ(wrench.size(), 15u);
  std::string wrench_text = "pose, fx, fy, fz, tx, ty, tz\n", pose_text;
  for (std::size_t i = 0; i < wrench.size(); ++i)
    if (i != 8) wrench_text += wrench[i];
  const std::size_t order[] = {14, 3, 0, 7, 8, 1, 12, 5, 10, 2, 13, 6, 4, 11, 9};
  for (std::size_t i : order) pose_text += pose[i];
  write_text(dir / "wrench.csv", wrench_text);
  write_text(dir / "pose.csv", pose_text);
  const std::string mapping =
      "format = \"zerog-import\"\nversion = 1\nrig_file = \"rig.rig.toml\"\nmaster = \"ft\"\n\n"
      "[files.ft]\npath = \"wrench.csv\"\ndelimiter = \", \"\npose_index = { column = \"pose\" }\n"
      "force = { columns = [\"fx\", \"fy\", \"fz\"], unit = \"N\" }\n"
      "torque = { columns = [\"tx\", \"ty\", \"tz\"], unit = \"N*m\" }\n\n"
      "[files.pose]\npath = \"pose.csv\"\nheader = false\ndelimiter = \", \"\n"
      "pose_index = { column = 13 }\n"
      "orientation = { type = \"matrix\", columns = [1, 2, 3, 4, 5, 6, 7, 8, 9] }\n"
      "specific_force = { columns = [10, 11, 12], unit = \"g\" }\n";
  write_text(dir / "split.toml", mapping);
  const io::ImportResult joined = io::import_recordings(dir / "split.toml");
  ASSERT_TRUE(joined.log.columns.static_rows);
  ASSERT_EQ(joined.log.samples.size(), 14u);
  for (std::size_t i = 0; i < 14; ++i) {
    const formats::Sample& want = whole.samples[i < 8 ? i : i + 1];
    const formats::Sample& got = joined.log.samples[i];
    EXPECT_EQ(got.t_s, static_cast<double>(i));
    EXPECT_EQ(got.force_sensor_N, want.force_sensor_N) << i;
    // The same rotation (a quaternion up to sign: the reader keeps neighbours in one
    // hemisphere, and the rows came in another order).
    EXPECT_LT(std::min((got.q_base_sensor.coeffs() - want.q_base_sensor.coeffs()).norm(),
                       (got.q_base_sensor.coeffs() + want.q_base_sensor.coeffs()).norm()),
              1e-12)
        << i;
    EXPECT_LT((got.specific_force_imu_mps2 - want.specific_force_imu_mps2).norm(), 1e-12) << i;
  }
  EXPECT_THAT(joined.report.summary(),
              AllOf(HasSubstr("joined by pose index ('pose') with 'pose'"),
                    HasSubstr("0 master rows dropped"), HasSubstr("1 of its rows not used"),
                    HasSubstr("rows out: 14 of 14 master rows")));

  // A pose twice in a file, a fractional index, an index in one file only: refused, saying where.
  write_text(dir / "pose.csv", pose_text + pose[3]);
  EXPECT_THAT(
      [&] { (void)io::import_recordings(dir / "split.toml"); },
      ::testing::ThrowsMessage<formats::InputError>(AllOf(
          HasSubstr("pose.csv:16:"), HasSubstr("pose index 4"), HasSubstr("at line 2 already"))));
  write_text(dir / "pose.csv", pose_text.substr(0, pose_text.rfind(", ")) + ", 10.5\n");
  EXPECT_THAT([&] { (void)io::import_recordings(dir / "split.toml"); },
              ::testing::ThrowsMessage<formats::InputError>(HasSubstr("is not a whole number")));
  std::string half = mapping;
  half.erase(half.find("pose_index = { column = 13 }\n"), 29);
  write_text(dir / "half.toml", half);
  EXPECT_THAT([&] { (void)io::import_recordings(dir / "half.toml"); },
              ::testing::ThrowsMessage<formats::InputError>(
                  HasSubstr("files.ft has a pose_index and files.pose has none")));
  fs::remove_all(dir);
}

TEST(StaticTable, ToolChangeFromTheTable) {
  // The sensor model (bias) is known, e.g. from a calibration run: here the simulator's truth.
  // A new tool of 60 kg is held through the 15 attitudes; only its gravity is re-identified.
  const auto points = appendix_c_points();
  const fs::path dir = fresh_dir("tool");
  for (std::uint64_t seed : {1u, 2u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    sim::SimConfig tool = sim::default_sim_config(seed);
    const io::ModelFile sensor_model = sim::RigSimulator(tool).truth();
    tool.payload.mass_kg = 60.0;
    tool.payload.com_sensor_m = Eigen::Vector3d(0.08, -0.06, 0.18);
    tool.payload.inertia_com_sensor_kgm2 = sim::box_inertia_kgm2(60.0);
    const sim::RigSimulator simulator(tool);
    const Dataset data =
        make_dataset(import_table(dir, static_table(simulator, points, seed + 100)));
    model::ModelParams base = sensor_model.params;
    base.effects = {Effect::bias, Effect::gravity};
    const ToolChangeResult tc = fit_tool_change(data, base, {});
    ASSERT_TRUE(tc.fit.usable) << tc.fit.termination;
    EXPECT_EQ(tc.dwells, 15u);  // every row of the table is a pose of its own
    EXPECT_EQ(tc.static_samples, 15u);
    EXPECT_GT(tc.spread_deg, 30.0);
    const double* g = tc.fit.params.block(Effect::gravity);
    std::printf(
        "tool change from the table, seed %llu: mass %.4f kg, centre of mass error %.4f mm\n",
        static_cast<unsigned long long>(seed), g[0],
        1e3 * (Eigen::Vector3d(g[1], g[2], g[3]) - tool.payload.com_sensor_m).norm());
    EXPECT_LT(std::abs(g[0] / 60.0 - 1.0), kMassTolerance);
    EXPECT_LT((Eigen::Vector3d(g[1], g[2], g[3]) - tool.payload.com_sensor_m).cwiseAbs().maxCoeff(),
              kComTolerance_m);
  }
  fs::remove_all(dir);
}

// ---- a moving run in partial files -------------------------------------------------------------

// Writes one simulated stream at its own rate. `row` returns the cells after the time.
template <typename Row>
void write_stream(const fs::path& file, const std::string& header, const formats::Log& log,
                  Row row) {
  std::string text = header + "\n";
  for (const formats::Sample& s : log.samples) text += cell(s.t_s) + "," + row(s) + "\n";
  write_text(file, text);
}

// One truth (seeded effect values), recorded at `period_s` with the noise of `noise_seed`.
sim::SimConfig moving_config(std::uint64_t seed, std::uint64_t noise_seed, double period_s) {
  sim::SimConfig c = sim::default_sim_config(seed);
  c.seed = noise_seed;
  c.effects = sim::parse_sim_effects("-rotational_inertia");  // bias, gravity, linear inertia
  c.period_s = period_s;
  c.duration_limit_s = 90.0;
  return c;
}

TEST(PartialFiles, AccelerometerOnlyOrientationOnlyBaseFrameWrench) {
  sim::DesignOptions oa;
  oa.kind = sim::DesignKind::oa;
  const auto points = sim::make_design(oa).points_rad;
  const fs::path dir = fresh_dir("partial");
  const std::uint64_t seed = 5;
  // Three recorders on one clock: the same motion sampled at 700, 250 and 100 Hz.
  const formats::Log ft =
      sim::RigSimulator(moving_config(seed, seed, 1.0 / 700.0), points).run().log;
  const formats::Log acc =
      sim::RigSimulator(moving_config(seed, seed + 1, 1.0 / 250.0), points).run().log;
  const sim::RigSimulator robot_sim(moving_config(seed, seed + 2, 1.0 / 100.0), points);
  const sim::SimOutput robot = robot_sim.run();
  // F/T in the base frame's axes (the recording software rotated it): F_B = R_BS F_S.
  write_stream(dir / "ft.csv", "t,FxB,FyB,FzB,MxB,MyB,MzB", ft, [](const formats::Sample& s) {
    const Eigen::Vector3d F = s.q_base_sensor * s.force_sensor_N;
    const Eigen::Vector3d M = s.q_base_sensor * s.torque_sensor_Nm;
    return cell(F.x()) + "," + cell(F.y()) + "," + cell(F.z()) + "," + cell(M.x()) + "," +
           cell(M.y()) + "," + cell(M.z());
  });
  write_stream(dir / "acc.csv", "t,ax_g,ay_g,az_g", acc, [](const formats::Sample& s) {
    const Eigen::Vector3d a = s.specific_force_imu_mps2 / kG;
    return cell(a.x()) + "," + cell(a.y()) + "," + cell(a.z());
  });
  write_stream(dir / "pose.csv", "t,r11,r12,r13,r21,r22,r23,r31,r32,r33", robot.log,
               [](const formats::Sample& s) {
                 const Eigen::Matrix3d R = s.q_base_sensor.toRotationMatrix();
                 std::string out;
                 for (int r = 0; r < 3; ++r)
                   for (int c = 0; c < 3; ++c) out += (out.empty() ? "" : ",") + cell(R(r, c));
                 return out;
               });
  formats::write_rig(robot.log.rig, dir / "rig.rig.toml");
  write_text(
      dir / "mapping.toml",
      "format = \"zerog-import\"\nversion = 1\nmaster = \"ft\"\nrig_file = \"rig.rig.toml\"\n"
      "[files.ft]\npath = \"ft.csv\"\ntime = { column = \"t\", unit = \"s\" }\n"
      "force = { columns = [\"FxB\", \"FyB\", \"FzB\"], unit = \"N\", frame = \"base\" }\n"
      "torque = { columns = [\"MxB\", \"MyB\", \"MzB\"], unit = \"N*m\", frame = \"base\" "
      "}\n"
      "[files.acc]\npath = \"acc.csv\"\ntime = { column = \"t\", unit = \"s\" }\n"
      "specific_force = { columns = [\"ax_g\", \"ay_g\", \"az_g\"], unit = \"g\" }\n"
      "[files.pose]\npath = \"pose.csv\"\ntime = { column = \"t\", unit = \"s\" }\n"
      "orientation = { type = \"matrix\", columns = [\"r11\", \"r12\", \"r13\", \"r21\", "
      "\"r22\", \"r23\", \"r31\", \"r32\", \"r33\"] }\n");
  const io::ImportResult imported = io::import_recordings(dir / "mapping.toml");
  const formats::Log& log = imported.log;
  EXPECT_EQ(log.columns, (formats::Columns{.specific_force = true, .position = false}));
  EXPECT_GT(log.samples.size(), 50000u);
  std::printf("%s", imported.report.summary().c_str());

  // Through the log format (version 2) and back.
  formats::write_log(log, dir / "run.csv");
  const Dataset data = make_dataset(formats::read_log(dir / "run.csv"));
  const Truth truth = truth_of(robot_sim.config());

  FitOptions fo;
  fo.effects = {Effect::bias, Effect::gravity};
  const FitResult static_model = fit(data, fo);
  fo.effects = {Effect::bias, Effect::gravity, Effect::linear_inertia};
  const FitResult r = fit(data, fo);
  ASSERT_TRUE(static_model.usable && r.usable) << r.termination;
  const Comparison without = compare(residuals(static_model.params, data), data);
  const Comparison with = compare(residuals(r.params, data), data);
  const double* g = r.params.block(Effect::gravity);
  const double mass_error = g[0] / truth.mass_kg - 1.0;
  const Eigen::Vector3d com_error = Eigen::Vector3d(g[1], g[2], g[3]) - truth.com_sensor_m;
  std::printf(
      "partial files: mass %.4f kg (error %+.4f %%), centre of mass error %.3f mm; moving force "
      "RMS %.3f N with linear_inertia from the accelerometer, %.3f N without\n",
      g[0], 100.0 * mass_error, 1e3 * com_error.norm(), with.moving.force_rms,
      without.moving.force_rms);
  EXPECT_LT(std::abs(mass_error), 0.005);
  EXPECT_LT(com_error.cwiseAbs().maxCoeff(), 0.005);
  // The accelerometer explains the moving segments' inertial force.
  EXPECT_LT(with.moving.force_rms, 0.5 * without.moving.force_rms);
  // The gyroscope is missing: rotational inertia is refused with the column that would feed it.
  fo.effects = {Effect::bias, Effect::gravity, Effect::linear_inertia, Effect::rotational_inertia};
  EXPECT_THAT([&] { (void)fit(data, fo); },
              ::testing::ThrowsMessage<std::runtime_error>(HasSubstr("imu_wx_radps")));

  // kinematics = "auto" (issue 13 item 2): ω and ω̇ from the orientation stream (Savitzky–Golay,
  // proto/robot_kinematics.md), the accelerometer still the specific force. linear_inertia's
  // lever-arm terms (ω̇ × r + ω × (ω × r) to the centre of mass, 0.25 m away) now have their
  // rates, and the moving error falls well below what the accelerometer alone leaves.
  std::string auto_mapping = read_text(dir / "mapping.toml");
  auto_mapping.insert(auto_mapping.find("[files.ft]"), "kinematics = \"auto\"\n");
  write_text(dir / "mapping.toml", auto_mapping);
  const formats::Log derived = io::import_recordings(dir / "mapping.toml").log;
  EXPECT_EQ(derived.rig.kinematics.angular_rate, formats::KinematicsOrigin::pose);
  EXPECT_EQ(derived.rig.kinematics.specific_force, formats::KinematicsOrigin::imu);
  const Dataset with_rates = make_dataset(derived);
  fo.effects = {Effect::bias, Effect::gravity, Effect::linear_inertia};
  const FitResult rr = fit(with_rates, fo);
  ASSERT_TRUE(rr.usable) << rr.termination;
  const Comparison rates = compare(residuals(rr.params, with_rates), with_rates);
  std::printf(
      "partial files, kinematics = \"auto\" (ω, ω̇ from the orientation): moving force RMS %.3f "
      "N (%.3f N from the accelerometer alone)\n",
      rates.moving.force_rms, with.moving.force_rms);
  EXPECT_LT(rates.moving.force_rms, 0.3 * with.moving.force_rms);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace zerog::ident
