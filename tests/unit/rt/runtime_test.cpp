// The runtime end to end on loopback UDP: a real RsiEndpoint and the runtime's cycle and
// recorder threads; a small robot in the test sends <Rob> datagrams and reads the <Sen> replies,
// and feeds the F/T and IMU rings the sensor threads would fill (the fakes' 64-entry scripts are
// too short for a run). Checked: every datagram is answered with its IPOC; --enable-zero-g's
// announcement; a push moves the robot; a silent F/T sensor is held, then faults ft_stale at the
// documented cycle with zero corrections from then on; the black box file appears with the fault
// cycle last; the recording reads back with formats::read_log, one row per cycle; the summary.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <thread>
#include <vector>

#include "../rtio/udp.hpp"
#include "rt_fixtures.hpp"
#include "zerog/formats/cycles_csv.hpp"
#include "zerog/proto/rsi_si.hpp"
#include "zerog/rt/runtime.hpp"
#include "zerog/rtio/rsi_endpoint.hpp"

namespace zerog::rt {
namespace {

namespace fs = std::filesystem;
namespace rsi = proto::rsi;
using namespace std::chrono_literals;

// A started RSI endpoint on a free loopback port (null if it did not start), its receive timeout
// long enough that the test's robot, slower than a controller, is never late.
std::unique_ptr<rtio::RsiEndpoint> loopback_endpoint() {
  rtio::RsiEndpointConfig rc;
  rc.bind_port = 0;
  rc.receive_timeout = 1s;
  auto endpoint = std::make_unique<rtio::RsiEndpoint>(rc);
  if (endpoint->start() != rtio::RobotStartStatus::ok) return nullptr;
  return endpoint;
}

// Zero-g enabled as soon as the robot is there, recording into `dir`/rec with the test rig.
RuntimeOptions recording_options(const test::TempDir& dir) {
  RuntimeOptions options;
  options.auto_enable_zero_g = true;
  options.recorder.dir = dir.path() / "rec";
  options.recorder.rig = test::test_rig();
  return options;
}

// Configures `rt` with the test cycle and payload model (and `path`, if given) and starts it.
testing::AssertionResult configure_and_start(Runtime& rt, std::vector<Status>& warnings,
                                             const loop::JointPath* path = nullptr) {
  if (const Status s = rt.configure(test::test_cycle_config(), test::payload_model(), path);
      !s.ok())
    return testing::AssertionFailure() << "configure: " << s.text();
  if (const Status s = rt.start(warnings); !s.ok())
    return testing::AssertionFailure() << "start: " << s.text();
  return testing::AssertionSuccess();
}

class RobotInTest {
 public:
  explicit RobotInTest(std::uint16_t endpoint_port) : port_(endpoint_port) {}
  bool ok() const { return peer_.ok(); }
  std::uint16_t port() const { return peer_.port(); }

  /// Sends `m` and waits for the reply; false on timeout or a reply that does not parse.
  bool exchange(const rsi::RobotMessage& m, rsi::Reply& reply) {
    std::array<char, 1024> buffer{};
    const rsi::FormatResult f = rsi::format_robot_message(m, buffer);
    if (f.status != rsi::FormatStatus::ok) return false;
    if (!peer_.send_to(port_, std::string_view(buffer.data(), f.size))) return false;
    const long n = peer_.receive(buffer, 2000);
    if (n <= 0) return false;
    return rsi::parse_reply(std::string_view(buffer.data(), static_cast<std::size_t>(n)), reply)
        .ok();
  }

 private:
  rtio::test::UdpPeer peer_;
  std::uint16_t port_;
};

double norm(const rsi::Correction& c) {
  return std::abs(c.x_mm) + std::abs(c.y_mm) + std::abs(c.z_mm) + std::abs(c.a_deg) +
         std::abs(c.b_deg) + std::abs(c.c_deg);
}

TEST(Runtime, EndToEndOnLoopbackUdp) {
  test::TempDir dir;
  const auto endpoint = loopback_endpoint();
  ASSERT_NE(endpoint, nullptr);

  Runtime rt(recording_options(dir), RuntimeDevices{endpoint.get()});
  std::vector<Status> warnings;
  ASSERT_TRUE(configure_and_start(rt, warnings));
  EXPECT_TRUE(warnings.empty());

  RobotInTest robot(endpoint->local_port());
  ASSERT_TRUE(robot.ok());
  test::StaticRobot rig;
  std::uint64_t cycles = 0;
  std::vector<std::string> announced;
  auto one_cycle = [&](const Eigen::Matrix<double, 6, 1>& contact, bool ft_silent) {
    for (int i = 0; i < 4 && !ft_silent; ++i) EXPECT_TRUE(rt.ft_ring().try_push(rig.ft(contact)));
    for (int i = 0; i < 24; ++i) EXPECT_TRUE(rt.imu_ring().try_push(rig.imu_sample));
    rsi::Reply reply;
    EXPECT_TRUE(robot.exchange(rig.message, reply)) << "cycle " << cycles + 1;
    EXPECT_EQ(reply.ipoc, rig.message.ipoc);
    EXPECT_TRUE(reply.has_rkorr);
    rig.message.ipoc += 12;
    ++cycles;
    const SupervisorEvents ev = rt.supervise();
    announced.insert(announced.end(), ev.out.begin(), ev.out.end());
    return reply.rkorr;
  };
  const Eigen::Matrix<double, 6, 1> none = Eigen::Matrix<double, 6, 1>::Zero();

  // Idle until the rows are there; --enable-zero-g's request goes in as soon as it is ready.
  for (int i = 0; i < 20; ++i) EXPECT_EQ(norm(one_cycle(none, false)), 0.0);
  ASSERT_EQ(announced.size(), 1u);
  EXPECT_EQ(announced[0].rfind("zerog-rt: zero-g enabled at cycle ", 0), 0u) << announced[0];
  const std::uint64_t enabled_at = std::stoull(announced[0].substr(34));
  EXPECT_GE(enabled_at, 6u);
  EXPECT_LE(enabled_at, 20u);

  // A push moves the robot.
  double moved = 0.0;
  for (int i = 0; i < 30; ++i) moved += norm(one_cycle(test::push(50.0, 0.0, 0.0), false));
  EXPECT_GT(moved, 1.0);

  // The F/T sensor falls silent: the last wrench is held (the robot keeps moving) for
  // ft_fault_cycles − 1 cycles; the next cycle faults and answers zero, and so do all after.
  const int threshold = test::test_cycle_config().watchdog.ft_fault_cycles;
  for (int i = 1; i < threshold; ++i) EXPECT_GT(norm(one_cycle(none, true)), 0.0) << i;
  EXPECT_EQ(norm(one_cycle(none, true)), 0.0);
  const std::uint64_t fault_cycle = cycles;
  for (int i = 0; i < 10; ++i) EXPECT_EQ(norm(one_cycle(test::push(50.0, 0.0, 0.0), false)), 0.0);

  // The black box, written by the recorder thread.
  const fs::path box = dir.path() / "rec" / ("blackbox-" + std::to_string(fault_cycle) + ".csv");
  for (int i = 0; i < 500 && !fs::exists(box); ++i) std::this_thread::sleep_for(10ms);
  ASSERT_TRUE(fs::exists(box)) << box;
  const std::string box_text = test::read_text(box);
  EXPECT_NE(box_text.find("fault ft_stale at cycle " + std::to_string(fault_cycle)),
            std::string::npos);
  const std::size_t last_line = box_text.rfind('\n', box_text.size() - 2) + 1;
  EXPECT_EQ(box_text.substr(last_line, box_text.find(',', last_line) - last_line),
            std::to_string(fault_cycle));
  EXPECT_NE(box_text.find(",fault,ft_stale,", last_line), std::string::npos);

  EXPECT_EQ(rt.stop().text(), "");
  EXPECT_NE(rt.status_line().find("state fault, fault ft_stale, cycles " + std::to_string(cycles)),
            std::string::npos)
      << rt.status_line();

  // The recording: one log row per cycle (samples from the first one), cycles.csv likewise.
  const formats::Log log = formats::read_log(dir.path() / "rec" / "run.csv");
  ASSERT_EQ(log.samples.size(), cycles);
  EXPECT_DOUBLE_EQ(log.samples[1].t_s - log.samples[0].t_s, 0.012);
  // (the log keeps 9 significant digits)
  EXPECT_NEAR(log.samples[0].joints_rad[1], -80.0 * rsi::kRadPerDeg, 1e-8);
  EXPECT_NEAR(log.samples[0].p_base_sensor_m.x(), 1.5, 1e-8);
  EXPECT_NEAR(log.samples[0].force_sensor_N.z(), rig.payload[2], 1e-6);
  EXPECT_NEAR(log.samples[30].force_sensor_N.x(), rig.payload[0] + 50.0, 1e-6);
  EXPECT_EQ(log.rig.name, test::test_rig().name);
  const std::string cycles_csv = test::read_text(dir.path() / "rec" / "cycles.csv");
  EXPECT_EQ(static_cast<std::uint64_t>(std::count(cycles_csv.begin(), cycles_csv.end(), '\n')),
            cycles + 1);
  for (const auto& entry : fs::directory_iterator(dir.path() / "rec"))
    EXPECT_NE(entry.path().extension(), ".partial") << entry.path();

  // The summary.
  const nlohmann::json s = nlohmann::json::parse(rt.summary_json());
  EXPECT_EQ(s["cycles"]["messages"], cycles);
  EXPECT_EQ(s["devices"]["robot"]["replies"], cycles);
  EXPECT_EQ(s["cycle_thread"]["replies_ok"], cycles);
  EXPECT_EQ(s["compute_ns"]["count"], cycles);
  EXPECT_GT(s["compute_ns"]["p99"].get<std::uint64_t>(), 0u);
  EXPECT_EQ(s["rings"]["records"]["dropped"], 0);
  EXPECT_EQ(s["recording"]["log_rows"], cycles);
  ASSERT_EQ(s["transitions"].size(), 2u);
  EXPECT_EQ(s["transitions"][0]["to"], "zero_g");
  EXPECT_EQ(s["transitions"][0]["command"], "enable_zero_g");
  EXPECT_EQ(s["transitions"][0]["cycle"], enabled_at);
  EXPECT_EQ(s["transitions"][1]["from"], "zero_g");
  EXPECT_EQ(s["transitions"][1]["fault"], "ft_stale");
  EXPECT_EQ(s["transitions"][1]["cycle"], fault_cycle);
  ASSERT_EQ(s["black_box_dumps"].size(), 1u);
  EXPECT_EQ(s["black_box_dumps"][0], box.string());
  EXPECT_EQ(s["state"], "fault");
  // Measured, not asserted (a shared machine): step() and receive → reply on loopback.
  std::printf("compute_ns %s\nreply_latency_ns %s\n", s["compute_ns"].dump().c_str(),
              s["reply_latency_ns"].dump().c_str());
}

TEST(Runtime, ResetAfterTheDumpReleasesTheBlackBoxForTheNextFault) {
  test::TempDir dir;
  const auto endpoint = loopback_endpoint();
  ASSERT_NE(endpoint, nullptr);
  RuntimeOptions options;
  options.recorder.blackbox_dir = dir.path();
  Runtime rt(options, RuntimeDevices{endpoint.get()});
  std::vector<Status> warnings;
  ASSERT_TRUE(configure_and_start(rt, warnings));
  RobotInTest robot(endpoint->local_port());
  test::StaticRobot rig;
  std::uint64_t cycles = 0;
  auto one_cycle = [&](bool ft_silent) {
    for (int i = 0; i < 4 && !ft_silent; ++i)
      rt.ft_ring().try_push(rig.ft(Eigen::Matrix<double, 6, 1>::Zero()));
    for (int i = 0; i < 24; ++i) rt.imu_ring().try_push(rig.imu_sample);
    rsi::Reply reply;
    EXPECT_TRUE(robot.exchange(rig.message, reply));
    EXPECT_EQ(reply.ipoc, rig.message.ipoc);
    rig.message.ipoc += 12;
    ++cycles;
  };
  auto wait_for = [&](const fs::path& p) {
    for (int i = 0; i < 500 && !fs::exists(p); ++i) std::this_thread::sleep_for(10ms);
    return fs::exists(p);
  };
  // The F/T watchdog runs in idle too, once the sensor has delivered: after 3 good cycles a
  // silent sensor faults ft_stale at its 5th cycle (cycle 8).
  for (int i = 0; i < 3; ++i) one_cycle(false);
  for (int i = 0; i < 5; ++i) one_cycle(true);
  ASSERT_TRUE(wait_for(dir.path() / "blackbox-8.csv"));
  // The file appears at the dump's rename, just before the recorder hands the box back: a reset
  // before the hand-back would release the box only at a later cycle (after the next fault).
  for (int i = 0; i < 500 && rt.black_box_pending(); ++i) std::this_thread::sleep_for(10ms);
  ASSERT_FALSE(rt.black_box_pending());
  for (int i = 0; i < 3; ++i) one_cycle(false);
  ASSERT_TRUE(rt.request(loop::Command::reset_fault));
  for (int i = 0; i < 3; ++i) one_cycle(false);
  for (int i = 0; i < 5; ++i) one_cycle(true);  // the second fault, at cycle 19
  ASSERT_TRUE(wait_for(dir.path() / "blackbox-19.csv"));
  EXPECT_EQ(rt.stop().text(), "");
  EXPECT_EQ(rt.cycle_thread_counters().black_box_releases, 1u);
  EXPECT_EQ(rt.black_box_paths().size(), 2u);
  EXPECT_EQ(cycles, 19u);
}

class Ramp final : public loop::JointPath {
 public:
  explicit Ramp(std::array<double, 6> start) : start_(start) {}
  double duration_s() const override { return 0.6; }
  std::array<double, 6> at(double t) const override {
    std::array<double, 6> q = start_;
    q[0] += 0.05 * std::clamp(t / 0.6, 0.0, 1.0);
    return q;
  }

 private:
  std::array<double, 6> start_;
};

TEST(Runtime, CollectStartsWhenReadyAnswersWithAxisCorrectionsAndFinishes) {
  test::TempDir dir;
  const auto endpoint = loopback_endpoint();
  ASSERT_NE(endpoint, nullptr);
  test::StaticRobot rig;
  Ramp path(rsi::joints_to_rad(rig.message.joints_deg));
  RuntimeOptions options;
  options.auto_collect = true;
  options.recorder.dir = dir.path() / "collect";
  options.recorder.rig = test::test_rig();
  Runtime rt(options, RuntimeDevices{endpoint.get()});
  std::vector<Status> warnings;
  ASSERT_TRUE(configure_and_start(rt, warnings, &path));
  RobotInTest robot(endpoint->local_port());
  std::vector<std::string> announced;
  double a1_deg = 0.0;
  std::uint64_t cycles = 0;
  for (; cycles < 200 && !rt.collection_finished(); ++cycles) {
    for (int i = 0; i < 4; ++i) rt.ft_ring().try_push(rig.ft(Eigen::Matrix<double, 6, 1>::Zero()));
    for (int i = 0; i < 24; ++i) rt.imu_ring().try_push(rig.imu_sample);
    rsi::Reply reply;
    ASSERT_TRUE(robot.exchange(rig.message, reply));
    ASSERT_EQ(reply.ipoc, rig.message.ipoc);
    if (reply.has_akorr) {
      a1_deg += reply.akorr_deg[0];
      // The robot follows (a real controller would report the moved axes).
      for (int k = 0; k < 6; ++k) rig.message.joints_deg[k] += reply.akorr_deg[k];
    }
    rig.message.ipoc += 12;
    for (int i = 0; i < 20; ++i) {  // let the cycle thread publish its status
      const SupervisorEvents ev = rt.supervise();
      announced.insert(announced.end(), ev.out.begin(), ev.out.end());
      if (!ev.out.empty() || rt.collection_finished()) break;
      std::this_thread::sleep_for(100us);
    }
  }
  EXPECT_TRUE(rt.collection_finished());
  ASSERT_EQ(announced.size(), 2u);
  EXPECT_EQ(announced[0].rfind("zerog-rt: collection started at cycle ", 0), 0u) << announced[0];
  EXPECT_EQ(announced[1].rfind("zerog-rt: collection finished at cycle ", 0), 0u) << announced[1];
  EXPECT_NEAR(a1_deg * rsi::kRadPerDeg, 0.05, 1e-3);  // 4 decimals of a degree per reply
  EXPECT_EQ(rt.stop().text(), "");
  EXPECT_EQ(rt.cycle().state_machine().state(), loop::State::idle);
  // The collection is recorded for zerog fit: the joints moved along A1 in the log.
  const formats::Log log = formats::read_log(dir.path() / "collect" / "run.csv");
  ASSERT_EQ(log.samples.size(), cycles);
  EXPECT_NEAR(log.samples.back().joints_rad[0] - log.samples.front().joints_rad[0], 0.05, 1e-3);
}

// SI at the border, the reply side (proto/loop.md): the cycle's correction is SI (m, rad) and is
// converted to the wire's mm and degrees exactly once, in rtio, on its way into the UDP reply;
// cycles.csv's writer converts the record's copy for the file once too. A conversion too many
// anywhere (the cycle, the record, rtio, the writer) makes one side 1000 or 57.3 times the other.
TEST(Runtime, TheCyclesSiCorrectionReachesTheUdpReplyInMillimetresAndDegreesOnce) {
  test::TempDir dir;
  const auto endpoint = loopback_endpoint();
  ASSERT_NE(endpoint, nullptr);
  Runtime rt(recording_options(dir), RuntimeDevices{endpoint.get()});
  std::vector<Status> warnings;
  ASSERT_TRUE(configure_and_start(rt, warnings));
  RobotInTest robot(endpoint->local_port());
  ASSERT_TRUE(robot.ok());
  test::StaticRobot rig;
  // A push through the centre of mass and a twist about the sensor's z: translation and rotation.
  Eigen::Matrix<double, 6, 1> push = test::push(50.0, -20.0, 0.0);
  push[5] += 8.0;
  rsi::Reply last;
  for (int i = 0; i < 50; ++i) {
    for (int k = 0; k < 4; ++k)
      EXPECT_TRUE(
          rt.ft_ring().try_push(rig.ft(i < 20 ? Eigen::Matrix<double, 6, 1>::Zero() : push)));
    for (int k = 0; k < 24; ++k) EXPECT_TRUE(rt.imu_ring().try_push(rig.imu_sample));
    ASSERT_TRUE(robot.exchange(rig.message, last)) << "cycle " << i + 1;
    rig.message.ipoc += 12;
    (void)rt.supervise();
  }
  EXPECT_EQ(rt.stop().text(), "");

  // The cycle's own value (SI; the cycle thread has stopped): the last reply's correction.
  const loop::CycleRecord& record = rt.cycle().last();
  ASSERT_EQ(record.state, loop::State::zero_g);
  ASSERT_EQ(record.reply.kind, samples::RobotCorrection::Kind::cartesian);
  ASSERT_EQ(record.reply.ipoc, last.ipoc);
  const std::array<double, 3>& t_m = record.reply.translation_m;
  const std::array<double, 3> abc_rad = rsi::rkorr_abc_rad(record.reply);
  // Moving, but by a plausible amount of metres and radians per 12 ms (not mm, not degrees).
  EXPECT_GT(std::abs(t_m[0]), 1e-5);
  EXPECT_LT(std::hypot(t_m[0], t_m[1], t_m[2]), 0.01);
  const double turn_rad =
      std::max({std::abs(abc_rad[0]), std::abs(abc_rad[1]), std::abs(abc_rad[2])});
  EXPECT_GT(turn_rad, 1e-4);
  EXPECT_LT(turn_rad, 0.01);
  // The UDP reply: that value in mm and degrees, once (RSI writes 4 decimals).
  ASSERT_TRUE(last.has_rkorr);
  const double x[] = {last.rkorr.x_mm, last.rkorr.y_mm, last.rkorr.z_mm};
  const double a[] = {last.rkorr.a_deg, last.rkorr.b_deg, last.rkorr.c_deg};
  for (int k = 0; k < 3; ++k) {
    EXPECT_NEAR(x[k], t_m[static_cast<std::size_t>(k)] * 1e3, 0.51e-4) << k;
    EXPECT_NEAR(a[k], abc_rad[static_cast<std::size_t>(k)] / rsi::kRadPerDeg, 0.51e-4) << k;
  }
  // cycles.csv: the same reply, converted for the file once (and read back to SI).
  const std::vector<loop::CycleRecord> rows =
      formats::read_cycles_csv(dir.path() / "rec" / "cycles.csv");
  ASSERT_FALSE(rows.empty());
  const samples::RobotCorrection& back = rows.back().reply;
  EXPECT_EQ(back.ipoc, last.ipoc);
  ASSERT_EQ(back.kind, samples::RobotCorrection::Kind::cartesian);
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_NEAR(back.translation_m[k], t_m[k], 1e-15) << k;
    EXPECT_NEAR(rsi::rkorr_abc_rad(back)[k], abc_rad[k], 1e-14) << k;
  }
}

TEST(CommandLine, ParsesTheFiveCommandsAndNamesTheRest) {
  EXPECT_EQ(parse_command_line("enable").command, loop::Command::enable_zero_g);
  EXPECT_EQ(parse_command_line("  stop\r").command, loop::Command::stop);
  EXPECT_EQ(parse_command_line("reset").command, loop::Command::reset_fault);
  EXPECT_EQ(parse_command_line("collect").command, loop::Command::start_collection);
  EXPECT_EQ(parse_command_line("collect").kind, CommandLine::Kind::command);
  EXPECT_EQ(parse_command_line("quit").kind, CommandLine::Kind::quit);
  EXPECT_EQ(parse_command_line("   ").kind, CommandLine::Kind::none);
  EXPECT_EQ(parse_command_line("enable zero-g").kind, CommandLine::Kind::unknown);
}

}  // namespace
}  // namespace zerog::rt
