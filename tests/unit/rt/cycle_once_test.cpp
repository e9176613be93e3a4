// Runtime::cycle_once(), the cycle thread's whole loop body, allocates nothing: with a
// FakeRobotLink and rings fed from FakeFtSensor/FakeImu, through idle, zero-g with a push, a
// silent F/T sensor (hold, then the ft_stale fault), lost robot cycles, and collection mode with
// axis replies. Every message is answered with its IPOC.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "alloc_count.hpp"
#include "rt_fixtures.hpp"
#include "zerog/rt/runtime.hpp"
#include "zerog/rtio/fake_ft_sensor.hpp"
#include "zerog/rtio/fake_imu.hpp"
#include "zerog/rtio/fake_robot_link.hpp"

namespace zerog::rt {
namespace {

using test::StaticRobot;

class CycleOnce : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(robot_link.start(), rtio::RobotStartStatus::ok);
    ASSERT_EQ(ft.start(), rtio::FtStartStatus::ok);
    ASSERT_EQ(imu.start(), rtio::ImuStartStatus::ok);
  }

  // What the sensor threads would do for one robot cycle: 4 F/T and 24 IMU samples from the
  // fakes into the rings; then the robot's datagram. Not counted (test side).
  void feed(Runtime& rt, const Eigen::Matrix<double, 6, 1>& contact, bool ft_silent = false,
            bool send = true) {
    samples::FtSample f;
    for (int i = 0; i < 4 && !ft_silent; ++i) {
      ASSERT_TRUE(ft.push(rtio::FtReadStatus::sample, robot.ft(contact)));
      ASSERT_EQ(ft.read_sample(f), rtio::FtReadStatus::sample);
      ASSERT_TRUE(rt.ft_ring().try_push(f));
    }
    samples::ImuSample s;
    for (int i = 0; i < 24; ++i) {
      ASSERT_TRUE(imu.push(rtio::ImuReadStatus::sample, robot.imu_sample));
      ASSERT_EQ(imu.read_sample(s), rtio::ImuReadStatus::sample);
      ASSERT_TRUE(rt.imu_ring().try_push(s));
    }
    if (send) {
      ASSERT_TRUE(robot_link.push(robot.message));
      sent_ipoc = robot.message.ipoc;
      robot.message.ipoc += 12;
    }
  }

  // One cycle_once(), counting its allocations.
  void cycle(Runtime& rt) {
    zerog::test::AllocGuard guard("Runtime::cycle_once");
    rt.cycle_once();
    guard.stop();
    allocations += guard.allocations() + guard.frees();
  }

  rtio::FakeRobotLink robot_link;
  rtio::FakeFtSensor ft;
  rtio::FakeImu imu;
  StaticRobot robot;
  std::uint64_t sent_ipoc = 0;
  std::size_t allocations = 0;
};

TEST_F(CycleOnce, TheSupervisorSnapshotAndTelemetryHandOverAllocateNothing) {
  RuntimeOptions options;
  options.model_file_crc32 = 0xC0FFEEu;
  telemetry::TelemetryConfig t;  // configured, not started: offer() only fills the queue
  t.domain_id = 7;
  options.telemetry = t;
  auto rt = std::make_unique<Runtime>(options, RuntimeDevices{&robot_link});
  ASSERT_EQ(rt->configure(test::test_cycle_config(), test::payload_model()).text(), "");
  modbus::SupervisorTarget& target = *rt;
  EXPECT_EQ(target.snapshot().model_crc32, 0xC0FFEEu) << "identity published at configure";
  EXPECT_EQ(target.snapshot().model_effects, model::kDefaultModel.bits());
  const Eigen::Matrix<double, 6, 1> none = Eigen::Matrix<double, 6, 1>::Zero();
  for (int i = 0; i < 6; ++i) {
    feed(*rt, none);
    cycle(*rt);
  }
  // The PLC's mass change, taken by the next cycle (idle), mirrored to the telemetry.
  loop::Tunables tun = target.tunables();
  EXPECT_EQ(tun.body.mass_kg, test::kMass);
  tun.body.mass_kg = 80.0;
  ASSERT_TRUE(target.propose(tun));
  feed(*rt, none);
  cycle(*rt);
  EXPECT_EQ(target.proposal_status(), loop::ProposalStatus::accepted);
  ASSERT_TRUE(target.request(loop::Command::enable_zero_g));
  for (int i = 0; i < 20; ++i) {
    feed(*rt, test::push(i < 10 ? 40.0 : 0.0, 0.0, 0.0));
    cycle(*rt);
  }
  EXPECT_EQ(allocations, 0u);
  const modbus::SupervisorSnapshot s = target.snapshot();
  EXPECT_EQ(s.state, loop::State::zero_g);
  EXPECT_EQ(s.cycle, 27u);
  EXPECT_EQ(s.model_crc32, 0xC0FFEEu);
  EXPECT_GT(s.compute_last_s, 0.0);
  EXPECT_EQ(s.contact_sensor, rt->cycle().last().contact);
  EXPECT_EQ(rt->cycle().motion().body().params().mass_kg, 80.0);
  ASSERT_NE(rt->telemetry(), nullptr);
  EXPECT_EQ(rt->telemetry()->counters().records_offered, 27u);
}

TEST_F(CycleOnce, AllocatesNothingInZeroGAndThroughAFault) {
  auto rt = std::make_unique<Runtime>(RuntimeOptions{}, RuntimeDevices{&robot_link});
  ASSERT_EQ(rt->configure(test::test_cycle_config(), test::payload_model()).text(), "");
  const Eigen::Matrix<double, 6, 1> none = Eigen::Matrix<double, 6, 1>::Zero();
  for (int i = 0; i < 6; ++i) {
    feed(*rt, none);
    cycle(*rt);
  }
  ASSERT_TRUE(rt->request(loop::Command::enable_zero_g));
  feed(*rt, none);
  cycle(*rt);
  ASSERT_EQ(rt->cycle().state_machine().state(), loop::State::zero_g);

  double moved_mm = 0.0;
  for (int i = 0; i < 200; ++i) {
    feed(*rt, test::push(i < 60 ? 40.0 : 0.0, 5.0, 0.0));
    cycle(*rt);
    const rtio::FakeRobotLink::Reply& r = robot_link.reply_at(robot_link.reply_count() - 1);
    ASSERT_EQ(r.ipoc, sent_ipoc);
    moved_mm += std::abs(r.correction.x_mm) + std::abs(r.correction.y_mm);
  }
  EXPECT_GT(moved_mm, 1.0);  // the push moved the robot
  // The F/T sensor falls silent: held for ft_fault_cycles − 1 cycles, then the fault.
  const int threshold = rt->cycle().config().watchdog.ft_fault_cycles;
  for (int i = 1; i <= threshold + 10; ++i) {
    feed(*rt, none, /*ft_silent=*/true);
    cycle(*rt);
    EXPECT_EQ(rt->cycle().state_machine().state(),
              i < threshold ? loop::State::zero_g : loop::State::fault)
        << "silent cycle " << i;
  }
  EXPECT_EQ(rt->cycle().state_machine().fault(), loop::Fault::ft_stale);
  // Lost robot cycles (receive timeouts) and a reset, still without allocating.
  for (int i = 0; i < 5; ++i) {
    feed(*rt, none, false, /*send=*/false);
    cycle(*rt);
  }
  ASSERT_TRUE(rt->request(loop::Command::reset_fault));
  feed(*rt, none);
  cycle(*rt);
  EXPECT_EQ(rt->cycle().state_machine().state(), loop::State::idle);

  EXPECT_EQ(allocations, 0u);
  EXPECT_EQ(rt->cycle_thread_counters().receive_timeouts, 5u);
  EXPECT_EQ(rt->cycle_thread_counters().replies_ok, rt->cycle().counters().messages);
  EXPECT_EQ(rt->cycle_thread_counters().samples_discarded, 5u * 28u);
  EXPECT_EQ(rt->compute_histogram().count(), rt->cycle().counters().messages);
  EXPECT_GT(rt->compute_histogram().max(), 0u);
  // The frozen black box waits for the recorder (none here): not released by the reset.
  EXPECT_TRUE(rt->cycle().black_box().frozen());
  EXPECT_EQ(rt->record_ring().pushed(), rt->cycle().counters().messages);
}

class Ramp final : public loop::JointPath {
 public:
  explicit Ramp(std::array<double, 6> start) : start_(start) {}
  double duration_s() const override { return 1.0; }
  std::array<double, 6> at(double t) const override {
    std::array<double, 6> q = start_;
    q[0] += 0.1 * std::clamp(t, 0.0, 1.0);
    return q;
  }

 private:
  std::array<double, 6> start_;
};

TEST_F(CycleOnce, AllocatesNothingInCollectionModeAndAnswersWithAxisCorrections) {
  Ramp path(proto::rsi::joints_to_rad(robot.message.joints_deg));
  auto rt = std::make_unique<Runtime>(RuntimeOptions{}, RuntimeDevices{&robot_link});
  ASSERT_EQ(rt->configure(test::test_cycle_config(), test::payload_model(), &path).text(), "");
  const Eigen::Matrix<double, 6, 1> none = Eigen::Matrix<double, 6, 1>::Zero();
  // A session with a path answers AKorr only (zeros before the collection starts: the
  // controller's context for it takes nothing else).
  int axis_replies = 0;
  for (int i = 0; i < 6; ++i) {
    feed(*rt, none);
    cycle(*rt);
    const rtio::FakeRobotLink::Reply& r = robot_link.reply_at(robot_link.reply_count() - 1);
    if (r.axis && r.akorr_deg == std::array<double, 6>{}) ++axis_replies;
  }
  ASSERT_EQ(axis_replies, 6);
  ASSERT_TRUE(rt->request(loop::Command::start_collection));
  double a1_deg = 0.0;
  for (int i = 0; i < 120; ++i) {
    feed(*rt, none);
    cycle(*rt);
    const rtio::FakeRobotLink::Reply& r = robot_link.reply_at(robot_link.reply_count() - 1);
    ASSERT_EQ(r.ipoc, sent_ipoc);
    if (r.axis) {
      ++axis_replies;
      a1_deg += r.akorr_deg[0];
    }
  }
  EXPECT_EQ(allocations, 0u);
  EXPECT_EQ(rt->cycle().state_machine().state(), loop::State::idle);  // the path's end
  EXPECT_EQ(axis_replies, 126);                                       // every reply
  EXPECT_EQ(rt->cycle_thread_counters().axis_replies, static_cast<std::uint64_t>(axis_replies));
  EXPECT_NEAR(a1_deg * proto::rsi::kRadPerDeg, 0.1, 1e-9);
}

}  // namespace
}  // namespace zerog::rt
