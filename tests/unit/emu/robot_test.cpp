// The robot controller emulator (host/emu robot.hpp, rig_emulator.hpp): the TCP Jacobian against
// finite differences of the kinematics, RKorr and AKorr moving the robot by exactly what they
// say, the servo against the analytic second-order response, joint ranges and the singular
// wrist; then the whole robot loop over real UDP against an in-test responder, with faults.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "zerog/emu/rig_emulator.hpp"
#include "zerog/emu/robot.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/io/model_file.hpp"
#include "zerog/model/rotation.hpp"

namespace zerog::emu {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Eigen::Vector3d rotation_vector(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.angle() * aa.axis();
}

void settle(RobotEmulator& robot, double seconds) {
  const int steps = static_cast<int>(seconds * robot.config().physics_rate_hz);
  for (int i = 0; i < steps; ++i) robot.step();
}

TEST(RobotEmulator, JacobianMatchesFiniteDifferencesOfForwardKinematics) {
  const RobotEmulator robot;
  const std::vector<sim::JointVector> poses = {
      default_start_joints(),
      {0.3, -1.2, 1.9, 0.7, -0.9, 2.5},
      {-1.0, -0.6, 0.4, -2.0, 1.4, -0.3},
  };
  const double h = 1e-6;
  for (const sim::JointVector& q : poses) {
    const Eigen::Matrix<double, 6, 6> J = robot.jacobian(q);
    for (int i = 0; i < 6; ++i) {
      sim::JointVector plus = q, minus = q;
      plus[i] += h;
      minus[i] -= h;
      const TcpPose a = robot.tcp_pose(plus), b = robot.tcp_pose(minus);
      const Eigen::Vector3d dp = (a.p_base_tcp_m - b.p_base_tcp_m) / (2 * h);
      const Eigen::Vector3d dw = rotation_vector(a.R_base_tcp * b.R_base_tcp.transpose()) / (2 * h);
      EXPECT_LT((J.block<3, 1>(0, i) - dp).norm(), 1e-7) << "linear, joint " << i + 1;
      EXPECT_LT((J.block<3, 1>(3, i) - dw).norm(), 1e-7) << "angular, joint " << i + 1;
    }
  }
  // The TCP offset matters: the sensor origin moves differently from the flange centre.
  RobotConfig flange;
  flange.p_flange_tcp_m.setZero();
  EXPECT_GT((RobotEmulator(flange).jacobian(poses[1]) - robot.jacobian(poses[1])).norm(), 0.01);
}

TEST(RobotEmulator, RkorrMovesTheSteadyStateTcpByExactlyTheCorrection) {
  RobotEmulator robot;
  const TcpPose before = robot.tcp_pose(robot.actual().q_rad);
  // 1 mm and 0.01 deg, on every axis at once.
  const proto::rsi::Correction c{1.0, -1.0, 1.0, 0.01, -0.01, 0.01};
  const CorrectionOutcome o = robot.apply_rkorr(c);
  EXPECT_FALSE(o.clamped);
  EXPECT_FALSE(o.near_singular);
  settle(robot, 2.0);
  const TcpPose after = robot.tcp_pose(robot.actual().q_rad);
  const Eigen::Vector3d dp_expected(1e-3, -1e-3, 1e-3);
  EXPECT_LT((after.p_base_tcp_m - before.p_base_tcp_m - dp_expected).norm(),
            1e-6 * dp_expected.norm());
  const Eigen::Matrix3d R_corr =
      model::rotation_from_kuka_abc(0.01 * kDeg, -0.01 * kDeg, 0.01 * kDeg);
  // Premultiplied, in the base frame: R_new = R_corr R_old.
  const Eigen::Vector3d residual =
      rotation_vector(after.R_base_tcp * (R_corr * before.R_base_tcp).transpose());
  EXPECT_LT(residual.norm(), 1e-6 * rotation_vector(R_corr).norm());
  // Not post-multiplied (a tool-frame correction would differ by far more than that).
  const Eigen::Vector3d tool_frame =
      rotation_vector(after.R_base_tcp * (before.R_base_tcp * R_corr).transpose());
  EXPECT_GT(tool_frame.norm(), 100 * residual.norm());
  EXPECT_EQ(robot.counters().rkorr_applied, 1u);

  // Relative: a second one adds to the first, measured on the command, not on the lagging robot.
  robot.apply_rkorr({1.0, 0, 0, 0, 0, 0});
  robot.apply_rkorr({1.0, 0, 0, 0, 0, 0});
  const TcpPose commanded = robot.tcp_pose(robot.commanded());
  EXPECT_NEAR(commanded.p_base_tcp_m.x() - after.p_base_tcp_m.x(), 2e-3, 1e-12);
  EXPECT_NEAR(commanded.p_base_tcp_m.y(), after.p_base_tcp_m.y(), 1e-12);
}

TEST(RobotEmulator, ServoFollowsTheAnalyticCriticallyDampedStepResponse) {
  RobotConfig config;
  config.servo_bandwidth_hz = 8.0;
  RobotEmulator robot(config);
  const double u = 0.5 * kDeg;
  const sim::JointVector q0 = robot.actual().q_rad;
  robot.apply_akorr({0.0, 0.0, 0.5, 0.0, 0.0, 0.0});
  const double w = 2 * std::numbers::pi * 8.0;
  const double h = 1.0 / config.physics_rate_hz;
  double worst = 0.0;
  for (int k = 1; k <= 1000; ++k) {
    robot.step();
    const double t = k * h;
    const double e = std::exp(-w * t);
    const double q = robot.actual().q_rad[2] - q0[2];
    EXPECT_NEAR(q, u * (1.0 - (1.0 + w * t) * e), 1e-12 * u) << t;
    EXPECT_NEAR(robot.actual().qd_radps[2], u * w * w * t * e, 1e-10 * u * w) << t;
    EXPECT_NEAR(robot.actual().qdd_radps2[2], u * w * w * (1.0 - w * t) * e, 1e-9 * u * w * w) << t;
    worst = std::max(worst, q);
    EXPECT_EQ(robot.actual().q_rad[0], q0[0]);  // the other joints stay
  }
  EXPECT_LE(worst, u * (1.0 + 1e-12));  // critically damped: no overshoot
  EXPECT_GT(robot.actual().q_rad[2] - q0[2], 0.999 * u);
}

TEST(RobotEmulator, ServoFollowsTheAnalyticResponseToTheInterpolatorsRamp) {
  // One AKorr spread over an interpolation time T: the set point is the ramp v t for t < T, then
  // holds. The critically damped servo's response to the ramp from rest is
  // q_r(t) = v (t − 2/ω + (t + 2/ω) e^{−ωt}), q̇_r = v (1 − (1 + ωt) e^{−ωt}), q̈_r = v ω² t e^{−ωt},
  // and to the whole set point q_r(t) − q_r(t − T). Before the fix the set point went up in
  // stairs of v h: q̈ at a step's end was off by about −ω² v h / 2 (0.63 v per second at 8 Hz and
  // 2 kHz), a drag on every moving joint that the F/T sensor and the IMU's accelerometer felt but
  // the gyroscope's derivative did not (HIL spin: +1.7 N·m of contact torque at 0.6 rad/s).
  RobotConfig config;
  config.interpolation_s = 0.012;
  RobotEmulator robot(config);
  const double T = config.interpolation_s;
  const double u = 0.5 * kDeg, v = u / T;
  const sim::JointVector q0 = robot.actual().q_rad;
  robot.apply_akorr({0.0, 0.0, 0.0, 0.0, 0.0, 0.5});
  const double w = 2 * std::numbers::pi * config.servo_bandwidth_hz;
  const double h = 1.0 / config.physics_rate_hz;
  struct Motion {
    double q, qd, qdd;
  };
  auto ramp = [&](double t) -> Motion {
    if (t <= 0.0) return {0.0, 0.0, 0.0};
    const double e = std::exp(-w * t);
    return {v * (t - 2.0 / w + (t + 2.0 / w) * e), v * (1.0 - (1.0 + w * t) * e),
            v * w * w * t * e};
  };
  double worst_qdd = 0.0;
  for (int k = 1; k <= 1000; ++k) {
    robot.step();
    const double t = k * h;
    const Motion a = ramp(t), b = ramp(t - T);
    const sim::JointState& js = robot.actual();
    EXPECT_NEAR(js.q_rad[5] - q0[5], a.q - b.q, 1e-12 * u) << t;
    EXPECT_NEAR(js.qd_radps[5], a.qd - b.qd, 1e-10 * v) << t;
    EXPECT_NEAR(js.qdd_radps2[5], a.qdd - b.qdd, 1e-9 * v * w) << t;
    worst_qdd = std::max(worst_qdd, std::abs(js.qdd_radps2[5] - (a.qdd - b.qdd)));
  }
  EXPECT_LT(worst_qdd, 1e-3 * w * w * v * h);                 // far below the stairs' error
  EXPECT_NEAR(robot.actual().q_rad[5] - q0[5], u, 1e-8 * u);  // settled after 0.5 s
}

TEST(RobotEmulator, AtASteadySpeedTheAccelerationIsZeroAndTheDerivativeOfTheSpeed) {
  // A train of equal corrections, one per cycle, as zerog-rt sends while the part floats at a
  // constant angular speed: A6 turns at 0.6 rad/s. q̈ must be what q̇ does: zero on average, and
  // at every step the central difference of q̇.
  RobotConfig config;
  config.interpolation_s = 0.012;
  RobotEmulator robot(config);
  const int steps_per_cycle = static_cast<int>(std::lround(0.012 * config.physics_rate_hz));
  const double h = 1.0 / config.physics_rate_hz;
  const double speed = 0.6, per_cycle_deg = speed * 0.012 / kDeg;
  std::vector<double> qd, qdd;
  for (int cycle = 0; cycle < 200; ++cycle) {
    robot.apply_akorr({0.0, 0.0, 0.0, 0.0, 0.0, per_cycle_deg});
    for (int k = 0; k < steps_per_cycle; ++k) {
      robot.step();
      if (cycle >= 100) {
        qd.push_back(robot.actual().qd_radps[5]);
        qdd.push_back(robot.actual().qdd_radps2[5]);
      }
    }
  }
  double mean = 0.0, worst = 0.0;
  for (std::size_t k = 1; k + 1 < qd.size(); ++k) {
    mean += qdd[k];
    worst = std::max(worst, std::abs(qdd[k] - (qd[k + 1] - qd[k - 1]) / (2 * h)));
  }
  mean /= static_cast<double>(qd.size() - 2);
  EXPECT_NEAR(qd.back(), speed, 1e-9);
  const double w = 2 * std::numbers::pi * config.servo_bandwidth_hz;
  const double stairs_bias = w * w * speed * h / 2.0;  // 0.38 rad/s² for these figures
  EXPECT_LT(std::abs(mean), 1e-6 * stairs_bias) << "mean q̈ at a constant speed";
  EXPECT_LT(worst, 1e-6 * stairs_bias) << "q̈ against the central difference of q̇";
}

TEST(RobotEmulator, TheInterpolatorSpreadsACorrectionOverOneCycleAndSmoothsTheServo) {
  // A train of equal corrections, one per 12 ms cycle (a steady speed): stepping the set point
  // jerks the servo by ω² Δq each cycle; the interpolator makes it a ramp.
  auto peak_accel = [](double interpolation_s) {
    RobotConfig config;
    config.interpolation_s = interpolation_s;
    RobotEmulator robot(config);
    const int steps_per_cycle = static_cast<int>(0.012 * config.physics_rate_hz);
    double peak = 0.0;
    for (int cycle = 0; cycle < 100; ++cycle) {
      robot.apply_akorr({0.0, 0.0, 0.1, 0.0, 0.0, 0.0});  // 0.1° per 12 ms ≈ 8.3 °/s
      for (int k = 0; k < steps_per_cycle; ++k) {
        robot.step();
        if (cycle > 50) peak = std::max(peak, std::abs(robot.actual().qdd_radps2[2]));
      }
    }
    // The command is followed either way.
    EXPECT_NEAR(robot.commanded()[2] - default_start_joints()[2], 10.0 * kDeg, 1e-12);
    return peak;
  };
  const double stepped = peak_accel(0.0);
  const double ramped = peak_accel(0.012);
  const double w = 2 * std::numbers::pi * 8.0;
  EXPECT_GT(stepped, 0.5 * w * w * 0.1 * kDeg);  // of the order of ω² Δq
  EXPECT_LT(ramped, 0.05 * stepped);
}

TEST(RobotEmulator, AkorrAddsToTheCommandAndRangesClamp) {
  RobotEmulator robot;
  const sim::JointVector q0 = robot.commanded();
  CorrectionOutcome o = robot.apply_akorr({1.0, -2.0, 3.0, -4.0, 5.0, -6.0});
  EXPECT_FALSE(o.clamped);
  for (int i = 0; i < 6; ++i)
    EXPECT_NEAR(robot.commanded()[i] - q0[i], (i % 2 ? -1.0 : 1.0) * (i + 1) * kDeg, 1e-15);
  settle(robot, 2.0);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(robot.actual().q_rad[i], robot.commanded()[i], 1e-12);

  // A5 starts at 50 deg now: +100 deg would reach 150, beyond +125.
  o = robot.apply_akorr({0, 0, 0, 0, 100.0, 0});
  EXPECT_TRUE(o.clamped);
  EXPECT_NEAR(robot.commanded()[4], 125.0 * kDeg, 1e-15);
  EXPECT_EQ(robot.counters().clamped_commands, 1u);
  EXPECT_EQ(robot.counters().akorr_applied, 2u);
}

TEST(RobotEmulator, NearTheWristSingularityTheStepStaysBoundedAndIsCounted) {
  RobotConfig config;
  config.start_joints_rad = {0.0, -90.0 * kDeg, 90.0 * kDeg, 0.0, 1e-4, 0.0};
  RobotEmulator robot(config);
  const sim::JointVector q0 = robot.commanded();
  // A rotation about the base x axis, which the aligned wrist cannot make directly.
  const CorrectionOutcome o = robot.apply_rkorr({0, 0, 0, 0, 0, 0.01});
  EXPECT_TRUE(o.near_singular);
  EXPECT_LT(o.sigma_min, config.singular_threshold);
  double largest = 0.0;
  for (int i = 0; i < 6; ++i) largest = std::max(largest, std::abs(robot.commanded()[i] - q0[i]));
  EXPECT_LT(largest, 0.2);  // an undamped inverse would turn A4/A6 by far more
  EXPECT_EQ(robot.counters().near_singular_cycles, 1u);
}

TEST(RobotEmulator, MessageReportsTheActualTcpAndJointsInRsiUnits) {
  RobotEmulator robot;
  robot.apply_akorr({2.0, 1.0, -1.0, 3.0, 2.0, -5.0});
  settle(robot, 0.05);  // mid-way: actual differs from commanded
  const proto::rsi::RobotMessage m = robot.message(1'000'024, 3);
  EXPECT_EQ(m.ipoc, 1'000'024u);
  EXPECT_TRUE(m.has_delay);
  EXPECT_EQ(m.delay, 3u);
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(m.joints_deg[i], robot.actual().q_rad[i] / kDeg, 1e-12);
  EXPECT_GT(std::abs(m.joints_deg[0] - robot.commanded()[0] / kDeg), 0.1);
  const TcpPose p = robot.tcp_pose(robot.actual().q_rad);
  EXPECT_NEAR(m.actual_pose.x_mm, p.p_base_tcp_m.x() * 1e3, 1e-9);
  EXPECT_NEAR(m.actual_pose.z_mm, p.p_base_tcp_m.z() * 1e3, 1e-9);
  const Eigen::Matrix3d R = model::rotation_from_kuka_abc(
      m.actual_pose.a_deg * kDeg, m.actual_pose.b_deg * kDeg, m.actual_pose.c_deg * kDeg);
  EXPECT_LT((R - p.R_base_tcp).norm(), 1e-12);
  // The default start: payload well above the base, flange 45 deg down from horizontal.
  EXPECT_GT(p.p_base_tcp_m.z(), 1.3);
}

TEST(RobotEmulator, RefusesBadConfiguration) {
  RobotConfig c;
  c.servo_bandwidth_hz = 300.0;  // above 2000 / 10
  EXPECT_THROW(RobotEmulator{c}, std::invalid_argument);
  c = RobotConfig{};
  c.start_joints_rad[4] = 130.0 * kDeg;
  try {
    RobotEmulator r(c);
    FAIL() << "accepted A5 = 130 deg";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("A5"), std::string::npos) << e.what();
  }
}

// --- The robot loop over real UDP --------------------------------------------------------------

// Plays zerog-rt: answers every well-formed <Rob> with a fixed RKorr and its IPOC, except for
// the IPOCs it is told to answer wrongly or late. Counts what it gets.
class Responder {
 public:
  Responder() {
    fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    ::inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
    EXPECT_EQ(::bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    socklen_t n = sizeof a;
    ::getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &n);
    port_ = ntohs(a.sin_port);
    thread_ = std::thread([this] { loop(); });
  }
  ~Responder() {
    stop_ = true;
    thread_.join();
    ::close(fd_);
  }
  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }

  proto::rsi::Correction correction{0.5, 0.0, -0.25, 0.0, 0.0, 0.0};
  std::uint64_t wrong_ipoc_for = 0;  // answer this IPOC with IPOC + 1
  std::uint64_t late_for = 0;        // answer this IPOC 15 ms late
  std::atomic<int> messages{0}, malformed{0}, replies{0};

 private:
  void loop() {
    std::array<char, 8192> buf;
    std::array<char, 512> out;
    while (!stop_) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 5) != 1) continue;
      sockaddr_in from{};
      socklen_t n = sizeof from;
      const ssize_t got =
          ::recvfrom(fd_, buf.data(), buf.size(), 0, reinterpret_cast<sockaddr*>(&from), &n);
      if (got < 0) continue;
      proto::rsi::RobotMessage m;
      if (!proto::rsi::parse_robot_message(std::string_view(buf.data(), got), m).ok()) {
        ++malformed;
        continue;
      }
      ++messages;
      std::uint64_t ipoc = m.ipoc;
      if (ipoc == wrong_ipoc_for) ipoc += 1;
      if (m.ipoc == late_for) std::this_thread::sleep_for(std::chrono::milliseconds(15));
      const proto::rsi::FormatResult f = proto::rsi::format_reply(correction, ipoc, out);
      ::sendto(fd_, out.data(), f.size, 0, reinterpret_cast<sockaddr*>(&from), sizeof from);
      ++replies;
    }
  }

  int fd_ = -1;
  std::uint16_t port_ = 0;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

std::vector<std::vector<std::string>> parse_csv(const std::string& text) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::istringstream l(line);
    std::string cell;
    while (std::getline(l, cell, ',')) cells.push_back(cell);
    rows.push_back(cells);
  }
  return rows;
}

TEST(RigEmulatorLoop, AppliesEveryTimelyReplyAndRecordsTheTruth) {
  Responder responder;
  Scenario scenario = default_scenario();
  RigEmulatorOptions options;
  options.robot_bind = "127.0.0.1:0";
  options.rt_address = responder.address();
  options.duration_s = 0.6;  // 50 cycles of 12 ms
  RigEmulator emulator(scenario, options);
  emulator.bind();
  const TcpPose start = emulator.robot().tcp_pose(emulator.robot().commanded());
  std::atomic<bool> stop{false};
  emulator.run(stop);

  const nlohmann::json s = emulator.summary();
  const auto ok = s["replies"]["ok"].get<std::uint64_t>();
  EXPECT_EQ(s["cycles"], 50);
  EXPECT_EQ(s["datagrams"]["sent"], 50);
  EXPECT_EQ(responder.messages.load(), 50);
  // A loaded machine may make a reply late; nearly all must be in time.
  EXPECT_GE(ok, 45u);
  EXPECT_EQ(
      ok + s["replies"]["late"].get<std::uint64_t>() + s["replies"]["missing"].get<std::uint64_t>(),
      50u);
  EXPECT_EQ(s["robot"]["rkorr_applied"].get<std::uint64_t>(), ok);
  EXPECT_EQ(s["robot"]["delay"].get<std::uint64_t>(), 50u - ok);
  EXPECT_EQ(s["replies"]["before_first_ok"], 0);
  EXPECT_EQ(s["replies"]["first_ok_cycle"], 0);
  EXPECT_GT(s["physics"]["steps"].get<std::uint64_t>(), 1100u);  // 2 kHz over 0.6 s

  // The command moved by exactly the applied corrections (x +0.5 mm, z −0.25 mm each).
  const TcpPose end = emulator.robot().tcp_pose(emulator.robot().commanded());
  const Eigen::Vector3d moved = end.p_base_tcp_m - start.p_base_tcp_m;
  EXPECT_NEAR(moved.x(), 0.5e-3 * static_cast<double>(ok), 1e-9);
  EXPECT_NEAR(moved.y(), 0.0, 1e-9);
  EXPECT_NEAR(moved.z(), -0.25e-3 * static_cast<double>(ok), 1e-9);
  EXPECT_LT(rotation_vector(end.R_base_tcp * start.R_base_tcp.transpose()).norm(), 1e-9);

  // truth.csv: a header and one row per cycle; the actual TCP follows, lagging by the servo.
  const auto rows = parse_csv(emulator.truth_csv());
  ASSERT_EQ(rows.size(), 51u);
  ASSERT_EQ(rows[0].size(), 39u);
  EXPECT_EQ(rows[0][9], "tcp_x_m");
  EXPECT_EQ(rows[0][31], "correction");
  std::size_t ok_rows = 0;
  for (std::size_t i = 1; i < rows.size(); ++i) {
    ASSERT_EQ(rows[i].size(), 39u);
    EXPECT_NEAR(std::stod(rows[i][0]), static_cast<double>(i - 1) * 0.012, 1e-12);
    EXPECT_EQ(std::stoull(rows[i][1]), 1'000'000u + (i - 1) * 12);
    if (rows[i][2] == "ok") {
      ++ok_rows;
      EXPECT_EQ(rows[i][31], "rkorr");
      EXPECT_EQ(std::stod(rows[i][32]), 0.5);
      EXPECT_EQ(std::stod(rows[i][34]), -0.25);
    }
  }
  EXPECT_EQ(ok_rows, ok);
  const double x_first = std::stod(rows[1][9]), x_last = std::stod(rows[50][9]);
  EXPECT_NEAR(x_first, start.p_base_tcp_m.x(), 1e-9);
  // At 41.7 mm/s the critically damped servo lags 2/ω · v = 1.7 mm behind the command.
  const double commanded_at_last = 0.5e-3 * 49;
  EXPECT_GT(x_last - x_first, commanded_at_last - 4e-3);
  EXPECT_LT(x_last - x_first, commanded_at_last);
  EXPECT_GT(std::stod(rows[50][16]), 0.02);  // moving in +x at the end (tcp_vx_mps)
}

TEST(RigEmulatorLoop, TheRobotMovesOnThePhysicsClockWhateverTheThreadsDo) {
  // The controller's interpolator runs on the physics clock: each accepted correction takes
  // effect exactly at its tick's physics step, and each truth row is the state at its tick. So
  // the truth is what a robot driven by the same corrections at the exact ticks does, to
  // rounding, however the robot loop and the physics threads were scheduled. (Applied at the
  // robot loop's wall-clock tick instead, a correction landed wherever the physics happened to
  // be: under qemu's TCG up to 30 ms early or late, a jolt of up to 9 % of the turning speed
  // that failed HIL spin.)
  Responder responder;
  responder.correction = {0.4, -0.2, 0.1, 0.15, -0.1, 0.25};
  Scenario scenario = default_scenario();
  RigEmulatorOptions options;
  options.robot_bind = "127.0.0.1:0";
  options.rt_address = responder.address();
  options.duration_s = 0.6;
  RigEmulator emulator(scenario, options);
  emulator.bind();
  std::atomic<bool> stop{false};
  emulator.run(stop);
  const auto& cycles = emulator.cycles();
  ASSERT_EQ(cycles.size(), 50u);

  RobotConfig rc;
  rc.physics_rate_hz = scenario.robot.physics_rate_hz;
  rc.servo_bandwidth_hz = scenario.robot.servo_bandwidth_hz;
  rc.interpolation_s = scenario.cycle_s();
  rc.start_joints_rad = scenario.robot.start_joints_rad;
  rc.p_flange_tcp_m = scenario.sim.p_flange_sensor_m;
  RobotEmulator replay(rc);
  const int steps_per_tick = static_cast<int>(std::lround(scenario.cycle_s() * rc.physics_rate_hz));
  std::size_t applied = 0;
  double worst = 0.0;
  for (std::size_t n = 0; n < cycles.size(); ++n) {
    if (n > 0 && cycles[n - 1].reply == ReplyStatus::ok) {  // the reply to cycle n − 1, at tick n
      replay.apply_rkorr(responder.correction);
      ++applied;
    }
    for (int j = 0; j < 6; ++j)
      worst = std::max(worst, std::abs(cycles[n].q_rad[j] - replay.actual().q_rad[j]));
    for (int k = 0; k < steps_per_tick; ++k) replay.step();
  }
  EXPECT_GE(applied, 40u);  // the robot really moved
  EXPECT_LT(worst, 1e-12) << "largest joint difference to the replay, rad";
  EXPECT_GT((replay.actual().qd_radps[5]), 0.01);
}

TEST(RigEmulatorLoop, FaultsAndBadRepliesAreCountedWhereTheyHappen) {
  Responder responder;
  Scenario scenario = default_scenario();
  auto fault = [](FaultKind kind, double start_s, int cycles, double delay_ms = 0.0) {
    Fault f;
    f.kind = kind;
    f.start_s = start_s;
    f.cycles = cycles;
    f.delay_ms = delay_ms;
    return f;
  };
  // Cycles of 12 ms: drop 10..12, malformed 20..23, duplicate 30..31, reorder 40 (held, sent
  // after 41), foreign 50..51, late 60 (datagram 5 ms late, answered in time).
  scenario.faults = {
      fault(FaultKind::robot_drop, 0.120, 3),      fault(FaultKind::robot_malformed, 0.240, 4),
      fault(FaultKind::robot_duplicate, 0.360, 2), fault(FaultKind::robot_reorder, 0.480, 1),
      fault(FaultKind::robot_foreign, 0.600, 2),   fault(FaultKind::robot_late, 0.720, 1, 5.0)};
  responder.wrong_ipoc_for = 1'000'000 + 70 * 12;
  responder.late_for = 1'000'000 + 75 * 12;
  RigEmulatorOptions options;
  options.robot_bind = "127.0.0.1:0";
  options.rt_address = responder.address();
  options.duration_s = 1.2;  // 100 cycles
  RigEmulator emulator(scenario, options);
  emulator.bind();
  std::atomic<bool> stop{false};
  emulator.run(stop);
  const nlohmann::json s = emulator.summary();
  const auto& cycles = emulator.cycles();
  ASSERT_EQ(cycles.size(), 100u);

  // What went out: 100 cycles − 3 dropped, + 2 duplicates + 2 foreign copies.
  EXPECT_EQ(s["datagrams"]["sent"], 100 - 3 + 2 + 2);
  EXPECT_EQ(s["datagrams"]["malformed"], 4);
  EXPECT_EQ(s["datagrams"]["good"], 100 - 3 - 4);
  EXPECT_EQ(responder.malformed.load(), 4);
  EXPECT_EQ(responder.messages.load(), 100 - 3 - 4 + 2 + 2);
  for (int n : {10, 11, 12, 20, 21, 22, 23}) {
    EXPECT_FALSE(cycles[n].sent) << n;
    EXPECT_EQ(cycles[n].reply, ReplyStatus::none) << n;
  }
  // The duplicate's second reply, the foreign copies' replies (to the second socket).
  EXPECT_EQ(s["replies"]["duplicate"], 2);
  EXPECT_EQ(s["replies"]["to_foreign_socket"], 2);
  // Reordered: 40 went out after 41, so its reply came in 41's cycle: late, not applied.
  EXPECT_EQ(cycles[40].reply, ReplyStatus::late);
  EXPECT_EQ(cycles[41].reply, ReplyStatus::ok);
  // The responder's wrong IPOC and its 15 ms late answer.
  EXPECT_EQ(cycles[70].reply, ReplyStatus::wrong_ipoc);
  EXPECT_EQ(cycles[75].reply, ReplyStatus::late);
  EXPECT_GE(s["replies"]["wrong_ipoc"].get<int>(), 1);
  EXPECT_GE(s["replies"]["late"].get<int>(), 2);
  // The late datagram (5 ms into its 12 ms cycle) was still answered in time.
  EXPECT_EQ(cycles[60].reply, ReplyStatus::ok);

  // Delay counts every cycle without a timely reply, as sent in the next datagram.
  std::uint64_t not_ok = 0;
  for (std::size_t n = 0; n < cycles.size(); ++n) {
    EXPECT_EQ(cycles[n].delay, not_ok) << n;
    not_ok += cycles[n].reply != ReplyStatus::ok;
  }
  EXPECT_EQ(s["robot"]["delay"].get<std::uint64_t>(), not_ok);
  EXPECT_GE(not_ok, 3u + 4u + 1u + 1u + 1u);
  EXPECT_EQ(s["robot"]["rkorr_applied"].get<std::uint64_t>(), 100u - not_ok);

  // The fault list names the cycles each fault changed.
  const nlohmann::json& f = s["faults"];
  ASSERT_EQ(f.size(), 6u);
  EXPECT_EQ(f[0]["kind"], "robot_drop");
  EXPECT_EQ(f[0]["first_cycle"], 10);
  EXPECT_EQ(f[0]["last_cycle"], 12);
  EXPECT_EQ(f[0]["cycles_affected"], 3);
  EXPECT_EQ(f[3]["kind"], "robot_reorder");
  EXPECT_EQ(f[3]["first_cycle"], 40);
  EXPECT_EQ(f[3]["cycles_affected"], 1);
}

TEST(RigEmulatorLoop, TruthModelAndRigReadBackAndNameTheSameRig) {
  Scenario scenario = default_scenario();
  scenario.robot.cycle_ms = 4;
  scenario.sim.effects.add(model::Effect::cable);
  const sim::RigSimulator simulator(scenario.sim);
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "zerog_emu_rig_test";
  std::filesystem::create_directories(dir);
  io::write_model(emulator_truth(scenario, simulator), dir / "truth.json");
  formats::write_rig(emulator_rig(scenario, simulator), dir / "emu.rig.toml");
  const io::ModelFile model = io::read_model(dir / "truth.json");
  const formats::Rig rig = formats::read_rig(dir / "emu.rig.toml");
  std::filesystem::remove_all(dir);
  EXPECT_EQ(model.rig_name, rig.name);
  EXPECT_EQ(rig.name, kEmulatorRigName);
  EXPECT_DOUBLE_EQ(rig.sample_period_s, 0.004);
  EXPECT_DOUBLE_EQ(rig.imu_rate_hz, 2000.0);
  EXPECT_EQ(rig.flange_sensor.p_m, scenario.sim.p_flange_sensor_m);
  EXPECT_TRUE(model.params.effects.has(model::Effect::cable));
  EXPECT_DOUBLE_EQ(model.params.block(model::Effect::gravity)[0], 100.0);
  EXPECT_EQ(model.extra["generator"], "zerog-emu");
}

TEST(RigEmulatorLoop, RefusesBadAddresses) {
  const Scenario scenario = default_scenario();
  RigEmulatorOptions options;
  options.rt_address = "localhost:49152";
  EXPECT_THROW(RigEmulator(scenario, options), std::invalid_argument);
  options.rt_address = "127.0.0.1:70000";
  EXPECT_THROW(RigEmulator(scenario, options), std::invalid_argument);
  options.rt_address = "127.0.0.1:49152";
  options.robot_bind = "127.0.0.1";
  EXPECT_THROW(RigEmulator(scenario, options), std::invalid_argument);
}

}  // namespace
}  // namespace zerog::emu
