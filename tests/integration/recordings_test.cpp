// Real recordings as they come (issue 13's acceptance), through the real `zerog` program:
//
// (a) CAN: a simulated run's wrench (`zerog sim`, `cable` hidden in the truth) put on the bus by
//     the emulated ATI NETCANOEM board (host/emu AtiBoard: the codec's encoders, gauges through
//     the exact inverse of the sensor's formula) and written as candump text — its default
//     output without timestamps and its -ta form — then `zerog decode-can` (with --assume-rate
//     for the former) → `zerog import` merged with the robot's pose/joints/IMU file →
//     `zerog fit` → `zerog diagnose`: `cable` must rank first.
// (b) joints only: the wrench and the robot's joints (no IMU, no pose) in two files, the joints
//     stamped on a clock 12 ms late (the analogue of imu_time_offset: a delay between joints and
//     wrench) → `zerog import` with kinematics = "robot" → fit → diagnose: imu_time_offset must
//     rank first, and adding it must lower the held-out error.
// (c) the static table of calib/static_table: diagnose cross-validates it (leave-one-out over
//     its 15 poses) and proposes nothing for the clean table, and `zerog fit` fits it.
// (d) an accelerometer-only IMU beside the pose (kinematics = "auto"), and a wrench logged in the
//     base frame: import → fit → compare → diagnose.
//
// Two seeds each; short runs (12 or 16 random path points, 80–115 s of simulated time).
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Core>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "zerog/emu/ati_board.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/io/candump.hpp"
#include "zerog/proto/netcanoem.hpp"

namespace {

namespace fs = std::filesystem;
namespace nc = zerog::proto::netcanoem;
using ::testing::HasSubstr;

const fs::path kSource = ZEROG_SOURCE_DIR;

struct Result {
  int status = -1;
  std::string out, err;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

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

class Recordings : public ::testing::Test {
 protected:
  static fs::path dir() {
    return fs::temp_directory_path() / ("zerog_recordings_test_" + std::to_string(getpid()));
  }
  void SetUp() override {
    fs::remove_all(dir());
    fs::create_directories(dir());
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir());
  }
  static Result run(const std::string& args) {
    const fs::path out = dir() / "stdout.txt", err = dir() / "stderr.txt";
    const std::string cmd =
        std::string(ZEROG_EXE) + " " + args + " >" + out.string() + " 2>" + err.string();
    const int rc = std::system(cmd.c_str());
    return {WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, slurp(out), slurp(err)};
  }
  static std::string path(const std::string& name) { return (dir() / name).string(); }

  // `zerog sim` with `effects` hidden, `points` random path points (about 7 s each), period
  // `period_s`; returns the log.
  static zerog::formats::Log simulate(unsigned seed, const std::string& effects, double period_s,
                                      int points) {
    const Result r =
        run("sim --kind random --points " + std::to_string(points) + " --design-seed " +
            std::to_string(seed) + " --seed " + std::to_string(seed) + " --effects " + effects +
            " --period " + cell(period_s) + " -q --out " + path("sim.csv"));
    EXPECT_EQ(r.status, 0) << r.err;
    return zerog::formats::read_log(dir() / "sim.csv");
  }
  // The simulator's rig with the robot described (robot_file in place of the name), as a user
  // edits a rig for kinematics = "robot".
  static void write_cell_rig() {
    std::string rig = slurp(dir() / "sim.rig.toml");
    const std::string name_line = "robot = \"KR 210 R2700\"";
    const auto at = rig.find(name_line);
    ASSERT_NE(at, std::string::npos);
    rig.replace(
        at, name_line.size(),
        "robot_file = \"" + (kSource / "calib/robots/kr210_r2700.robot.toml").string() + "\"");
    write_text(dir() / "cell.rig.toml", rig);
  }
  // fit (default model) then diagnose --json; returns the diagnosis.
  static nlohmann::json fit_and_diagnose(const std::string& log) {
    const Result f = run("fit " + log + " -q --out " + path("model.json"));
    EXPECT_EQ(f.status, 0) << f.err;
    const Result d =
        run("diagnose " + log + " --model " + path("model.json") + " --no-discover --json -q");
    EXPECT_EQ(d.status, 0) << d.err;
    return d.status == 0 ? nlohmann::json::parse(d.out) : nlohmann::json();
  }
};

const char* kForceTorqueKeys =
    "force = { columns = [\"Fx_N\", \"Fy_N\", \"Fz_N\"], unit = \"N\" }\n"
    "torque = { columns = [\"Mx_Nm\", \"My_Nm\", \"Mz_Nm\"], unit = \"N*m\" }\n";

// ---- (a) candump → decode-can → import → fit → diagnose ---------------------------------

// The frames of a recorded session: the start-up read-out (as zerog-rt's sensor asks for it),
// then one sample request and its two answers per row of `log`, the second answer at the row's
// time (on candump's µs clock, `start_ns` + t), the request 300 µs and the first answer 100 µs
// before. The board's counts are the finest whose range holds the run's wrench with 30 % margin.
struct CanSession {
  std::vector<zerog::io::CandumpRecord> records;
  std::array<double, 6> resolution{};  ///< wrench of one count on every gauge (AtiBoard)
};
CanSession can_session(const zerog::formats::Log& log, std::int64_t start_ns) {
  std::array<double, 6> peak{};
  for (const auto& s : log.samples)
    for (int k = 0; k < 3; ++k) {
      peak[k] = std::max(peak[k], std::abs(s.force_sensor_N[k]));
      peak[3 + k] = std::max(peak[3 + k], std::abs(s.torque_sensor_Nm[k]));
    }
  zerog::emu::AtiBoardConfig config;
  bool fits = false;
  for (std::uint32_t counts : {1'000'000u, 500'000u, 200'000u, 100'000u, 50'000u, 20'000u, 10'000u,
                               5'000u, 2'000u, 1'000u}) {
    config.counts_per_force = counts;
    config.counts_per_torque = counts / 10;
    const zerog::emu::AtiBoard probe(config);
    const auto range = probe.full_scale_si();
    fits = true;
    for (int k = 0; k < 6; ++k) fits = fits && range[k] > 1.3 * peak[k];
    if (fits) break;
  }
  EXPECT_TRUE(fits) << "no counts give the range of this run's wrench";
  zerog::emu::AtiBoard board(config);

  CanSession session;
  session.resolution = board.count_resolution_si();
  std::vector<zerog::io::CandumpRecord>& records = session.records;
  auto add = [&](const zerog::proto::CanFrame& frame, std::int64_t t_ns) {
    zerog::io::CandumpRecord r;
    r.timestamp_ns = t_ns / 1000 * 1000;  // candump's stamps are whole microseconds
    r.interface = "can0";
    r.frame = frame;
    records.push_back(r);
  };
  zerog::emu::AtiBoard::Response answer;
  auto ask = [&](const std::optional<zerog::proto::CanFrame>& request, std::int64_t& t_ns) {
    add(*request, t_ns);
    const std::size_t n = board.respond(*request, answer);
    EXPECT_GT(n, 0u);
    for (std::size_t i = 0; i < n; ++i) add(answer[i], t_ns += 100'000);
    t_ns += 1'000'000;
  };
  std::int64_t t_ns = start_ns - 100'000'000;  // the read-out, 0.1 s before the first sample
  ask(nc::request_set_active_calibration(config.base_id, 0), t_ns);
  for (std::uint8_t row = 0; row < 6; ++row) ask(nc::request_matrix_row(config.base_id, row), t_ns);
  ask(nc::request_counts(config.base_id), t_ns);
  ask(nc::request_units(config.base_id), t_ns);
  for (const auto& s : log.samples) {
    board.set_wrench({s.force_sensor_N.x(), s.force_sensor_N.y(), s.force_sensor_N.z(),
                      s.torque_sensor_Nm.x(), s.torque_sensor_Nm.y(), s.torque_sensor_Nm.z()});
    const std::int64_t t_sample = start_ns + std::llround(s.t_s * 1e9);
    add(*nc::request_sample(config.base_id), t_sample - 300'000);
    const std::size_t n = board.respond(*nc::request_sample(config.base_id), answer);
    EXPECT_EQ(n, 2u);
    add(answer[0], t_sample - 100'000);
    add(answer[1], t_sample);
  }
  return session;
}

// The robot's logger: time, pose of S, joints and the IMU at every row of the simulated run.
void write_robot_file(const zerog::formats::Log& log, const fs::path& file) {
  std::string text = "t,qw,qx,qy,qz,px,py,pz,A1,A2,A3,A4,A5,A6,fx,fy,fz,wx,wy,wz\n";
  for (const auto& s : log.samples) {
    text += cell(s.t_s) + "," + cell(s.q_base_sensor.w()) + "," + cell(s.q_base_sensor.x()) + "," +
            cell(s.q_base_sensor.y()) + "," + cell(s.q_base_sensor.z());
    for (int k = 0; k < 3; ++k) text += "," + cell(s.p_base_sensor_m[k]);
    for (int j = 0; j < 6; ++j) text += "," + cell(s.joints_rad[j]);
    for (int k = 0; k < 3; ++k) text += "," + cell(s.specific_force_imu_mps2[k]);
    for (int k = 0; k < 3; ++k) text += "," + cell(s.angular_rate_imu_radps[k]);
    text += "\n";
  }
  write_text(file, text);
}

TEST_F(Recordings, CandumpDefaultAndTaThroughDecodeImportFitDiagnoseFindTheCable) {
  const double period_s = 0.004;  // the sensor polled at 250 Hz
  const std::int64_t start_ns = 1'700'000'000'000'000'000;
  for (unsigned seed : {21u, 22u}) {
    const zerog::formats::Log truth = simulate(seed, "cable", period_s, 12);
    ASSERT_GT(truth.samples.size(), 15000u);
    ASSERT_EQ(truth.samples.front().t_s, 0.0);
    write_robot_file(truth, dir() / "robot.csv");
    const CanSession session = can_session(truth, start_ns);
    // Rounding a gauge moves the wrench by at most half a count's worth on each axis.
    const double quantum_N =
        0.5 *
        Eigen::Vector3d(session.resolution[0], session.resolution[1], session.resolution[2]).norm();
    for (const zerog::io::CandumpClock clock :
         {zerog::io::CandumpClock::none, zerog::io::CandumpClock::absolute}) {
      const bool stamped = clock == zerog::io::CandumpClock::absolute;
      SCOPED_TRACE("seed " + std::to_string(seed) + (stamped ? ", candump -ta" : ", candump"));
      std::string text;
      for (const auto& r : session.records)
        text += zerog::io::format_candump_columns(r, clock) + "\n";
      write_text(dir() / "bus.log", text);
      // Default output: no time at all; decode-can needs the rate, sample k gets k / rate.
      const Result decoded =
          run("decode-can " + path("bus.log") + " --out " + path("ft.csv") +
              (stamped ? std::string() : " --assume-rate " + cell(1.0 / period_s)));
      ASSERT_EQ(decoded.status, 0) << decoded.err;
      EXPECT_THAT(decoded.out, HasSubstr("candump default output"));
      EXPECT_THAT(decoded.out, HasSubstr("calibration: read from the log"));
      EXPECT_THAT(decoded.out,
                  HasSubstr(std::to_string(truth.samples.size()) + " usable samples written"));
      write_text(dir() / "mapping.toml",
                 std::string("format = \"zerog-import\"\nversion = 1\nmaster = \"ft\"\n"
                             "rig_file = \"sim.rig.toml\"\n[files.ft]\npath = \"ft.csv\"\n"
                             "time = { column = \"t_s\", unit = \"s\" }\n") +
                     (stamped ? "time_offset_s = -1700000000\n" : "") + kForceTorqueKeys +
                     "[files.robot]\npath = \"robot.csv\"\ntime = { column = \"t\", unit = \"s\" "
                     "}\norientation = { type = \"quaternion\", columns = [\"qw\", \"qx\", "
                     "\"qy\", \"qz\"] }\nposition = { columns = [\"px\", \"py\", \"pz\"], unit = "
                     "\"m\" }\njoints = { columns = [\"A1\", \"A2\", \"A3\", \"A4\", \"A5\", "
                     "\"A6\"], unit = \"rad\" }\nspecific_force = { columns = [\"fx\", \"fy\", "
                     "\"fz\"], unit = \"m/s2\" }\nangular_rate = { columns = [\"wx\", \"wy\", "
                     "\"wz\"], unit = \"rad/s\" }\n");
      const Result imported =
          run("import --mapping " + path("mapping.toml") + " --out " + path("run.csv"));
      ASSERT_EQ(imported.status, 0) << imported.err;
      // Every sample survives (the robot file covers the bus log's span; the -ta clock's
      // 1.7e9 s leave the first row a rounding away from the robot file's first sample).
      const zerog::formats::Log log = zerog::formats::read_log(dir() / "run.csv");
      ASSERT_GE(log.samples.size() + 1, truth.samples.size()) << imported.out;

      // The wrench on the bus is the simulated one to within the gauge quantisation, each row
      // at its sample's time.
      double force_error = 0.0, time_error = 0.0;
      for (const auto& s : log.samples) {
        const auto k = static_cast<std::size_t>(std::llround(s.t_s / period_s));
        ASSERT_LT(k, truth.samples.size());
        time_error = std::max(time_error, std::abs(s.t_s - truth.samples[k].t_s));
        force_error =
            std::max(force_error, (s.force_sensor_N - truth.samples[k].force_sensor_N).norm());
      }
      EXPECT_LT(time_error, 1e-6);
      EXPECT_LT(force_error, 1.01 * quantum_N + 1e-4) << "one count " << 2 * quantum_N << " N";

      const nlohmann::json d = fit_and_diagnose(path("run.csv"));
      ASSERT_FALSE(d.is_null());
      std::printf(
          "seed %u, %s: candidates %s %.3f, %s %.3f; held-out force RMS %.3f -> %.3f N\n", seed,
          stamped ? "-ta" : "default", d["candidates"][0]["effect"].dump().c_str(),
          d["candidates"][0]["gain"].get<double>(), d["candidates"][1]["effect"].dump().c_str(),
          d["candidates"][1]["gain"].get<double>(), d["baseline"]["force_rms"].get<double>(),
          d["candidates"][0]["heldout"]["force_rms"].get<double>());
      EXPECT_EQ(d["verdict"]["kind"], "effect");
      EXPECT_EQ(d["verdict"]["effect"], "cable");
      EXPECT_EQ(d["candidates"][0]["effect"], "cable");
    }
  }
}

// ---- (b) joints only, a delay between joints and wrench -------------------------------------

TEST_F(Recordings, JointsOnlyWithAJointDelayDiagnosesTheTimeOffset) {
  const double period_s = 0.012;  // an RSI link's 12 ms
  const double delay_s = 0.012;   // the joints are stamped this much late
  for (unsigned seed : {31u, 32u}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const zerog::formats::Log truth = simulate(seed, "rotational_inertia", period_s, 16);
    write_cell_rig();
    std::string wrench = "t,Fx_N,Fy_N,Fz_N,Mx_Nm,My_Nm,Mz_Nm\n", joints = "t,A1,A2,A3,A4,A5,A6\n";
    for (const auto& s : truth.samples) {
      wrench += cell(s.t_s);
      for (int k = 0; k < 3; ++k) wrench += "," + cell(s.force_sensor_N[k]);
      for (int k = 0; k < 3; ++k) wrench += "," + cell(s.torque_sensor_Nm[k]);
      wrench += "\n";
      joints += cell(s.t_s + delay_s);
      for (int j = 0; j < 6; ++j) joints += "," + cell(s.joints_rad[j]);
      joints += "\n";
    }
    write_text(dir() / "wrench.csv", wrench);
    write_text(dir() / "joints.csv", joints);
    // Joints only: the pose and ω, ω̇, specific force all from the robot.
    write_text(dir() / "mapping.toml",
               std::string("format = \"zerog-import\"\nversion = 1\nmaster = \"wrench\"\n"
                           "rig_file = \"cell.rig.toml\"\nkinematics = \"robot\"\n"
                           "[files.wrench]\npath = \"wrench.csv\"\n"
                           "time = { column = \"t\", unit = \"s\" }\n") +
                   kForceTorqueKeys +
                   "[files.joints]\npath = \"joints.csv\"\ntime = { column = \"t\", unit = \"s\" "
                   "}\njoints = { columns = [\"A1\", \"A2\", \"A3\", \"A4\", \"A5\", \"A6\"], "
                   "unit = \"rad\" }\n");
    const Result imported =
        run("import --mapping " + path("mapping.toml") + " --out " + path("run.csv"));
    ASSERT_EQ(imported.status, 0) << imported.err;
    EXPECT_THAT(imported.out, HasSubstr("the sensor's pose from them through KR 210 R2700"));
    EXPECT_THAT(imported.out, HasSubstr("angular rate and specific force from the joints"));

    const nlohmann::json d = fit_and_diagnose(path("run.csv"));
    ASSERT_FALSE(d.is_null());
    EXPECT_EQ(d["kinematics_sources"]["mode"], "robot");
    const nlohmann::json& best = d["candidates"][0];
    const double tau = best["params"].value("tau", 0.0);
    std::printf(
        "joints only, seed %u: candidates %s %.3f (tau %.4f s), %s %.3f; held-out force RMS "
        "%.3f -> %.3f N, torque %.4f -> %.4f N*m\n",
        seed, best["effect"].dump().c_str(), best["gain"].get<double>(), tau,
        d["candidates"][1]["effect"].dump().c_str(), d["candidates"][1]["gain"].get<double>(),
        d["baseline"]["force_rms"].get<double>(), best["heldout"]["force_rms"].get<double>(),
        d["baseline"]["torque_rms"].get<double>(), best["heldout"]["torque_rms"].get<double>());
    EXPECT_EQ(d["verdict"]["effect"], "imu_time_offset");
    EXPECT_EQ(best["effect"], "imu_time_offset");
    // The derived IMU lags the wrench by the joints' delay.
    EXPECT_NEAR(tau, delay_s, 0.25 * delay_s);
    // Adding it lowers the held-out error.
    EXPECT_LT(best["heldout"]["force_rms"].get<double>(),
              0.8 * d["baseline"]["force_rms"].get<double>());
  }
}

// ---- (c) a static table ---------------------------------------------------------------------

TEST_F(Recordings, StaticTableIsDiagnosedByCrossValidationAndFitWorks) {
  const fs::path table = kSource / "calib/static_table";
  const Result imported =
      run("import --mapping " + (table / "mapping.toml").string() + " --out " + path("static.csv"));
  ASSERT_EQ(imported.status, 0) << imported.err;
  // The default model of a table is bias and gravity (a table feeds no inertia).
  const Result d = run("diagnose " + path("static.csv") + " --json -q");
  ASSERT_EQ(d.status, 0) << d.err;
  const auto j = nlohmann::json::parse(d.out);
  EXPECT_THAT(j["split"]["text"].get<std::string>(), HasSubstr("leave-one-out"));
  EXPECT_EQ(j["split"]["blocks"], 15);
  EXPECT_EQ(j["verdict"]["kind"], "nothing_left") << j["verdict"]["text"];
  EXPECT_TRUE(j["outliers"].empty());
  EXPECT_EQ(j["model"], nlohmann::json({"bias", "gravity"}));
  // What it names works.
  const Result f = run("fit " + path("static.csv") + " --effects bias,gravity --json -q");
  ASSERT_EQ(f.status, 0) << f.err;
  EXPECT_TRUE(nlohmann::json::parse(f.out)["extra"]["fit"]["usable"].get<bool>());
}

// ---- (d) accelerometer only; a wrench in the base frame ---------------------------------------

// Two of issue 13's fixtures through import → fit → compare → diagnose, from one short run:
// an accelerometer-only IMU (in g) beside the pose (ω, ω̇ from the orientation with
// kinematics = "auto"), and a wrench the recording software rotated into the base frame
// (`frame = "base"`), which must fit as the simulator's own log does.
TEST_F(Recordings, AccelerometerOnlyAndBaseFrameWrenchFitCompareDiagnose) {
  const unsigned seed = 41;
  const zerog::formats::Log truth = simulate(seed, "rotational_inertia", 0.012, 8);
  const nlohmann::json truth_model = nlohmann::json::parse(slurp(dir() / "sim.truth.json"));
  const double mass_kg = truth_model["parameters"]["gravity"]["mass"]["value"].get<double>();
  std::string acc = "t,Fx_N,Fy_N,Fz_N,Mx_Nm,My_Nm,Mz_Nm,qw,qx,qy,qz,px,py,pz,ax_g,ay_g,az_g\n";
  std::string base = "t,FxB,FyB,FzB,MxB,MyB,MzB,qw,qx,qy,qz,px,py,pz,fx,fy,fz,wx,wy,wz\n";
  for (const auto& s : truth.samples) {
    const Eigen::Matrix3d R_BS = s.q_base_sensor.toRotationMatrix();
    std::string pose = "," + cell(s.q_base_sensor.w()) + "," + cell(s.q_base_sensor.x()) + "," +
                       cell(s.q_base_sensor.y()) + "," + cell(s.q_base_sensor.z());
    for (int k = 0; k < 3; ++k) pose += "," + cell(s.p_base_sensor_m[k]);
    acc += cell(s.t_s);
    for (int k = 0; k < 3; ++k) acc += "," + cell(s.force_sensor_N[k]);
    for (int k = 0; k < 3; ++k) acc += "," + cell(s.torque_sensor_Nm[k]);
    acc += pose;
    for (int k = 0; k < 3; ++k) acc += "," + cell(s.specific_force_imu_mps2[k] / 9.80665);
    acc += "\n";
    const Eigen::Vector3d F_B = R_BS * s.force_sensor_N, M_B = R_BS * s.torque_sensor_Nm;
    base += cell(s.t_s);
    for (int k = 0; k < 3; ++k) base += "," + cell(F_B[k]);
    for (int k = 0; k < 3; ++k) base += "," + cell(M_B[k]);
    base += pose;
    for (int k = 0; k < 3; ++k) base += "," + cell(s.specific_force_imu_mps2[k]);
    for (int k = 0; k < 3; ++k) base += "," + cell(s.angular_rate_imu_radps[k]);
    base += "\n";
  }
  write_text(dir() / "acc.csv", acc);
  write_text(dir() / "base.csv", base);
  const std::string pose_keys =
      "orientation = { type = \"quaternion\", columns = [\"qw\", \"qx\", \"qy\", \"qz\"] }\n"
      "position = { columns = [\"px\", \"py\", \"pz\"], unit = \"m\" }\n";
  const std::string head = "format = \"zerog-import\"\nversion = 1\nrig_file = \"sim.rig.toml\"\n";
  const std::string effects = " --effects bias,gravity,linear_inertia,rotational_inertia";
  // fit, compare, diagnose: the fitted model and the diagnosis.
  const auto chain = [&](const std::string& log) {
    Result r = run("fit " + log + effects + " -q --json --out " + path("model.json"));
    EXPECT_EQ(r.status, 0) << r.err;
    const nlohmann::json fit = r.status == 0 ? nlohmann::json::parse(r.out) : nlohmann::json();
    r = run("compare " + log + " --model " + path("model.json") + " --json -q");
    EXPECT_EQ(r.status, 0) << r.err;
    const nlohmann::json compared = r.status == 0 ? nlohmann::json::parse(r.out) : nlohmann::json();
    r = run("diagnose " + log + " --model " + path("model.json") + " --no-discover --json -q");
    EXPECT_EQ(r.status, 0) << r.err;
    const nlohmann::json d = r.status == 0 ? nlohmann::json::parse(r.out) : nlohmann::json();
    return std::array<nlohmann::json, 3>{fit, compared, d};
  };

  // Accelerometer only: ω, ω̇ from the pose, the specific force from the accelerometer.
  write_text(dir() / "acc.toml",
             head +
                 "kinematics = \"auto\"\n[files.acc]\npath = \"acc.csv\"\n"
                 "time = { column = \"t\", unit = \"s\" }\n" +
                 kForceTorqueKeys + pose_keys +
                 "specific_force = { columns = [\"ax_g\", \"ay_g\", \"az_g\"], unit = \"g\" }\n");
  Result imported = run("import --mapping " + path("acc.toml") + " --out " + path("acc_run.csv"));
  ASSERT_EQ(imported.status, 0) << imported.err;
  EXPECT_THAT(imported.out, HasSubstr("angular rate from pose"));
  const auto [acc_fit, acc_compare, acc_diagnosis] = chain(path("acc_run.csv"));
  ASSERT_FALSE(acc_fit.is_null() || acc_compare.is_null() || acc_diagnosis.is_null());
  const nlohmann::json& sources = acc_fit["extra"]["fit"]["kinematics_sources"];
  EXPECT_EQ(sources["effects"]["linear_inertia"]["specific_force"], "imu");
  EXPECT_EQ(sources["effects"]["rotational_inertia"]["omega"], "pose");
  EXPECT_EQ(sources["effects"]["rotational_inertia"]["omega_dot"], "pose");
  EXPECT_EQ(acc_diagnosis["kinematics_sources"]["effects"]["linear_inertia"]["omega"], "pose");
  const double acc_mass = acc_fit["parameters"]["gravity"]["mass"]["value"].get<double>();
  std::printf(
      "accelerometer only (ω, ω̇ from the pose): mass %.4f kg (truth %.4f), moving force RMS "
      "%.3f N, diagnose baseline held-out force RMS %.3f N\n",
      acc_mass, mass_kg, acc_compare["segments"]["moving"]["force_rms"].get<double>(),
      acc_diagnosis["baseline"]["force_rms"].get<double>());
  EXPECT_NEAR(acc_mass, mass_kg, 0.005 * mass_kg);

  // The wrench in the base frame (full IMU): the same fit as on the simulator's own log.
  write_text(dir() / "base.toml",
             head +
                 "[files.b]\npath = \"base.csv\"\ntime = { column = \"t\", unit = \"s\" }\n"
                 "force = { columns = [\"FxB\", \"FyB\", \"FzB\"], unit = \"N\", frame = "
                 "\"base\" }\n"
                 "torque = { columns = [\"MxB\", \"MyB\", \"MzB\"], unit = \"N*m\", frame = "
                 "\"base\" }\n" +
                 pose_keys +
                 "specific_force = { columns = [\"fx\", \"fy\", \"fz\"], unit = \"m/s2\" }\n"
                 "angular_rate = { columns = [\"wx\", \"wy\", \"wz\"], unit = \"rad/s\" }\n");
  imported = run("import --mapping " + path("base.toml") + " --out " + path("base_run.csv"));
  ASSERT_EQ(imported.status, 0) << imported.err;
  const auto [base_fit, base_compare, base_diagnosis] = chain(path("base_run.csv"));
  ASSERT_FALSE(base_fit.is_null() || base_compare.is_null() || base_diagnosis.is_null());
  const auto [sim_fit, sim_compare, sim_diagnosis] = chain(path("sim.csv"));
  ASSERT_FALSE(sim_fit.is_null());
  for (const char* param : {"mass", "cx", "cy", "cz"}) {
    if (!sim_fit["parameters"]["gravity"].contains(param)) continue;
    const double a = base_fit["parameters"]["gravity"][param]["value"].get<double>();
    const double b = sim_fit["parameters"]["gravity"][param]["value"].get<double>();
    EXPECT_NEAR(a, b, 1e-6 * std::max(1.0, std::abs(b))) << param;
  }
  std::printf(
      "wrench in the base frame: mass %.6f kg, all-rows force RMS %.4f N (the simulator's own "
      "log: %.6f kg, %.4f N)\n",
      base_fit["parameters"]["gravity"]["mass"]["value"].get<double>(),
      base_compare["segments"]["all"]["force_rms"].get<double>(),
      sim_fit["parameters"]["gravity"]["mass"]["value"].get<double>(),
      sim_compare["segments"]["all"]["force_rms"].get<double>());
  EXPECT_NEAR(base_compare["segments"]["all"]["force_rms"].get<double>(),
              sim_compare["segments"]["all"]["force_rms"].get<double>(), 1e-4);
  EXPECT_EQ(base_diagnosis["verdict"]["kind"], sim_diagnosis["verdict"]["kind"]);
}

}  // namespace
