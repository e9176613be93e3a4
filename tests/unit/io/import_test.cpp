// `zerog import` (proto/import_mapping.md): round trips through user-style files, merging of
// files at different rates, unit conversion, and errors with their exact positions.
#include "zerog/io/import.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <numbers>
#include <random>
#include <tuple>

#include "test_util.hpp"
#include "zerog/formats/log.hpp"

namespace zerog::io {

using formats::read_log;

using formats::Columns;
using formats::KinematicsOrigin;
using formats::Log;
using formats::Rig;
using formats::Sample;
using formats::write_log;
using formats::write_rig;
namespace {

namespace fs = std::filesystem;
using test::expect_input_error;
using test::read_text;
using test::write_text;

constexpr double kG = 9.80665;
constexpr double kDeg = std::numbers::pi / 180.0;

std::string fmt(const char* format, ...) {
  char buffer[1024];
  va_list args;
  va_start(args, format);
  std::vsnprintf(buffer, sizeof buffer, format, args);
  va_end(args);
  return buffer;
}

std::string rig_table() {
  return "[rig]\n"
         "name = \"import-test\"\n"
         "robot = \"KR 210 R2700\"\n"
         "[rig.flange_sensor]\n"
         "p_m = [0.0, 0.0, 0.05]\n"
         "q_wxyz = [1.0, 0.0, 0.0, 0.0]\n"
         "[rig.sensor_imu]\n"
         "p_m = [0.0, 0.0, 0.0]\n"
         "q_wxyz = [1.0, 0.0, 0.0, 0.0]\n";
}

// A log with smooth-ish but arbitrary values at 1 kHz.
Log reference_log(std::size_t rows) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Log log;
  log.rig.name = "round-trip";
  log.rig.sample_period_s = 0.001;
  log.rig.flange_sensor.p_m = {0.0, 0.0, 0.06};
  log.columns = {.joints = true, .specific_force = true, .angular_rate = true, .temperature = true};
  for (std::size_t i = 0; i < rows; ++i) {
    Sample s;
    s.t_s = 10.0 + 0.001 * static_cast<double>(i);
    for (double& q : s.joints_rad) q = 2.0 * u(rng);
    s.p_base_sensor_m = {1.5 * u(rng), 1.5 * u(rng), 1.0 + 0.5 * u(rng)};
    s.q_base_sensor = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
    s.specific_force_imu_mps2 = 15.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    s.angular_rate_imu_radps = 2.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    s.force_sensor_N = 1200.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    s.torque_sensor_Nm = 250.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    s.temperature_C = 30.0 + 5.0 * u(rng);
    log.samples.push_back(s);
  }
  return log;
}

// KUKA A, B, C (rad) of a rotation R = Rz(A) Ry(B) Rx(C).
Eigen::Vector3d kuka_abc_of(const Eigen::Matrix3d& R) {
  return {std::atan2(R(1, 0), R(0, 0)), std::asin(-R(2, 0)), std::atan2(R(2, 1), R(2, 2))};
}

enum class Style { kuka_abc, matrix, quaternion_xyzw };

// Writes `log` as a user would record it: three files in µs/deg/mm/g/N*mm/K with different
// delimiters, plus the mapping. The robot file reports the flange pose for kuka_abc.
fs::path export_user_files(const Log& log, const fs::path& dir, Style style) {
  std::string wrench = "time_us,Fx,Fy,Fz,Tx_Nmm,Ty_Nmm,Tz_Nmm,T_K\n";
  std::string imu = "# IMU export\nt_us\tax_g\tay_g\taz_g\tgx_dps\tgy_dps\tgz_dps\n";
  std::string robot = "time_us;A1;A2;A3;A4;A5;A6;X;Y;Z";
  std::string orientation;
  if (style == Style::kuka_abc) {
    robot += ";A;B;C\n";
    orientation = "{ type = \"kuka_abc\", columns = [\"A\", \"B\", \"C\"], unit = \"deg\" }";
  } else if (style == Style::matrix) {
    robot += ";r11;r12;r13;r21;r22;r23;r31;r32;r33\n";
    orientation =
        "{ type = \"matrix\", columns = [\"r11\", \"r12\", \"r13\", \"r21\", \"r22\", \"r23\", "
        "\"r31\", \"r32\", \"r33\"] }";
  } else {
    robot += ";qx;qy;qz;qw\n";
    orientation =
        "{ type = \"quaternion\", order = \"xyzw\", columns = [\"qx\", \"qy\", \"qz\", \"qw\"] }";
  }
  const bool flange = style == Style::kuka_abc;
  for (const Sample& s : log.samples) {
    const double t_us = s.t_s * 1e6;
    const Eigen::Vector3d& F = s.force_sensor_N;
    const Eigen::Vector3d M = s.torque_sensor_Nm * 1e3;
    wrench += fmt("%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", t_us, F.x(), F.y(), F.z(),
                  M.x(), M.y(), M.z(), s.temperature_C + 273.15);
    const Eigen::Vector3d a = s.specific_force_imu_mps2 / kG;
    const Eigen::Vector3d w = s.angular_rate_imu_radps / kDeg;
    imu += fmt("%.17g\t%.17g\t%.17g\t%.17g\t%.17g\t%.17g\t%.17g\n", t_us, a.x(), a.y(), a.z(),
               w.x(), w.y(), w.z());
    robot += fmt("%.17g", t_us);
    for (double q : s.joints_rad) robot += fmt(";%.17g", q / kDeg);
    Eigen::Vector3d p = s.p_base_sensor_m;
    Eigen::Matrix3d R = s.q_base_sensor.toRotationMatrix();
    if (flange) {  // p_BF = p_BS − R_BF p_FS with R_FS = I
      p -= R * log.rig.flange_sensor.p_m;
    }
    p *= 1e3;
    robot += fmt(";%.17g;%.17g;%.17g", p.x(), p.y(), p.z());
    if (style == Style::kuka_abc) {
      const Eigen::Vector3d abc = kuka_abc_of(R) / kDeg;
      robot += fmt(";%.17g;%.17g;%.17g", abc.x(), abc.y(), abc.z());
    } else if (style == Style::matrix) {
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) robot += fmt(";%.17g", R(r, c));
      }
    } else {
      const Eigen::Quaterniond& q = s.q_base_sensor;
      robot += fmt(";%.17g;%.17g;%.17g;%.17g", q.x(), q.y(), q.z(), q.w());
    }
    robot += "\n";
  }
  write_text(dir / "wrench.csv", wrench);
  write_text(dir / "imu.txt", imu);
  write_text(dir / "robot.csv", robot);
  write_rig(log.rig, dir / "rig.rig.toml");
  const std::string mapping =
      std::string("format = \"zerog-import\"\nversion = 1\nmaster = \"wrench\"\n") +
      "pose_of = \"" + (flange ? "flange" : "sensor") + "\"\nrig_file = \"rig.rig.toml\"\n" +
      "[files.wrench]\npath = \"wrench.csv\"\ntime = { column = \"time_us\", unit = \"us\" }\n"
      "force = { columns = [\"Fx\", \"Fy\", \"Fz\"], unit = \"N\" }\n"
      "torque = { columns = [\"Tx_Nmm\", \"Ty_Nmm\", \"Tz_Nmm\"], unit = \"N*mm\" }\n"
      "temperature = { column = \"T_K\", unit = \"K\" }\n"
      "[files.imu]\npath = \"imu.txt\"\ndelimiter = \"tab\"\n"
      "time = { column = \"t_us\", unit = \"us\" }\n"
      "specific_force = { columns = [\"ax_g\", \"ay_g\", \"az_g\"], unit = \"g\" }\n"
      "angular_rate = { columns = [\"gx_dps\", \"gy_dps\", \"gz_dps\"], unit = \"deg/s\" }\n"
      "[files.robot]\npath = \"robot.csv\"\ndelimiter = \"semicolon\"\n"
      "time = { column = \"time_us\", unit = \"us\" }\n"
      "joints = { columns = [\"A1\", \"A2\", \"A3\", \"A4\", \"A5\", \"A6\"], unit = \"deg\" }\n"
      "position = { columns = [\"X\", \"Y\", \"Z\"], unit = \"mm\" }\n"
      "orientation = " +
      orientation + "\n";
  write_text(dir / "mapping.toml", mapping);
  return dir / "mapping.toml";
}

// Equal within `rel` relative to max(1, |value|): 1e-12 straight from the importer, 1e-8 after
// the log went through its 9-digit text form.
void expect_close(const Log& got, const Log& want, double rel) {
  EXPECT_EQ(got.columns, want.columns);
  ASSERT_EQ(got.samples.size(), want.samples.size());
  auto near = [rel](const auto& g, const auto& w) {
    for (int k = 0; k < static_cast<int>(w.size()); ++k) {
      if (std::abs(g[k] - w[k]) > rel * std::max(1.0, std::abs(w[k]))) return false;
    }
    return true;
  };
  for (std::size_t i = 0; i < want.samples.size(); ++i) {
    const Sample& g = got.samples[i];
    const Sample& w = want.samples[i];
    EXPECT_NEAR(g.t_s, w.t_s, 1e-12) << i;
    EXPECT_TRUE(near(g.joints_rad, w.joints_rad)) << i;
    EXPECT_TRUE(near(g.p_base_sensor_m, w.p_base_sensor_m)) << i;
    EXPECT_LT(g.q_base_sensor.angularDistance(w.q_base_sensor), 1e-7) << i;
    EXPECT_TRUE(near(g.specific_force_imu_mps2, w.specific_force_imu_mps2)) << i;
    EXPECT_TRUE(near(g.angular_rate_imu_radps, w.angular_rate_imu_radps)) << i;
    EXPECT_TRUE(near(g.force_sensor_N, w.force_sensor_N)) << i;
    EXPECT_TRUE(near(g.torque_sensor_Nm, w.torque_sensor_Nm)) << i;
    EXPECT_TRUE(
        near(std::array<double, 1>{g.temperature_C}, std::array<double, 1>{w.temperature_C}))
        << i;
  }
}

using ImportTest = test::TempDirTest;

TEST_F(ImportTest, RoundTripKukaAbcFlangePose) {
  const Log log = reference_log(300);
  const fs::path mapping = export_user_files(log, dir_, Style::kuka_abc);
  const ImportReport report = import_to_log(mapping, path("out.csv"));
  EXPECT_EQ(report.master_rows, 300u);
  EXPECT_EQ(report.rows_out, 300u);
  const Log back = read_log(path("out.csv"));
  expect_close(back, log, 1e-8);
  EXPECT_EQ(back.rig.name, "round-trip");
  EXPECT_EQ(back.rig.flange_sensor.p_m.z(), 0.06);
}

TEST_F(ImportTest, RoundTripRotationMatrix) {
  const Log log = reference_log(200);
  const ImportResult result = import_recordings(export_user_files(log, dir_, Style::matrix));
  expect_close(result.log, log, 1e-12);
}

TEST_F(ImportTest, RoundTripQuaternionScalarLast) {
  const Log log = reference_log(200);
  const ImportResult result =
      import_recordings(export_user_files(log, dir_, Style::quaternion_xyzw));
  expect_close(result.log, log, 1e-12);
  // Every file read is an input that must never be overwritten.
  EXPECT_EQ(result.inputs.size(), 5u);  // mapping, three data files, rig file
}

// ---- merging files at different rates -------------------------------------------------------

// Analytic signals of the merge test, functions of the common clock t (s).
Eigen::Vector3d force_at(double t) { return {100.0 + 3.0 * t, -20.0, 900.0 - 7.0 * t}; }
Eigen::Vector3d specific_force_at(double t) { return {0.5 + 2.0 * t, -1.0 * t, -kG + 0.25 * t}; }
double rate_z_at(double t) { return 0.8 * std::sin(2.0 * std::numbers::pi * 3.0 * t); }
Eigen::Vector3d position_at(double t) { return {1.2 + 0.1 * t, -0.4 + 0.05 * t, 1.1}; }
const Eigen::Vector3d kAxis = Eigen::Vector3d(1.0, 2.0, 2.0) / 3.0;
Eigen::Quaterniond orientation_at(double t) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(0.3 + 1.5 * t, kAxis));  // constant rate: slerp exact
}

class MergeTest : public test::TempDirTest {
 protected:
  void SetUp() override {
    TempDirTest::SetUp();
    // Master: F/T at 1 kHz, t = 0 … 0.999 s.
    std::string ft = "t,fx,fy,fz,mx,my,mz\n";
    for (int i = 0; i < 1000; ++i) {
      const double t = 0.001 * i;
      const Eigen::Vector3d F = force_at(t);
      ft += fmt("%.17g,%.17g,%.17g,%.17g,0,0,0\n", t, F.x(), F.y(), F.z());
      master_t.push_back(t);
    }
    write_text(path("ft.csv"), ft);
    // IMU at 2 kHz on its own clock, 2 ms ahead: t_imu = t + 0.002, in ms.
    std::string imu = "t_ms ax ay az wx wy wz\n";
    for (int i = 0; i < 2010; ++i) {
      const double t = -0.001 + 0.0005 * i;
      const Eigen::Vector3d f = specific_force_at(t) / kG;
      imu += fmt("%.17g %.17g %.17g %.17g 0 0 %.17g\n", (t + 0.002) * 1e3, f.x(), f.y(), f.z(),
                 rate_z_at(t));
    }
    write_text(path("imu.txt"), imu);
    // Robot at 12 ms from 0.05 s on, for 71 samples (last at 0.89 s).
    std::string robot = "t;x;y;z;qw;qx;qy;qz;a1\n";
    for (int i = 0; i <= 70; ++i) {
      const double t = 0.05 + 0.012 * i;
      const Eigen::Vector3d p = position_at(t);
      const Eigen::Quaterniond q = orientation_at(t);
      robot += fmt("%.17g;%.17g;%.17g;%.17g;%.17g;%.17g;%.17g;%.17g;%.17g\n", t, p.x(), p.y(),
                   p.z(), q.w(), q.x(), q.y(), q.z(), 10.0 * t);
      robot_t.push_back(t);
    }
    write_text(path("robot.csv"), robot);
  }

  std::string mapping(const std::string& robot_extra = "") const {
    return "format = \"zerog-import\"\nversion = 1\nmaster = \"ft\"\n" + rig_table() +
           "[files.ft]\npath = \"ft.csv\"\ntime = { column = \"t\", unit = \"s\" }\n"
           "force = { columns = [\"fx\", \"fy\", \"fz\"], unit = \"N\" }\n"
           "torque = { columns = [\"mx\", \"my\", \"mz\"], unit = \"N*m\" }\n"
           "[files.imu]\npath = \"imu.txt\"\ndelimiter = \"whitespace\"\n"
           "time = { column = \"t_ms\", unit = \"ms\" }\ntime_offset_s = -0.002\n"
           "specific_force = { columns = [\"ax\", \"ay\", \"az\"], unit = \"g\" }\n"
           "angular_rate = { columns = [\"wx\", \"wy\", \"wz\"], unit = \"rad/s\" }\n"
           "[files.robot]\npath = \"robot.csv\"\ndelimiter = \"semicolon\"\n"
           "time = { column = \"t\", unit = \"s\" }\n" +
           robot_extra +
           "position = { columns = [\"x\", \"y\", \"z\"], unit = \"m\" }\n"
           "orientation = { type = \"quaternion\", columns = [\"qw\", \"qx\", \"qy\", \"qz\"] }\n"
           "joints = { columns = [\"a1\", \"a1\", \"a1\", \"a1\", \"a1\", \"a1\"], unit = \"rad\" "
           "}\n";
  }

  std::vector<double> master_t;
  std::vector<double> robot_t;
};

TEST_F(MergeTest, InterpolatesOntoTheMasterAndCountsDroppedRows) {
  write_text(path("map.toml"), mapping());
  const ImportResult result = import_recordings(path("map.toml"));
  const ImportReport& r = result.report;

  std::size_t before = 0, after = 0;
  for (double t : master_t) {
    before += t < robot_t.front() ? 1 : 0;
    after += t > robot_t.back() ? 1 : 0;
  }
  EXPECT_EQ(before, 50u);  // t = 0 … 0.049
  EXPECT_EQ(after, 109u);  // t = 0.891 … 0.999
  ASSERT_EQ(r.files.size(), 3u);
  EXPECT_EQ(r.files[0].name, "ft");
  EXPECT_TRUE(r.files[0].master);
  EXPECT_EQ(r.files[0].rows_read, 1000u);
  EXPECT_EQ(r.files[1].name, "imu");
  EXPECT_EQ(r.files[1].rows_read, 2010u);
  EXPECT_EQ(r.files[1].master_rows_before + r.files[1].master_rows_after, 0u);
  EXPECT_EQ(r.files[2].name, "robot");
  EXPECT_EQ(r.files[2].rows_read, 71u);
  EXPECT_EQ(r.files[2].master_rows_before, before);
  EXPECT_EQ(r.files[2].master_rows_after, after);
  EXPECT_EQ(r.master_rows, 1000u);
  EXPECT_EQ(r.rows_out, 1000u - before - after);
  const std::string summary = r.summary();
  EXPECT_NE(summary.find("rows out: 841 of 1000 master rows (159 dropped)"), std::string::npos)
      << summary;
  EXPECT_NE(summary.find("50 master rows before the first sample of 'robot'"), std::string::npos)
      << summary;
  EXPECT_NE(summary.find("109 master rows after the last sample of 'robot'"), std::string::npos)
      << summary;

  const Log& log = result.log;
  ASSERT_EQ(log.samples.size(), r.rows_out);
  EXPECT_EQ(log.columns, (Columns{.joints = true, .specific_force = true, .angular_rate = true}));
  EXPECT_EQ(log.rig.name, "import-test");
  EXPECT_NEAR(log.rig.sample_period_s, 0.001, 1e-12);  // median of the master
  const double h_imu = 0.0005;
  const double w = 2.0 * std::numbers::pi * 3.0;
  const double rate_bound = h_imu * h_imu / 8.0 * w * w * 0.8 + 1e-9;  // linear interp. error
  for (const Sample& s : log.samples) {
    const double t = s.t_s;
    ASSERT_GE(t, robot_t.front());
    ASSERT_LE(t, robot_t.back());
    EXPECT_LT((s.force_sensor_N - force_at(t)).norm(), 1e-9) << t;  // master: no interpolation
    EXPECT_LT((s.specific_force_imu_mps2 - specific_force_at(t)).norm(), 1e-9) << t;
    EXPECT_NEAR(s.angular_rate_imu_radps.z(), rate_z_at(t), rate_bound) << t;
    EXPECT_LT((s.p_base_sensor_m - position_at(t)).norm(), 1e-9) << t;
    EXPECT_LT(s.q_base_sensor.angularDistance(orientation_at(t)), 1e-9) << t;
    EXPECT_NEAR(s.joints_rad[3], 10.0 * t, 1e-9) << t;
  }
}

TEST_F(MergeTest, GapsLongerThanMaxGapAreDroppedAndCounted) {
  // Remove robot rows 20..24 (t = 0.29 … 0.338): a 72 ms hole between 0.278 and 0.35.
  std::string robot = read_text(path("robot.csv"));
  std::size_t start = 0;
  for (int line = 0; line < 21; ++line) start = robot.find('\n', start) + 1;
  std::size_t end = start;
  for (int line = 0; line < 5; ++line) end = robot.find('\n', end) + 1;
  robot.erase(start, end - start);
  write_text(path("robot.csv"), robot);
  write_text(path("map.toml"), mapping("max_gap_s = 0.05\n"));
  const ImportResult result = import_recordings(path("map.toml"));
  std::size_t in_gap = 0;
  for (double t : master_t) in_gap += (t > robot_t[19] && t < robot_t[25]) ? 1 : 0;
  EXPECT_EQ(in_gap, 71u);
  EXPECT_EQ(result.report.files[2].master_rows_in_gap, in_gap);
  EXPECT_EQ(result.report.rows_out, 841u - in_gap);
  EXPECT_NE(
      result.report.summary().find("71 master rows in a gap longer than max_gap_s of 'robot'"),
      std::string::npos)
      << result.report.summary();
  for (const Sample& s : result.log.samples) {
    EXPECT_FALSE(s.t_s > robot_t[19] && s.t_s < robot_t[25]) << s.t_s;
  }
}

TEST_F(MergeTest, NoSurvivingRowIsAnError) {
  std::string m = mapping();
  m.replace(m.find("time_offset_s = -0.002"), 22, "time_offset_s = 5.000");
  write_text(path("map.toml"), m);
  EXPECT_THROW((void)import_recordings(path("map.toml")), std::runtime_error);
}

// ---- units and file dialects ------------------------------------------------------------------

TEST_F(ImportTest, ConvertsUnitsAndReadsDialects) {
  // One file: BOM, preamble, semicolons with decimal commas, quoted header, comments, blanks.
  write_text(
      path("rec.csv"),
      "\xEF\xBB\xBFVendor XYZ logger v2\n"
      "serial 1234\n"
      "\"time\";\"fx\";\"fy\";\"fz\";\"tx\";\"ty\";\"tz\";\"x\";\"y\";\"z\";\"a\";\"b\";\"c\";"
      "\"ax\";\"ay\";\"az\";\"gx\";\"gy\";\"gz\";\"temp\";\"q1\";\"q2\";\"q3\";\"q4\";\"q5\";"
      "\"q6\";\"note\"\n"
      "// comment\n"
      "1000;1;2;3;1000;2000;3000;1000;-500;250;90;0;0;1;0;-1;180;90;-45;300;90;180;-90;45;0;"
      "1,5;hello world\n"
      "\n"
      "2000;0,5;0;0;0;0;0;0;0;0;0;90;0;0;0;1;0;0;0;273,15;0;0;0;0;0;0;x\n");
  write_text(path("map.toml"),
             "format = \"zerog-import\"\nversion = 1\n" + rig_table() +
                 "[files.rec]\npath = \"rec.csv\"\ndelimiter = \"semicolon\"\ndecimal = \",\"\n"
                 "skip_lines = 2\ncomment = \"//\"\n"
                 "time = { column = \"time\", unit = \"ms\" }\n"
                 "force = { columns = [\"fx\", \"fy\", \"fz\"], unit = \"kN\" }\n"
                 "torque = { columns = [\"tx\", \"ty\", \"tz\"], unit = \"Nmm\" }\n"
                 "position = { columns = [\"x\", \"y\", \"z\"], unit = \"mm\" }\n"
                 "orientation = { type = \"kuka_abc\", columns = [\"a\", \"b\", \"c\"], unit = "
                 "\"deg\" }\n"
                 "specific_force = { columns = [\"ax\", \"ay\", \"az\"], unit = \"g\" }\n"
                 "angular_rate = { columns = [\"gx\", \"gy\", \"gz\"], unit = \"deg/s\" }\n"
                 "temperature = { column = \"temp\", unit = \"K\" }\n"
                 "joints = { columns = [\"q1\", \"q2\", \"q3\", \"q4\", \"q5\", \"q6\"], unit = "
                 "\"deg\" }\n");
  const ImportResult result = import_recordings(path("map.toml"));
  ASSERT_EQ(result.log.samples.size(), 2u);
  const Sample& s = result.log.samples[0];
  EXPECT_DOUBLE_EQ(s.t_s, 1.0);
  EXPECT_DOUBLE_EQ(result.log.samples[1].t_s, 2.0);
  EXPECT_LT((s.force_sensor_N - Eigen::Vector3d(1000, 2000, 3000)).norm(), 1e-9);
  EXPECT_LT((s.torque_sensor_Nm - Eigen::Vector3d(1, 2, 3)).norm(), 1e-12);
  EXPECT_LT((s.p_base_sensor_m - Eigen::Vector3d(1, -0.5, 0.25)).norm(), 1e-15);
  const Eigen::Quaterniond rz90(Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitZ()));
  EXPECT_LT(s.q_base_sensor.angularDistance(rz90), 1e-12);
  const Eigen::Quaterniond ry90(Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitY()));
  EXPECT_LT(result.log.samples[1].q_base_sensor.angularDistance(ry90), 1e-12);
  EXPECT_LT((s.specific_force_imu_mps2 - Eigen::Vector3d(kG, 0, -kG)).norm(), 1e-12);
  EXPECT_LT((s.angular_rate_imu_radps -
             Eigen::Vector3d(std::numbers::pi, std::numbers::pi / 2, -std::numbers::pi / 4))
                .norm(),
            1e-12);
  EXPECT_NEAR(s.temperature_C, 300.0 - 273.15, 1e-12);
  EXPECT_NEAR(result.log.samples[1].temperature_C, 0.0, 1e-12);
  EXPECT_NEAR(result.log.samples[1].force_sensor_N.x(), 500.0, 1e-12);
  const std::array<double, 6> joints = {90, 180, -90, 45, 0, 1.5};
  for (int j = 0; j < 6; ++j) EXPECT_NEAR(s.joints_rad[j], joints[j] * kDeg, 1e-15) << j;
  // sample_period_s left out of [rig]: the master's median period.
  EXPECT_DOUBLE_EQ(result.log.rig.sample_period_s, 1.0);
}

TEST_F(ImportTest, TimeUnits) {
  for (const auto& [unit, scale] : std::vector<std::pair<std::string, double>>{
           {"s", 1.0}, {"ms", 1e-3}, {"us", 1e-6}, {"µs", 1e-6}, {"ns", 1e-9}}) {
    write_text(path("r.csv"), "t,f,q\n5,1,1\n7,1,1\n");
    write_text(path("m.toml"),
               "format = \"zerog-import\"\nversion = 1\n" + rig_table() +
                   "[files.r]\npath = \"r.csv\"\ntime = { column = \"t\", unit = \"" + unit +
                   "\" }\nforce = { columns = [\"f\", \"f\", \"f\"], unit = \"N\" }\n"
                   "torque = { columns = [\"f\", \"f\", \"f\"], unit = \"N*m\" }\n"
                   "position = { columns = [\"f\", \"f\", \"f\"], unit = \"m\" }\n"
                   "orientation = { type = \"quaternion\", columns = [\"q\", \"f\", \"f\", \"f\"] "
                   "}\n");
    // (1, 1, 1, 1) is not a unit quaternion: expect that error first, then fix the file.
    expect_input_error([&] { (void)import_recordings(path("m.toml")); }, path("r.csv"), 2, 3,
                       "quaternion has norm 2");
    write_text(path("r.csv"), "t,f,q,z\n5,1,1,0\n7,1,1,0\n");
    std::string map = read_text(path("m.toml"));
    map.replace(map.find("[\"q\", \"f\", \"f\", \"f\"]"), 20, "[\"q\", \"z\", \"z\", \"z\"]");
    write_text(path("m.toml"), map);
    const ImportResult result = import_recordings(path("m.toml"));
    ASSERT_EQ(result.log.samples.size(), 2u) << unit;
    EXPECT_DOUBLE_EQ(result.log.samples[0].t_s, 5.0 * scale) << unit;
    EXPECT_DOUBLE_EQ(result.log.samples[1].t_s, 7.0 * scale) << unit;
  }
}

// ---- errors -----------------------------------------------------------------------------------

class ImportErrorTest : public MergeTest {
 protected:
  void SetUp() override {
    MergeTest::SetUp();
    write_text(path("map.toml"), mapping());
  }
  void expect_error(const fs::path& file, int line, int column, const std::string& part) {
    expect_input_error([&] { (void)import_recordings(path("map.toml")); }, file, line, column,
                       part);
  }
  // Replaces data line `line` (1-based) of `file`.
  void set_line(const std::string& file, int line, const std::string& text) {
    std::string content = read_text(path(file));
    std::size_t start = 0;
    for (int i = 1; i < line; ++i) start = content.find('\n', start) + 1;
    const std::size_t end = content.find('\n', start);
    content.replace(start, end - start, text);
    write_text(path(file), content);
  }
};

TEST_F(ImportErrorTest, MissingColumn) {
  set_line("robot.csv", 1, "t;x;y;Z;qw;qx;qy;qz;a1");
  expect_error(path("robot.csv"), 1, 1,
               "column 'z' not found in the header (named by files.robot.position.columns at "
               "map.toml:");
  expect_error(path("robot.csv"), 1, 1, "did you mean 'Z'?");
}

TEST_F(ImportErrorTest, NonNumericCell) {
  set_line("robot.csv", 4, "0.086;1.2;-0.3;abc;1;0;0;0;0.5");
  expect_error(path("robot.csv"), 4, 16, "not a number: 'abc' in column 'z'");
}

TEST_F(ImportErrorTest, NanCell) {
  set_line("imu.txt", 3, "3  1   nan 0 0 0 0");
  expect_error(path("imu.txt"), 3, 8, "NaN/inf 'nan' in column 'ay'");
}

TEST_F(ImportErrorTest, EmptyCellAndWrongCellCount) {
  set_line("ft.csv", 5, "0.003,1,,3,0,0,0");
  expect_error(path("ft.csv"), 5, 9, "empty cell in column 'fy'");
  set_line("ft.csv", 5, "0.003,1,2,3,0,0");
  expect_error(path("ft.csv"), 5, 16, "row has 6 cells but the header has 7");
}

TEST_F(ImportErrorTest, TimeGoesBackwards) {
  set_line("ft.csv", 6, "0.001,1,2,3,0,0,0");
  expect_error(path("ft.csv"), 6, 1,
               "time goes backwards at line 6: t=0.001 after 0.003 (line 5, column 't', s)");
  set_line("ft.csv", 6, "0.0030000000000000001,1,2,3,0,0,0");
  expect_error(path("ft.csv"), 6, 1, "time stands still at line 6");
}

TEST_F(ImportErrorTest, BadOrientation) {
  set_line("robot.csv", 3, "0.062;1.2;-0.3;1.1;0.9;0.3;0;0;0.5");
  expect_error(path("robot.csv"), 3, 20, "quaternion has norm");
}

TEST_F(ImportErrorTest, MappingErrors) {
  auto with = [&](const std::string& from, const std::string& to) {
    std::string m = mapping();
    const std::size_t at = m.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    m.replace(at, from.size(), to);
    write_text(path("map.toml"), m);
  };
  // Line numbers: 1 format, 2 version, 3 master, 4-12 [rig], 13 [files.ft], 14 path, 15 time,
  // 16 force, 17 torque, 18 [files.imu], ...
  with("force = {", "forces = {");
  expect_error(path("map.toml"), 16, 1,
               "unknown key 'files.ft.forces' (did you mean 'files.ft.force'?)");
  with("unit = \"N\" }", "unit = \"lbf\" }");
  expect_error(path("map.toml"), 16, 48, "unknown unit \"lbf\" for 'files.ft.force.unit'");
  with("path = \"ft.csv\"", "path = \"nope.csv\"");
  expect_error(path("map.toml"), 14, 8, "data file not found");
  with("master = \"ft\"", "master = \"sensor\"");
  expect_error(path("map.toml"), 3, 10, "master 'sensor' is not one of the files");
  with("force = { columns = [\"fx\", \"fy\", \"fz\"], unit = \"N\" }\n", "");
  expect_error(path("map.toml"), 13, 1, "no file maps 'force'");
  with("[files.robot]\n",
       "[files.robot]\nforce = { columns = [\"x\", \"y\", \"z\"], unit = \"N\" }\n");
  expect_error(path("map.toml"), 26, 9, "'force' is mapped twice: here and in files.ft (line 16)");
  with("columns = [\"fx\", \"fy\", \"fz\"]", "columns = [\"fx\", \"fy\"]");
  expect_error(path("map.toml"), 16, 21,
               "'files.ft.force.columns' must be a list of 3 columns (header names, or "
               "1-based column numbers)");
  with(rig_table(), "");
  expect_error(path("map.toml"), 1, 1, "no rig");
  with("version = 1", "version = 7");
  expect_error(path("map.toml"), 2, 11, "mapping version 7 is not supported");
  with("delimiter = \"semicolon\"", "delimiter = \"pipe\"");
  expect_error(path("map.toml"), 27, 13, "'files.robot.delimiter' must be \"comma\"");
}

TEST_F(ImportErrorTest, RigFileOverridesAndRefusesToOverwriteInputs) {
  Rig rig;
  rig.name = "from-file";
  write_rig(rig, path("other.rig.toml"));
  const ImportResult result = import_recordings(path("map.toml"), path("other.rig.toml"));
  EXPECT_EQ(result.log.rig.name, "from-file");
  EXPECT_NE(result.report.rig_source.find("replacing the mapping's rig"), std::string::npos);

  const std::string before = read_text(path("robot.csv"));
  EXPECT_THROW((void)import_to_log(path("map.toml"), path("robot.csv")), std::runtime_error);
  EXPECT_THROW((void)import_to_log(path("map.toml"), path("other.csv"), path("other.rig.toml")),
               std::runtime_error);  // other.rig.toml is the sidecar of other.csv and an input
  EXPECT_EQ(read_text(path("robot.csv")), before);
  EXPECT_FALSE(fs::exists(path("other.csv")));
  EXPECT_EQ(read_text(path("other.rig.toml")).find("name = \"from-file\"") != std::string::npos,
            true);
}

// ---- the worked example of proto/import_mapping.md -------------------------------------------

TEST_F(ImportTest, WorkedExampleImports) {
  const fs::path example = fs::path(ZEROG_SOURCE_DIR) / "calib/import_example";
  const ImportReport report = import_to_log(example / "mapping.toml", path("run.csv"));
  EXPECT_EQ(report.master_rows, 200u);
  EXPECT_EQ(report.rows_out, 181u);
  ASSERT_EQ(report.files.size(), 3u);
  EXPECT_EQ(report.files[2].master_rows_before, 4u);
  EXPECT_EQ(report.files[2].master_rows_after, 15u);
  const Log log = read_log(path("run.csv"));
  EXPECT_EQ(
      log.columns,
      (Columns{.joints = true, .specific_force = true, .angular_rate = true, .temperature = true}));
  EXPECT_EQ(log.rig.name, "kr210-import-example");
  for (const Sample& s : log.samples) {
    EXPECT_NEAR(s.specific_force_imu_mps2.z(), -kG, 1e-9);
    EXPECT_NEAR(s.angular_rate_imu_radps.z(), -20.0 * kDeg, 1e-9);
    EXPECT_NEAR(s.p_base_sensor_m.z(), 1.5 - 0.06, 1e-9);  // flange pose + rig flange_sensor
    EXPECT_NEAR(s.force_sensor_N.z(), 100.0 * kG, 2.5);
    // Sensor z axis points down (C = 180°), so gravity is along +z_S.
    EXPECT_NEAR((s.q_base_sensor.conjugate() * Eigen::Vector3d(0, 0, -1)).z(), 1.0, 1e-9);
  }
}

// ---- partial recordings: static tables, no header, partial IMU, no position, base frame -------

// 1-based line and character column of the first `needle` in `text` (ASCII text).
std::pair<int, int> line_column_of(const std::string& text, const std::string& needle) {
  const std::size_t at = text.find(needle);
  EXPECT_NE(at, std::string::npos) << needle;
  const std::size_t line_start =
      text.rfind('\n', at) == std::string::npos ? 0 : text.rfind('\n', at) + 1;
  const int line = 1 + static_cast<int>(std::count(text.begin(), text.begin() + at, '\n'));
  return {line, static_cast<int>(at - line_start) + 1};
}

// Poses held still: orientation only (a rotation matrix), wrench, accelerometer in g.
struct StaticRow {
  Eigen::Matrix3d R_base_sensor;
  Eigen::Vector3d force_sensor_N, torque_sensor_Nm, specific_force_imu_mps2;
};

std::vector<StaticRow> static_rows(int n) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<StaticRow> rows;
  for (int i = 0; i < n; ++i) {
    StaticRow r;
    r.R_base_sensor = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized().matrix();
    const Eigen::Vector3d g_S = r.R_base_sensor.transpose() * Eigen::Vector3d(0, 0, -kG);
    r.force_sensor_N = 50.0 * g_S + Eigen::Vector3d(1, -2, 3);
    r.torque_sensor_Nm = Eigen::Vector3d(0.01, 0.02, 0.1).cross(r.force_sensor_N);
    r.specific_force_imu_mps2 = -g_S;  // at rest the accelerometer reads −g
    rows.push_back(r);
  }
  return rows;
}

// A headerless comma-space table: F (N), M (N*m), r11..r33, accelerometer (g).
std::string static_table_text(const std::vector<StaticRow>& rows) {
  std::string text = "# held poses, no header\n";
  for (const StaticRow& r : rows) {
    std::string line;
    auto put = [&](double v) { line += (line.empty() ? "" : ", ") + fmt("%.17g", v); };
    for (int k = 0; k < 3; ++k) put(r.force_sensor_N[k]);
    for (int k = 0; k < 3; ++k) put(r.torque_sensor_Nm[k]);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) put(r.R_base_sensor(a, b));
    for (int k = 0; k < 3; ++k) put(r.specific_force_imu_mps2[k] / kG);
    text += line + "\n";
  }
  return text;
}

std::string static_mapping(const std::string& force_columns = "[1, 2, 3]") {
  return "format = \"zerog-import\"\nversion = 1\n" + rig_table() +
         "[files.table]\npath = \"table.csv\"\nheader = false\ndelimiter = \", \"\n"
         "force = { columns = " +
         force_columns +
         ", unit = \"N\" }\n"
         "torque = { columns = [4, 5, 6], unit = \"N*m\" }\n"
         "orientation = { type = \"matrix\", columns = [7, 8, 9, 10, 11, 12, 13, 14, 15] }\n"
         "specific_force = { columns = [16, 17, 18], unit = \"g\" }\n";
}

TEST_F(ImportTest, StaticTableWithoutHeaderOrTime) {
  const auto rows = static_rows(15);
  write_text(path("table.csv"), static_table_text(rows));
  write_text(path("map.toml"), static_mapping());
  const ImportResult result = import_recordings(path("map.toml"));
  const Log& log = result.log;
  EXPECT_EQ(log.columns, (Columns{.specific_force = true, .position = false, .static_rows = true}));
  ASSERT_EQ(log.samples.size(), rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const Sample& s = log.samples[i];
    EXPECT_EQ(s.t_s, static_cast<double>(i));  // the row index stands in for time
    EXPECT_LT((s.force_sensor_N - rows[i].force_sensor_N).norm(), 1e-9) << i;
    EXPECT_LT((s.torque_sensor_Nm - rows[i].torque_sensor_Nm).norm(), 1e-9) << i;
    EXPECT_LT((s.specific_force_imu_mps2 - rows[i].specific_force_imu_mps2).norm(), 1e-9) << i;
    EXPECT_LT((s.q_base_sensor.toRotationMatrix() - rows[i].R_base_sensor).norm(), 1e-9) << i;
    EXPECT_EQ(s.p_base_sensor_m, Eigen::Vector3d::Zero());
  }
  EXPECT_TRUE(result.report.static_rows);
  EXPECT_NE(result.report.summary().find("15 rows without time"), std::string::npos)
      << result.report.summary();

  // Written as format version 2 (no t_s, no position, accelerometer alone) and read back.
  write_log(log, path("static.csv"));
  const std::string text = read_text(path("static.csv"));
  EXPECT_EQ(text.rfind("# zerog-log 2\nqw,qx,qy,qz,imu_fx_mps2,imu_fy_mps2,imu_fz_mps2,Fx_N,", 0),
            0u)
      << text.substr(0, 120);
  const Log back = read_log(path("static.csv"));
  EXPECT_EQ(back.columns, log.columns);
  ASSERT_EQ(back.samples.size(), log.samples.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    EXPECT_EQ(back.samples[i].t_s, static_cast<double>(i));
    EXPECT_LT((back.samples[i].force_sensor_N - rows[i].force_sensor_N).norm(), 1e-5);
  }
}

TEST_F(ImportTest, StaticTableWithHeaderAndBlanksAroundSeparators) {
  // Header names with blanks after the separator, columns named and numbered in one mapping.
  write_text(path("t.csv"),
             "Fx ; Fy ; Fz ; Mx ; My ; Mz ; A ; B ; C\n"
             "1 ; 2 ; 3 ; 0.1 ; 0.2 ; 0.3 ; 90 ; 0 ; 0\n"
             "4 ; 5 ; 6 ; 0.4 ; 0.5 ; 0.6 ; 0 ; 90 ; 0\n");
  write_text(path("m.toml"),
             "format = \"zerog-import\"\nversion = 1\n" + rig_table() +
                 "[files.t]\npath = \"t.csv\"\ndelimiter = \" ; \"\n"
                 "force = { columns = [\"Fx\", \"Fy\", 3], unit = \"N\" }\n"
                 "torque = { columns = [4, \"My\", \"Mz\"], unit = \"N*m\" }\n"
                 "orientation = { type = \"kuka_abc\", columns = [\"A\", \"B\", \"C\"], unit = "
                 "\"deg\" }\n");
  const ImportResult result = import_recordings(path("m.toml"));
  ASSERT_EQ(result.log.samples.size(), 2u);
  EXPECT_TRUE(result.log.columns.static_rows);
  EXPECT_LT((result.log.samples[1].force_sensor_N - Eigen::Vector3d(4, 5, 6)).norm(), 1e-12);
  EXPECT_LT((result.log.samples[1].torque_sensor_Nm - Eigen::Vector3d(0.4, 0.5, 0.6)).norm(),
            1e-12);
}

TEST_F(MergeTest, PartialImuAndNoPosition) {
  // Accelerometer only.
  std::string m = mapping();
  m.erase(m.find("angular_rate = {"),
          m.find('\n', m.find("angular_rate = {")) + 1 - m.find("angular_rate = {"));
  write_text(path("map.toml"), m);
  Log log = import_recordings(path("map.toml")).log;
  EXPECT_TRUE(log.columns.specific_force);
  EXPECT_FALSE(log.columns.angular_rate);
  for (const Sample& s : log.samples) {
    EXPECT_LT((s.specific_force_imu_mps2 - specific_force_at(s.t_s)).norm(), 1e-9);
    EXPECT_EQ(s.angular_rate_imu_radps, Eigen::Vector3d::Zero());
  }
  // Gyroscope only, and no position (orientation alone).
  m = mapping();
  m.erase(m.find("specific_force = {"),
          m.find('\n', m.find("specific_force = {")) + 1 - m.find("specific_force = {"));
  m.erase(m.find("position = {"),
          m.find('\n', m.find("position = {")) + 1 - m.find("position = {"));
  write_text(path("map.toml"), m);
  log = import_recordings(path("map.toml")).log;
  EXPECT_FALSE(log.columns.specific_force);
  EXPECT_TRUE(log.columns.angular_rate);
  EXPECT_FALSE(log.columns.position);
  EXPECT_FALSE(log.columns.static_rows);
  for (const Sample& s : log.samples) {
    EXPECT_EQ(s.p_base_sensor_m, Eigen::Vector3d::Zero());
    EXPECT_NEAR(s.angular_rate_imu_radps.z(), rate_z_at(s.t_s), 1e-6);
    EXPECT_LT(s.q_base_sensor.angularDistance(orientation_at(s.t_s)), 1e-3);
  }
  write_log(log, path("gyro_only.csv"));
  EXPECT_EQ(read_text(path("gyro_only.csv")).rfind("# zerog-log 2\nt_s,q1_rad,", 0), 0u);
  const Log back = read_log(path("gyro_only.csv"));
  EXPECT_EQ(back.columns, log.columns);
  EXPECT_EQ(back.samples.size(), log.samples.size());
}

TEST_F(ImportTest, BaseFrameAndFixedFrameVectors) {
  // The sensor S and the IMU I are turned against each other and against the base B; the files
  // give the wrench and the IMU with base-frame axes, and a second wrench in a fixed frame D.
  Rig rig;
  rig.name = "frames";
  rig.sensor_imu.q =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  write_rig(rig, path("frames.rig.toml"));
  const Eigen::Quaterniond q_S_D(Eigen::AngleAxisd(-1.1, Eigen::Vector3d(0, 1, 1).normalized()));
  const Eigen::Matrix3d R_SI = rig.sensor_imu.q.toRotationMatrix();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::string text = "t,fx,fy,fz,mx,my,mz,ax,ay,az,wx,wy,wz,qw,qx,qy,qz,dx,dy,dz\n";
  struct Want {
    Eigen::Vector3d F_S, M_S, f_I, w_I;
  };
  std::vector<Want> want;
  for (int i = 0; i < 20; ++i) {
    const Eigen::Quaterniond q_BS = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
    const Eigen::Matrix3d R_BS = q_BS.toRotationMatrix();
    Want w{Eigen::Vector3d(u(rng), u(rng), u(rng)) * 100, Eigen::Vector3d(u(rng), u(rng), u(rng)),
           Eigen::Vector3d(u(rng), u(rng), u(rng)) * 10, Eigen::Vector3d(u(rng), u(rng), u(rng))};
    const Eigen::Vector3d F_B = R_BS * w.F_S, M_B = R_BS * w.M_S;
    const Eigen::Vector3d f_B = R_BS * R_SI * w.f_I, w_B = R_BS * R_SI * w.w_I;
    const Eigen::Vector3d F_D = q_S_D.conjugate() * w.F_S;
    text += fmt("%d", i);
    for (const Eigen::Vector3d* v : {&F_B, &M_B, &f_B, &w_B})
      text += fmt(",%.17g,%.17g,%.17g", v->x(), v->y(), v->z());
    text += fmt(",%.17g,%.17g,%.17g,%.17g", q_BS.w(), q_BS.x(), q_BS.y(), q_BS.z());
    text += fmt(",%.17g,%.17g,%.17g\n", F_D.x(), F_D.y(), F_D.z());
    want.push_back(w);
  }
  write_text(path("b.csv"), text);
  const std::string head =
      "format = \"zerog-import\"\nversion = 1\nrig_file = \"frames.rig.toml\"\n"
      "[files.b]\npath = \"b.csv\"\ntime = { column = \"t\", unit = \"s\" }\n"
      "orientation = { type = \"quaternion\", columns = [\"qw\", \"qx\", \"qy\", \"qz\"] }\n"
      "torque = { columns = [\"mx\", \"my\", \"mz\"], unit = \"N*m\", frame = \"base\" }\n"
      "specific_force = { columns = [\"ax\", \"ay\", \"az\"], unit = \"m/s^2\", frame = \"base\" "
      "}\n"
      "angular_rate = { columns = [\"wx\", \"wy\", \"wz\"], unit = \"rad/s\", frame = \"base\" }\n";
  write_text(
      path("m.toml"),
      head + "force = { columns = [\"fx\", \"fy\", \"fz\"], unit = \"N\", frame = \"base\" }\n");
  Log log = import_recordings(path("m.toml")).log;
  ASSERT_EQ(log.samples.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    const Sample& s = log.samples[i];
    EXPECT_LT((s.force_sensor_N - want[i].F_S).norm(), 1e-9) << i;
    EXPECT_LT((s.torque_sensor_Nm - want[i].M_S).norm(), 1e-9) << i;
    EXPECT_LT((s.specific_force_imu_mps2 - want[i].f_I).norm(), 1e-9) << i;
    EXPECT_LT((s.angular_rate_imu_radps - want[i].w_I).norm(), 1e-9) << i;
  }
  // A fixed frame D, given by its axes in S.
  write_text(path("m.toml"),
             head + fmt("force = { columns = [\"dx\", \"dy\", \"dz\"], unit = \"N\", frame = { "
                        "q_wxyz = [%.17g, %.17g, %.17g, %.17g] } }\n",
                        q_S_D.w(), q_S_D.x(), q_S_D.y(), q_S_D.z()));
  log = import_recordings(path("m.toml")).log;
  for (std::size_t i = 0; i < want.size(); ++i)
    EXPECT_LT((log.samples[i].force_sensor_N - want[i].F_S).norm(), 1e-9) << i;
}

// A wrench recorded in a fixed frame D that is turned and shifted against S (issue 13: a fixed
// transform with a lever arm): F_S = R_SD F_D, M_S = R_SD M_D + p_SD × F_S. The truth is built
// the other way round, from a known wrench in S.
TEST_F(ImportTest, FixedFrameWithLeverArmMovesTheTorqueToTheSensorOrigin) {
  const Eigen::Quaterniond q_S_D(Eigen::AngleAxisd(0.9, Eigen::Vector3d(1, -2, 0.5).normalized()));
  const Eigen::Matrix3d R_SD = q_S_D.toRotationMatrix();
  const Eigen::Vector3d p_SD(0.02, -0.15, 0.3);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::string text = "fx,fy,fz,mx,my,mz\n";
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> want;  // F_S, M_S
  for (int i = 0; i < 12; ++i) {
    const Eigen::Vector3d F_S = 100.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    const Eigen::Vector3d M_S = 10.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    // The same wrench about D's origin, in D's axes.
    const Eigen::Vector3d F_D = R_SD.transpose() * F_S;
    const Eigen::Vector3d M_D = R_SD.transpose() * (M_S - p_SD.cross(F_S));
    text += fmt("%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", F_D.x(), F_D.y(), F_D.z(), M_D.x(),
                M_D.y(), M_D.z());
    want.emplace_back(F_S, M_S);
  }
  write_text(path("w.csv"), text);
  const std::string frame =
      fmt("frame = { p_m = [%.17g, %.17g, %.17g], q_wxyz = [%.17g, %.17g, "
          "%.17g, %.17g] }",
          p_SD.x(), p_SD.y(), p_SD.z(), q_S_D.w(), q_S_D.x(), q_S_D.y(), q_S_D.z());
  const std::string head = "format = \"zerog-import\"\nversion = 1\n" + rig_table() +
                           "[files.w]\npath = \"w.csv\"\n"
                           "orientation = { type = \"kuka_abc\", columns = [1, 2, 3], unit = "
                           "\"deg\" }\n";
  write_text(path("m.toml"), head + "force = { columns = [\"fx\", \"fy\", \"fz\"], unit = \"N\", " +
                                 frame +
                                 " }\ntorque = { columns = [\"mx\", \"my\", \"mz\"], unit = "
                                 "\"N*m\", " +
                                 frame + " }\n");
  const Log log = import_recordings(path("m.toml")).log;
  ASSERT_EQ(log.samples.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    EXPECT_LT((log.samples[i].force_sensor_N - want[i].first).norm(), 1e-9) << i;
    EXPECT_LT((log.samples[i].torque_sensor_Nm - want[i].second).norm(), 1e-9) << i;
  }
  // The torque's lever arm needs the force; an IMU group takes no lever arm.
  const std::string torque_only =
      "[files.w]\npath = \"w.csv\"\n"
      "torque = { columns = [4, 5, 6], unit = \"N*m\", " +
      frame + " }\n";
  const std::string no_force = "format = \"zerog-import\"\nversion = 1\n" + rig_table() +
                               torque_only +
                               "orientation = { type = \"kuka_abc\", columns = [1, 2, 3], unit "
                               "= \"deg\" }\n";
  write_text(path("m.toml"), no_force);
  const auto [line, column] = line_column_of(no_force, "[" + fmt("%.17g", p_SD.x()));
  expect_input_error([&] { (void)import_recordings(path("m.toml")); }, path("m.toml"), line, column,
                     "'files.w.torque.frame.p_m' moves the torque from the recording frame's "
                     "origin to the sensor origin, M_S = R M + p × F_S, which needs the force: map "
                     "'force'");
  const std::string imu_lever = head +
                                "force = { columns = [1, 2, 3], unit = \"N\" }\n"
                                "torque = { columns = [4, 5, 6], unit = \"N*m\" }\n"
                                "specific_force = { columns = [1, 2, 3], unit = \"g\", " +
                                frame + " }\n";
  write_text(path("m.toml"), imu_lever);
  const auto [imu_line, imu_column] = line_column_of(imu_lever, "[" + fmt("%.17g", p_SD.x()));
  expect_input_error([&] { (void)import_recordings(path("m.toml")); }, path("m.toml"), imu_line,
                     imu_column, "the rig's [sensor_imu] p_m");
}

// A recording that logged the angular acceleration (issue 13): `angular_accel` maps it like the
// other IMU groups (columns, unit, frame) into imu_dw*_radps2, which host/ident then uses as
// logged; the rig says where it came from. Log format 2 holds ω̇ only beside the angular rate,
// and kinematics = "robot" takes ω̇ from the robot: both refusals name the key and the fix.
TEST_F(ImportTest, LoggedAngularAccelerationComesThroughOrIsRefused) {
  Rig rig;
  rig.name = "logged-dw";
  rig.sensor_imu.q =
      Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(-1, 2, 1).normalized()));
  write_rig(rig, path("dw.rig.toml"));
  const Eigen::Matrix3d R_SI = rig.sensor_imu.q.toRotationMatrix();
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::string text = "t,fx,fy,fz,mx,my,mz,qw,qx,qy,qz,wx,wy,wz,dwx,dwy,dwz\n";
  std::vector<Eigen::Vector3d> want_w, want_dw;
  for (int i = 0; i < 20; ++i) {
    const Eigen::Quaterniond q_BS = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
    const Eigen::Vector3d w_I(u(rng), u(rng), u(rng)),
        dw_I = 5.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    // ω̇ recorded with base-frame axes, in deg/s².
    const Eigen::Vector3d dw_B = q_BS.toRotationMatrix() * R_SI * dw_I / kDeg;
    text += fmt("%.17g,1,2,3,0.1,0.2,0.3,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g", 0.01 * i,
                q_BS.w(), q_BS.x(), q_BS.y(), q_BS.z(), w_I.x(), w_I.y(), w_I.z());
    text += fmt(",%.17g,%.17g,%.17g\n", dw_B.x(), dw_B.y(), dw_B.z());
    want_w.push_back(w_I);
    want_dw.push_back(dw_I);
  }
  write_text(path("dw.csv"), text);
  const std::string head =
      "format = \"zerog-import\"\nversion = 1\nrig_file = \"dw.rig.toml\"\n"
      "%s[files.rec]\npath = \"dw.csv\"\ntime = { column = \"t\", unit = \"s\" }\n"
      "force = { columns = [\"fx\", \"fy\", \"fz\"], unit = \"N\" }\n"
      "torque = { columns = [\"mx\", \"my\", \"mz\"], unit = \"N*m\" }\n"
      "orientation = { type = \"quaternion\", columns = [\"qw\", \"qx\", \"qy\", \"qz\"] }\n";
  const std::string gyro =
      "angular_rate = { columns = [\"wx\", \"wy\", \"wz\"], unit = \"rad/s\" }\n";
  const std::string accel =
      "angular_accel = { columns = [\"dwx\", \"dwy\", \"dwz\"], unit = \"deg/s^2\", frame = "
      "\"base\" }\n";
  const auto mapping = [&](const std::string& kinematics, const std::string& keys) {
    return fmt(head.c_str(), kinematics.c_str()) + keys;
  };
  write_text(path("m.toml"), mapping("", gyro + accel));
  const ImportResult imported = import_recordings(path("m.toml"));
  const Log& log = imported.log;
  ASSERT_EQ(log.samples.size(), want_dw.size());
  EXPECT_TRUE(log.columns.angular_accel);
  EXPECT_EQ(log.rig.kinematics.angular_accel, KinematicsOrigin::logged);
  EXPECT_NE(
      imported.report.summary().find("angular acceleration: logged in files.rec.angular_accel"),
      std::string::npos)
      << imported.report.summary();
  for (std::size_t i = 0; i < want_dw.size(); ++i) {
    EXPECT_LT((log.samples[i].angular_accel_imu_radps2 - want_dw[i]).norm(), 1e-9) << i;
    EXPECT_LT((log.samples[i].angular_rate_imu_radps - want_w[i]).norm(), 1e-12) << i;
  }
  // Through the log format: version 2 with imu_dw*, and the rig says the ω̇ was logged.
  write_log(log, path("dw_out.csv"));
  EXPECT_EQ(read_text(path("dw_out.csv")).rfind("# zerog-log 2\n", 0), 0u);
  EXPECT_NE(read_text(path("dw_out.rig.toml")).find("angular_accel = \"logged\""),
            std::string::npos);
  const Log back = read_log(path("dw_out.csv"));
  EXPECT_TRUE(back.columns.angular_accel);
  EXPECT_EQ(back.rig.kinematics.angular_accel, KinematicsOrigin::logged);
  EXPECT_LT((back.samples[7].angular_accel_imu_radps2 - want_dw[7]).norm(), 1e-6);
  // "auto" keeps the logged ω̇ (no Savitzky–Golay of the gyro in its place).
  write_text(path("m.toml"), mapping("kinematics = \"auto\"\n", gyro + accel));
  const ImportResult automatic = import_recordings(path("m.toml"));
  EXPECT_EQ(automatic.log.rig.kinematics.angular_accel, KinematicsOrigin::logged);
  EXPECT_EQ(automatic.log.rig.kinematics.accel_sg_half_width, 0);
  EXPECT_LT((automatic.log.samples[3].angular_accel_imu_radps2 - want_dw[3]).norm(), 1e-9);

  // Refused: ω̇ without the angular rate (log format 2 holds imu_dw* only beside imu_w*).
  std::string map = mapping("", accel);
  write_text(path("m.toml"), map);
  auto [line, column] = line_column_of(map, "{ columns = [\"dwx\"");
  expect_input_error([&] { (void)import_recordings(path("m.toml")); }, path("m.toml"), line, column,
                     "'files.rec.angular_accel' needs the angular rate beside it (the log holds "
                     "ω̇, imu_dw*_radps2, only with imu_w*_radps; proto/log_format.md): map the "
                     "gyro as 'angular_rate'");
  // Refused: kinematics = "robot" takes ω̇ from the robot.
  map = mapping("kinematics = \"robot\"\n", gyro + accel);
  write_text(path("m.toml"), map);
  std::tie(line, column) = line_column_of(map, "{ columns = [\"dwx\"");
  expect_input_error([&] { (void)import_recordings(path("m.toml")); }, path("m.toml"), line, column,
                     "kinematics = \"robot\" takes ω̇ from the robot: use kinematics = \"auto\"");
  // Refused: kinematics = "fused" (issue 28) needs the joints with the rig's robot; its
  // crossover is for it only.
  map = mapping("kinematics = \"fused\"\n", gyro);
  write_text(path("m.toml"), map);
  std::tie(line, column) = line_column_of(map, "kinematics = \"fused\"");
  column += static_cast<int>(std::string("kinematics = ").size());
  expect_input_error([&] { (void)import_recordings(path("m.toml")); }, path("m.toml"), line, column,
                     "'kinematics = \"fused\"': the joints are not mapped: map 'joints' (and "
                     "give the rig its robot) to fuse them with the IMU");
  map = mapping("kinematics_crossover_hz = 0.5\n", gyro);
  write_text(path("m.toml"), map);
  std::tie(line, column) = line_column_of(map, "0.5");
  expect_input_error([&] { (void)import_recordings(path("m.toml")); }, path("m.toml"), line, column,
                     "'kinematics_crossover_hz' is for kinematics = \"fused\" only");
  // An unknown unit names the accepted ones.
  map = mapping(
      "", gyro + "angular_accel = { columns = [\"dwx\", \"dwy\", \"dwz\"], unit = \"rad/s\" }\n");
  write_text(path("m.toml"), map);
  std::tie(line, column) = line_column_of(map, "\"dwz\"], unit = \"rad/s\"");
  column += static_cast<int>(std::string("\"dwz\"], unit = ").size());
  expect_input_error([&] { (void)import_recordings(path("m.toml")); }, path("m.toml"), line, column,
                     "unknown unit \"rad/s\" for 'files.rec.angular_accel.unit' (use one of "
                     "\"rad/s^2\", \"rad/s2\", \"deg/s^2\", \"deg/s2\")");
}

TEST_F(ImportTest, RefusalsNameFileLineColumnAndTheFix) {
  write_text(path("table.csv"), static_table_text(static_rows(4)));
  auto expect_mapping_error = [&](const std::string& map, const std::string& at,
                                  const std::string& part) {
    write_text(path("map.toml"), map);
    const auto [line, column] = line_column_of(map, at);
    expect_input_error([&] { (void)import_recordings(path("map.toml")); }, path("map.toml"), line,
                       column, part);
  };
  // A header name in a file without header.
  expect_mapping_error(static_mapping("[1, 2, \"Fz\"]"), "\"Fz\"",
                       "'files.table.force.columns' names column 'Fz', but files.table has "
                       "header = false: give the 1-based column number instead");
  // Column numbers count from 1.
  expect_mapping_error(static_mapping("[0, 2, 3]"), "0, 2, 3",
                       "column number 0 is out of range (columns are counted from 1)");
  // An unknown frame.
  std::string map = static_mapping();
  map.replace(map.find("unit = \"N\" }"), 12, "unit = \"N\", frame = \"tool\" }");
  expect_mapping_error(map, "\"tool\"", "must be \"sensor\" (the default), \"base\" or");
  // time_offset_s without a time column.
  map = static_mapping() + "time_offset_s = 0.5\n";
  expect_mapping_error(map, "0.5", "'files.table.time_offset_s' needs a time column");
  // A second file with time beside one without: they cannot be merged (all without time would
  // join row by row).
  map = static_mapping();
  map.insert(map.find("[rig]"), "master = \"more\"\n");
  map +=
      "[files.more]\npath = \"table.csv\"\nheader = false\n"
      "time = { column = 1, unit = \"s\" }\ntemperature = { column = 2, unit = \"C\" }\n";
  expect_mapping_error(map, "[files.table]",
                       "files.table has no 'time' but files.more has: a file without time holds "
                       "static samples");
  // A column number beyond the row: reported at the first data row (line 2, after the comment),
  // just past its end.
  write_text(path("map.toml"), static_mapping("[1, 2, 30]"));
  const std::string text = read_text(path("table.csv"));
  const std::string first_row =
      text.substr(text.find('\n') + 1, text.find('\n', text.find('\n') + 1) - text.find('\n') - 1);
  expect_input_error([&] { (void)import_recordings(path("map.toml")); }, path("table.csv"), 2,
                     static_cast<int>(first_row.size()) + 1,
                     "column 30 (named by files.table.force.columns at map.toml:");
  // A short row in a headerless file.
  write_text(path("map.toml"), static_mapping());
  write_text(path("table.csv"), text + "1, 2, 3\n");
  expect_input_error([&] { (void)import_recordings(path("map.toml")); }, path("table.csv"), 6, 8,
                     "row has 3 cells but the first row has 18");
}
}  // namespace
}  // namespace zerog::io
