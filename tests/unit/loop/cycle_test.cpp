// zerog::loop::Cycle without I/O: time alignment, zero-g motion from a push, watchdogs (hold,
// then fault with zero correction, at the documented cycle), IPOC handling, collection mode and
// the allocation-free cycle.
#include "zerog/loop/cycle.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <functional>
#include <thread>
#include <vector>

#include "alloc_count.hpp"
#include "loop_fixtures.hpp"

namespace zerog::loop {
namespace {

using test::kMass;
using test::kPeriod;
using test::payload_model;
using test::push;
using test::start_zero_g;
using test::StaticRobot;
using test::test_cycle_config;
using zerog::test::AllocGuard;
using zerog::test::RsiReply;

// A refused value is invalid_setting naming its CycleConfig field as a path; the message does
// not repeat the field.
void expect_refused(const CycleConfig& bad, const std::string& setting, const std::string& why) {
  Cycle c;
  const zerog::Status st = c.configure(bad, payload_model());
  EXPECT_EQ(st.code(), zerog::StatusCode::invalid_setting) << setting;
  EXPECT_EQ(st.setting(), setting) << st.text();
  EXPECT_NE(st.message().find(why), std::string::npos) << st.text();
  EXPECT_EQ(st.text(), setting + ": " + st.message());
  EXPECT_FALSE(c.ready());
  const zerog::Status again = check_config(bad);
  EXPECT_EQ(again.setting(), setting) << "check_config is configure's check";
}

TEST(Cycle, ConfigureNamesTheRefusedField) {
  CycleConfig bad = test_cycle_config();
  bad.angular_accel_order = 3;
  expect_refused(bad, "angular_accel_order", "must be 2 or 4, is 3");
  bad = test_cycle_config();
  bad.period_s = 0.0;
  expect_refused(bad, "period_s", "positive");
  bad = test_cycle_config();
  bad.body.inertia_body_kgm2(0, 1) = 1.0;
  expect_refused(bad, "body.inertia_body_kgm2", "symmetric positive definite");
  bad = test_cycle_config();
  bad.watchdog.robot_late_cycles = 0;
  expect_refused(bad, "watchdog.robot_late_cycles", "at least 1, is 0");
  bad = test_cycle_config();
  bad.limits.max_angular_speed_radps = -1.0;
  expect_refused(bad, "limits.max_angular_speed_radps", "must be positive");
  bad = test_cycle_config();
  bad.limits.torque_deadband_Nm = bad.limits.max_contact_torque_Nm;
  expect_refused(bad, "limits.torque_deadband_Nm", "below max_contact_torque_Nm");
  bad = test_cycle_config();
  bad.limits.workspace_max_m.y() = bad.limits.workspace_min_m.y();
  expect_refused(bad, "limits.workspace_max_m", "above workspace_min_m");
  bad = test_cycle_config();
  bad.p_sensor_com_m.z() = std::nan("");
  expect_refused(bad, "p_sensor_com_m", "finite");
  bad = test_cycle_config();
  bad.approach_accel_radps2 = 0.0;
  expect_refused(bad, "approach_accel_radps2", "positive");
  EXPECT_TRUE(check_config(test_cycle_config()).ok());
  Cycle c;
  EXPECT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
}

// The model's refusal (Inference::configure) comes back as the model's, and nothing changes.
TEST(Cycle, ConfigureReportsARefusedModelAsTheModels) {
  Cycle c;
  infer::DeployedModel bad = payload_model();
  bad.rig.name.clear();
  const zerog::Status st = c.configure(test_cycle_config(), bad);
  EXPECT_EQ(st.code(), zerog::StatusCode::invalid_setting);
  EXPECT_EQ(st.setting(), "model.rig.name");
  EXPECT_EQ(st.message(), "is empty");
  EXPECT_FALSE(c.inference().configured());
}

// check_tunables (the proposals' check, real-time safe) names the Tunables field the same way.
TEST(Cycle, CheckTunablesNamesTheField) {
  const CycleConfig good = test_cycle_config();
  Tunables t{good.body, good.limits, good.p_sensor_com_m};
  EXPECT_TRUE(check_tunables(t).ok());
  EXPECT_STREQ(check_tunables(t).setting, "");
  t.body.mass_kg = 0.0;
  EXPECT_STREQ(check_tunables(t).setting, "body.mass_kg");
  EXPECT_STREQ(check_tunables(t).message, "must be positive");
  t = {good.body, good.limits, good.p_sensor_com_m};
  t.limits.force_deadband_N = t.limits.max_contact_force_N + 1.0;
  EXPECT_STREQ(check_tunables(t).setting, "limits.force_deadband_N");
  EXPECT_FALSE(check_tunables(t).ok());
}

TEST(Cycle, IdleAnswersEveryMessageWithItsIpocAndNoCorrectionAndSeesNoContact) {
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
  StaticRobot rig;
  for (int i = 0; i < 20; ++i) {
    const std::uint64_t ipoc = rig.message.ipoc;
    const RsiReply r = rig.quiet(c);
    EXPECT_EQ(r.ipoc, ipoc);
    EXPECT_FALSE(r.axis);
    EXPECT_EQ(r.rkorr.x_mm, 0.0);
    EXPECT_EQ(r.rkorr.c_deg, 0.0);
  }
  EXPECT_EQ(c.state_machine().state(), State::idle);
  // With the true model the contact is zero (to rounding) once the rows are there.
  for (int k = 0; k < 6; ++k) EXPECT_NEAR(c.last().contact[k], 0.0, 1e-9);
  EXPECT_EQ(c.last().flags & kNotReady, 0u);
}

// The payload model with a temperature_bias of 2 N/K on Fx (none on the other axes).
infer::DeployedModel temperature_model() {
  infer::DeployedModel model = payload_model();
  model.physics.effects.add(model::Effect::temperature_bias);
  double* per_kelvin = model.physics.block(model::Effect::temperature_bias);
  for (int k = 0; k < 6; ++k) per_kelvin[k] = k == 0 ? 2.0 : 0.0;
  return model;
}

// The model's temperature_bias gets the F/T sensor's own temperature (the NETCANOEM thermistor)
// once a sample brings one, held between readings; before that the configured temperature_C.
// Rig at 35 °C with a model of 2 N/K on Fx: with the configured 25 °C the contact would show
// 20 N; with the sensor's reading it is zero.
TEST(Cycle, TheSensorsTemperatureReachesTheModelAndTheRecord) {
  const infer::DeployedModel model = temperature_model();
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), model).text(), "");
  StaticRobot rig(model);  // its payload wrench is the model's at 25 °C
  Eigen::Matrix<double, 6, 1> warm = Eigen::Matrix<double, 6, 1>::Zero();
  warm[0] = 2.0 * (35.0 - 25.0);                    // what 35 °C adds to Fx
  for (int i = 0; i < 10; ++i) rig.cycle(c, warm);  // no temperature in the samples
  EXPECT_FALSE(c.last().temperature_measured);
  EXPECT_DOUBLE_EQ(c.last().temperature_C, test_cycle_config().temperature_C);
  EXPECT_NEAR(c.last().contact[0], 20.0, 1e-6);
  samples::FtSample s = rig.ft(warm);
  s.temperature_valid = true;
  s.temperature_C = 35.0;
  s.temperature_age_s = 0.25;
  c.add_ft(s);  // one sample with the reading; the others of later cycles carry none
  for (int i = 0; i < 10; ++i) rig.cycle(c, warm);
  EXPECT_TRUE(c.last().temperature_measured);
  EXPECT_DOUBLE_EQ(c.last().temperature_C, 35.0);
  EXPECT_DOUBLE_EQ(c.last().temperature_age_s, 0.25);
  EXPECT_NEAR(c.last().contact[0], 0.0, 1e-6);
}

// A reading the sensor reports stale (older than its maximum age: the board stopped answering
// the thermistor reads) is not held any longer: the model gets the configured temperature_C
// again, every such cycle is flagged kTemperatureStale and counted, and the next fresh reading
// ends it. Same rig as above: the fallback shows as the 20 N the configured 25 °C leaves.
TEST(Cycle, AStaleTemperatureFallsBackToTheConfiguredOneFlaggedAndCounted) {
  const infer::DeployedModel model = temperature_model();
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), model).text(), "");
  StaticRobot rig(model);
  Eigen::Matrix<double, 6, 1> warm = Eigen::Matrix<double, 6, 1>::Zero();
  warm[0] = 2.0 * (35.0 - 25.0);
  samples::FtSample fresh = rig.ft(warm);
  fresh.temperature_valid = true;
  fresh.temperature_C = 35.0;
  samples::FtSample stale = rig.ft(warm);
  stale.temperature_stale = true;  // temperature_valid false, as the sensor reports it
  c.add_ft(fresh);
  for (int i = 0; i < 10; ++i) rig.cycle(c, warm);
  ASSERT_TRUE(c.last().temperature_measured);
  EXPECT_EQ(c.last().flags & kTemperatureStale, 0u);
  EXPECT_NEAR(c.last().contact[0], 0.0, 1e-6);
  EXPECT_EQ(c.counters().temperature_stale_cycles, 0u);

  c.add_ft(stale);
  rig.cycle(c, warm);
  EXPECT_FALSE(c.last().temperature_measured);
  EXPECT_DOUBLE_EQ(c.last().temperature_C, test_cycle_config().temperature_C);
  EXPECT_NE(c.last().flags & kTemperatureStale, 0u);
  // Cycles whose samples say nothing about the temperature keep it stale (not the old reading).
  for (int i = 0; i < 9; ++i) rig.cycle(c, warm);
  EXPECT_FALSE(c.last().temperature_measured);
  EXPECT_NE(c.last().flags & kTemperatureStale, 0u);
  EXPECT_NEAR(c.last().contact[0], 20.0, 1e-6);  // the model's row has the configured 25 °C
  EXPECT_EQ(c.counters().temperature_stale_cycles, 10u);
  EXPECT_EQ(c.state_machine().state(), State::idle);  // not a fault
  EXPECT_EQ(c.last().flags & kNotReady, 0u);

  // A stale sample and a fresh one in the same cycle: the latest wins.
  c.add_ft(stale);
  c.add_ft(fresh);
  for (int i = 0; i < 10; ++i) rig.cycle(c, warm);
  EXPECT_TRUE(c.last().temperature_measured);
  EXPECT_DOUBLE_EQ(c.last().temperature_C, 35.0);
  EXPECT_EQ(c.last().flags & kTemperatureStale, 0u);
  EXPECT_NEAR(c.last().contact[0], 0.0, 1e-6);
  EXPECT_EQ(c.counters().temperature_stale_cycles, 10u);
}

TEST(Cycle, SensorsThatHaveNotStartedYetMeanNotReadyNotAFault) {
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
  StaticRobot rig;
  // The robot's datagrams come before the sensors' first samples (start-up order).
  for (int i = 0; i < 20; ++i) rig.quiet(c, 0, 0);
  EXPECT_EQ(c.state_machine().state(), State::idle);
  EXPECT_NE(c.last().flags & kNotReady, 0u);
  ASSERT_TRUE(c.request(Command::enable_zero_g));
  rig.quiet(c, 0, 0);
  EXPECT_EQ(c.state_machine().state(), State::idle);  // refused
  // Once they have started, the watchdogs count.
  for (int i = 0; i < 6; ++i) rig.quiet(c);
  for (int i = 0; i < c.config().watchdog.imu_fault_cycles; ++i) rig.quiet(c, 4, 0);
  EXPECT_EQ(c.state_machine().fault(), Fault::imu_stale);
}

TEST(Cycle, EnableIsRefusedUntilTheModelHasItsRows) {
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
  StaticRobot rig;
  rig.quiet(c);
  ASSERT_TRUE(c.request(Command::enable_zero_g));
  rig.quiet(c);  // two rows: the 5-point stencil needs five
  EXPECT_EQ(c.state_machine().state(), State::idle);
  EXPECT_NE(c.last().flags & kCommandRefused, 0u);
  EXPECT_EQ(c.counters().commands_refused, 1u);
  for (int i = 0; i < 3; ++i) rig.quiet(c);
  ASSERT_TRUE(c.request(Command::enable_zero_g));
  rig.quiet(c);
  EXPECT_EQ(c.state_machine().state(), State::zero_g);
}

// Each command's own outcome, under its ticket (the Modbus server answers a coil write with it).
TEST(Cycle, EveryCommandHasATicketAndItsOwnOutcome) {
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
  StaticRobot rig;
  rig.quiet(c);
  const std::uint64_t early = c.request(Command::enable_zero_g);
  ASSERT_NE(early, 0u);
  EXPECT_EQ(c.request(Command::stop), 0u) << "one pending at a time";
  EXPECT_EQ(c.command_outcome(early), CommandOutcome::pending);
  rig.quiet(c);  // two rows: not ready
  EXPECT_EQ(c.command_outcome(early), CommandOutcome::refused);
  for (int i = 0; i < 4; ++i) rig.quiet(c);
  const std::uint64_t enable = c.request(Command::enable_zero_g);
  ASSERT_GT(enable, early);
  rig.quiet(c);
  EXPECT_EQ(c.command_outcome(enable), CommandOutcome::accepted);
  EXPECT_EQ(c.state_machine().state(), State::zero_g);
  EXPECT_EQ(c.command_outcome(early), CommandOutcome::refused) << "kept";
  // A stale-IPOC message does not apply it (nor decide it): still pending.
  const std::uint64_t stop = c.request(Command::stop);
  rig.message.ipoc -= 24;
  rig.quiet(c);
  EXPECT_EQ(c.command_outcome(stop), CommandOutcome::pending);
  rig.message.ipoc += 24;
  rig.quiet(c);
  EXPECT_EQ(c.command_outcome(stop), CommandOutcome::accepted);
  // Outcomes older than the last kCommandOutcomes are no longer known.
  for (std::size_t i = 0; i < Cycle::kCommandOutcomes; ++i) {
    ASSERT_NE(c.request(Command::reset_fault), 0u);
    rig.quiet(c);
  }
  EXPECT_EQ(c.command_outcome(early), CommandOutcome::unknown);
}

TEST(Cycle, PushOfImpulseJGivesVelocityJOverMAndTheCorrectionsAddUpToTheMotion) {
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
  StaticRobot rig;
  start_zero_g(c, rig);
  const Eigen::Vector3d p0 = c.motion().sensor_position_world();
  // 50 N along sensor x for 40 cycles; the contact gate keeps the whole impulse.
  const int n_push = 40;
  Eigen::Vector3d sum_mm = Eigen::Vector3d::Zero();
  for (int i = 0; i < n_push; ++i) {
    const RsiReply r = rig.cycle(c, push(50.0, 0.0, 0.0));
    sum_mm += Eigen::Vector3d(r.rkorr.x_mm, r.rkorr.y_mm, r.rkorr.z_mm);
  }
  for (int i = 0; i < 30; ++i) {
    const RsiReply r = rig.quiet(c);
    sum_mm += Eigen::Vector3d(r.rkorr.x_mm, r.rkorr.y_mm, r.rkorr.z_mm);
  }
  ASSERT_EQ(c.state_machine().state(), State::zero_g);
  const Eigen::Vector3d J_world = rig.R * Eigen::Vector3d(50.0 * n_push * kPeriod, 0, 0);
  const Eigen::Vector3d v = c.motion().body().state().v_world_mps;
  EXPECT_NEAR((v - J_world / kMass).norm(), 0.0, 1e-9 * J_world.norm());
  // The robot was told to move exactly as the virtual sensor pose moved (RSI: 0.1 µm steps).
  const Eigen::Vector3d moved_mm = (c.motion().sensor_position_world() - p0) * 1000.0;
  EXPECT_NEAR((sum_mm - moved_mm).norm(), 0.0, 70 * 0.5e-4 * std::sqrt(3.0));
  EXPECT_GT(moved_mm.norm(), 10.0);
}

TEST(Cycle, AnOffCentrePushTurnsTheBodyAndTheCorrectionCarriesTheRotation) {
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
  StaticRobot rig;
  start_zero_g(c, rig);
  // A pure torque of 5 N·m about sensor z for 20 cycles (the gate's release of three cycles'
  // impulse stays below the angular acceleration limit).
  Eigen::Matrix<double, 6, 1> torque = Eigen::Matrix<double, 6, 1>::Zero();
  torque[5] = 5.0;
  double c_sum = 0.0, a_sum = 0.0, b_sum = 0.0;
  for (int i = 0; i < 20; ++i) {
    const RsiReply r = rig.cycle(c, torque);
    a_sum += r.rkorr.a_deg;
    b_sum += r.rkorr.b_deg;
    c_sum += r.rkorr.c_deg;
  }
  const Eigen::Vector3d L = c.motion().body().state().L_world_kgm2ps;
  // Angular impulse about the virtual centre of mass, in world: the 18 cycles that reached the
  // model row (two rows late), all of it kept by the contact gate.
  const Eigen::Vector3d expected = rig.R * Eigen::Vector3d(0, 0, 5.0 * 18 * kPeriod);
  EXPECT_NEAR((L - expected).norm(), 0.0, 1e-9 * expected.norm());
  EXPECT_GT(std::abs(a_sum) + std::abs(b_sum) + std::abs(c_sum), 0.1);
}

TEST(Cycle, TunablesProposedInIdleAreTakenByTheNextCycle) {
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
  StaticRobot rig;
  for (int i = 0; i < 6; ++i) rig.quiet(c);
  Tunables t = c.tunables();
  EXPECT_EQ(t.body.mass_kg, kMass);
  t.body.mass_kg = 60.0;
  t.limits.linear_damping_per_s = 0.5;
  ASSERT_TRUE(c.propose(t));
  EXPECT_EQ(c.proposal_status(), ProposalStatus::pending);
  EXPECT_FALSE(c.propose(t)) << "one proposal at a time";
  rig.quiet(c);
  EXPECT_EQ(c.proposal_status(), ProposalStatus::accepted);
  EXPECT_EQ(c.tunables().body.mass_kg, 60.0);
  EXPECT_EQ(c.motion().body().params().mass_kg, 60.0);
  // A lost robot cycle (receive timeout) also takes a proposal: no robot, no wait.
  t.body.mass_kg = 70.0;
  ASSERT_TRUE(c.propose(t));
  c.robot_lost(RobotLoss::timeout);
  EXPECT_EQ(c.proposal_status(), ProposalStatus::accepted);
  EXPECT_EQ(c.tunables().body.mass_kg, 70.0);
  // Inconsistent values are refused whole.
  t.body.mass_kg = 80.0;
  t.body.inertia_body_kgm2(0, 1) = 1.0;  // not symmetric
  ASSERT_TRUE(c.propose(t));
  rig.quiet(c);
  EXPECT_EQ(c.proposal_status(), ProposalStatus::refused_invalid);
  EXPECT_EQ(c.tunables().body.mass_kg, 70.0);
  // Withdrawn before the cycle took it: nothing happens.
  t = c.tunables();
  t.body.mass_kg = 90.0;
  ASSERT_TRUE(c.propose(t));
  EXPECT_TRUE(c.withdraw_proposal());
  EXPECT_FALSE(c.withdraw_proposal());
  EXPECT_EQ(c.proposal_status(), ProposalStatus::none);
  rig.quiet(c);
  EXPECT_EQ(c.tunables().body.mass_kg, 70.0);
}

TEST(Cycle, TunablesAreRefusedOutsideIdleAndTheRunningBodyKeepsItsMass) {
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
  StaticRobot rig;
  start_zero_g(c, rig);
  Tunables t = c.tunables();
  t.body.mass_kg = 50.0;
  ASSERT_TRUE(c.propose(t));
  AllocGuard guard("Cycle::step refusing a proposal");
  rig.cycle(c, push(30.0, 0.0, 0.0));
  guard.stop();
  EXPECT_EQ(guard.allocations(), 0u) << guard.first_call();
  EXPECT_EQ(guard.frees(), 0u) << guard.first_call();
  EXPECT_EQ(c.proposal_status(), ProposalStatus::refused_state);
  EXPECT_EQ(c.tunables().body.mass_kg, kMass);
  EXPECT_EQ(c.motion().body().params().mass_kg, kMass);
  EXPECT_EQ(c.state_machine().state(), State::zero_g);
}

TEST(Cycle, ProposalsFromAnotherThreadAreEachDecidedOnce) {
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
  StaticRobot rig;
  for (int i = 0; i < 6; ++i) rig.quiet(c);
  std::atomic<bool> done{false};
  int accepted = 0, withdrawn = 0;
  const Tunables start = c.tunables();  // the proposer never reads the cycle's own copy
  std::thread proposer([&] {
    for (int i = 0; i < 2000; ++i) {
      Tunables t = start;
      t.body.mass_kg = 50.0 + (i % 100);
      while (!c.propose(t)) std::this_thread::yield();
      if (i % 3 == 0 && c.withdraw_proposal()) {
        ++withdrawn;
        continue;
      }
      ProposalStatus s;
      while ((s = c.proposal_status()) == ProposalStatus::pending) std::this_thread::yield();
      if (s == ProposalStatus::accepted) ++accepted;
    }
    done = true;
  });
  while (!done) {
    rig.quiet(c);
    const double m = c.motion().body().params().mass_kg;
    ASSERT_TRUE(m == kMass || (m >= 50.0 && m < 150.0)) << m;
  }
  proposer.join();
  EXPECT_EQ(accepted + withdrawn, 2000);
  EXPECT_GT(accepted, 0);
}

TEST(Cycle, StepDoesNotAllocate) {
  Cycle c;
  CycleConfig config = test_cycle_config();
  config.tare_s = 0.3;  // the tare restarted by a hand, then taken, inside the guard
  ASSERT_EQ(c.configure(config, payload_model()).text(), "");
  StaticRobot rig;
  start_zero_g(c, rig);
  AllocGuard guard("Cycle::step");
  for (int i = 0; i < 200; ++i) {
    const bool pushed = i < 6 || (i >= 50 && i < 100);  // a hand while taring; then a push
    rig.cycle(c, push(pushed ? 30.0 : 0.0, pushed ? 5.0 : 0.0, 0.0));
  }
  const std::uint32_t taring = c.last().flags & kContactTaring;
  const double speed = c.motion().body().state().v_world_mps.norm();
  for (int i = 0; i < 10; ++i) rig.cycle(c, push(0, 0, 0), 0, 24);  // hold, then fault
  c.robot_lost(RobotLoss::timeout);
  guard.stop();
  EXPECT_EQ(guard.allocations(), 0u) << guard.first_call();
  EXPECT_EQ(guard.frees(), 0u) << guard.first_call();
  EXPECT_EQ(c.state_machine().fault(), Fault::ft_stale);
  EXPECT_EQ(taring, 0u) << "the tare was taken";
  EXPECT_GT(speed, 0.0) << "and the push moved the body";
}

// Issue 15 acceptance: the allocator-level guard passes on the real cycle (in abort mode, so the
// first allocation or free would end the test with its stack) and catches a deliberate
// std::vector push, a malloc and an Eigen dynamic allocation made inside the same cycle scope.
TEST(Cycle, TheAllocationGuardPassesTheRealCycleAndCatchesADeliberatePushInIt) {
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
  StaticRobot rig;
  start_zero_g(c, rig);
  {
    AllocGuard guard("Cycle::step (real cycle)", AllocGuard::Mode::abort);
    for (int i = 0; i < 100; ++i) rig.cycle(c, push(i < 50 ? 30.0 : 0.0, 5.0, 0.0));
  }
  std::vector<double> trace;  // what a careless cycle might keep
  AllocGuard push_guard("Cycle::step + std::vector push");
  for (int i = 0; i < 10; ++i) {
    rig.cycle(c, push(10.0, 0.0, 0.0));
    trace.push_back(c.motion().body().params().mass_kg);
  }
  push_guard.stop();
  EXPECT_GT(push_guard.allocations(), 0u);
  EXPECT_EQ(trace.size(), 10u);

  AllocGuard malloc_guard("Cycle::step + malloc");
  rig.cycle(c, push(10.0, 0.0, 0.0));
  void* volatile scratch = std::malloc(64);
  malloc_guard.stop();
  std::free(scratch);
  EXPECT_EQ(malloc_guard.allocations(), 1u);

  Eigen::VectorXd residuals;  // a dynamic Eigen vector sized in the cycle
  AllocGuard eigen_guard("Cycle::step + Eigen::VectorXd");
  rig.cycle(c, push(10.0, 0.0, 0.0));
  Eigen::internal::set_is_malloc_allowed(true);  // NDEBUG compiles Eigen's check out: the hooks
  residuals.setZero(12);                         // alone must see it
  eigen_guard.stop();
  EXPECT_EQ(eigen_guard.allocations(), 1u);
}

TEST(CycleDeathTest, AnAbortModeGuardStopsADeliberatePushInsideTheCycle) {
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
  StaticRobot rig;
  start_zero_g(c, rig);
  std::vector<double> trace;
  EXPECT_DEATH(
      {
        AllocGuard guard("Cycle::step + std::vector push", AllocGuard::Mode::abort);
        rig.cycle(c, push(10.0, 0.0, 0.0));
        trace.push_back(c.motion().body().params().mass_kg);
      },
      "inside the scope 'Cycle::step \\+ std::vector push', which must not allocate");
}

// A held sensor value is stale next to fresh ones: the rows that held it drive nothing (zero
// contact, kContactHeld, the body coasts), D cycles later when the model reaches them. Before
// this rule a held 30 N push went on pushing the body for every held cycle.
TEST(Cycle, RowsWithAHeldSensorValueDoNotDriveTheBody) {
  for (const bool hold_ft : {true, false}) {
    SCOPED_TRACE(hold_ft ? "F/T held" : "IMU held");
    Cycle c;
    ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
    StaticRobot rig;
    start_zero_g(c, rig);
    const int D = c.delay_rows();
    const int n_push = 20, n_held = 3;
    int contact_held = 0, pushed = 0;
    auto tally = [&] {
      if ((c.last().flags & kContactHeld) != 0) {
        ++contact_held;
        for (int k = 0; k < 6; ++k) EXPECT_EQ(c.last().contact[k], 0.0);
      } else if (c.last().contact[0] > 1.0) {
        ++pushed;
      }
    };
    for (int i = 0; i < n_push; ++i) {
      const bool held = i >= 8 && i < 8 + n_held;  // three cycles without a sample, mid-push
      rig.cycle(c, push(30.0, 0.0, 0.0), held && hold_ft ? 0 : 4, held && !hold_ft ? 0 : 24);
      EXPECT_EQ((c.last().flags & (kFtHeld | kImuHeld)) != 0, held) << "cycle " << i;
      tally();
    }
    for (int i = 0; i < 10; ++i) {
      rig.quiet(c);
      tally();
    }
    ASSERT_EQ(c.state_machine().state(), State::zero_g);
    EXPECT_EQ(contact_held, n_held);
    EXPECT_EQ(pushed, n_push - n_held);
    // The impulse is that of the cycles with fresh samples only.
    const Eigen::Vector3d J_world =
        rig.R * Eigen::Vector3d(30.0 * (n_push - n_held) * kPeriod, 0, 0);
    const Eigen::Vector3d v = c.motion().body().state().v_world_mps;
    EXPECT_NEAR((v - J_world / kMass).norm(), 0.0, 1e-9 * J_world.norm()) << "D = " << D;
  }
}

// Watchdogs: consecutive bad cycles below the threshold hold; the threshold raises the fault and
// from that very cycle on the reply is a zero correction.
void expect_hold_then_fault(Cycle& c, StaticRobot& rig, int threshold, Fault fault,
                            const std::function<RsiReply()>& bad_cycle, std::uint32_t held_flag) {
  for (int i = 1; i < threshold; ++i) {
    const RsiReply r = bad_cycle();
    EXPECT_EQ(c.state_machine().state(), State::zero_g) << "cycle " << i;
    EXPECT_NE(c.last().flags & held_flag, 0u) << "cycle " << i;
    (void)r;
  }
  const std::uint64_t ipoc = rig.message.ipoc;
  const RsiReply r = bad_cycle();
  EXPECT_EQ(c.state_machine().state(), State::fault);
  EXPECT_EQ(c.state_machine().fault(), fault);
  EXPECT_EQ(r.ipoc, ipoc);
  EXPECT_EQ(r.rkorr.x_mm, 0.0);
  EXPECT_EQ(r.rkorr.y_mm, 0.0);
  EXPECT_EQ(r.rkorr.a_deg, 0.0);
  // The black box holds the cycles up to the fault, the fault cycle last, and stays frozen.
  ASSERT_TRUE(c.black_box().frozen());
  EXPECT_EQ(c.black_box().at(c.black_box().size() - 1).fault, fault);
  for (int i = 0; i < 5; ++i) {
    const RsiReply later = rig.cycle(c, push(40.0, 0.0, 0.0));
    EXPECT_EQ(later.rkorr.x_mm, 0.0);
  }
  EXPECT_EQ(c.black_box().at(c.black_box().size() - 1).fault, fault);
}

class Watchdog : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
    start_zero_g(c, rig);
    // Moving, so that a zero correction is a real change.
    for (int i = 0; i < 10; ++i) rig.cycle(c, push(30.0, 0.0, 0.0));
    ASSERT_NE(rig.quiet(c).rkorr.x_mm, 0.0);
  }
  Cycle c;
  StaticRobot rig;
};

TEST_F(Watchdog, SilentFtSensorHoldsThenFaults) {
  expect_hold_then_fault(
      c, rig, c.config().watchdog.ft_fault_cycles, Fault::ft_stale,
      [&] { return rig.quiet(c, 0, 24); }, kFtHeld);
}

TEST_F(Watchdog, TheMeasuredComputeTimeReachesTheFrozenBlackBoxForTheFaultCycleOnly) {
  for (int i = 0; i < c.config().watchdog.ft_fault_cycles; ++i) {
    rig.quiet(c, 0, 24);
    c.set_compute_ns(1000 + i);
  }
  ASSERT_TRUE(c.black_box().frozen());
  const std::size_t n = c.black_box().size();
  EXPECT_EQ(c.black_box().at(n - 1).compute_ns, 1000 + c.config().watchdog.ft_fault_cycles - 1);
  EXPECT_EQ(c.black_box().at(n - 2).compute_ns, 1000 + c.config().watchdog.ft_fault_cycles - 2);
  rig.quiet(c);
  c.set_compute_ns(5);  // a later cycle: not in the frozen box
  EXPECT_EQ(c.black_box().at(n - 1).compute_ns, 1000 + c.config().watchdog.ft_fault_cycles - 1);
  EXPECT_EQ(c.last().compute_ns, 5);
}

TEST_F(Watchdog, CriticalStatusHoldsThenFaultsNamingIt) {
  expect_hold_then_fault(
      c, rig, c.config().watchdog.ft_fault_cycles, Fault::ft_critical,
      [&] {
        samples::FtSample bad;
        bad.status = samples::FtSampleStatus::critical;
        bad.valid = false;
        c.add_ft(bad);
        return rig.quiet(c, 0, 24);
      },
      kFtHeld);
}

TEST_F(Watchdog, SaturatedGaugesHoldThenFault) {
  expect_hold_then_fault(
      c, rig, c.config().watchdog.ft_fault_cycles, Fault::ft_saturated,
      [&] {
        samples::FtSample bad;
        bad.status = samples::FtSampleStatus::saturated;
        c.add_ft(bad);
        return rig.quiet(c, 0, 24);
      },
      kFtHeld);
}

TEST_F(Watchdog, GarbledImuHoldsThenFaults) {
  expect_hold_then_fault(
      c, rig, c.config().watchdog.imu_fault_cycles, Fault::imu_stale,
      [&] {
        samples::ImuSample bad;  // status bytes set: groups invalid
        c.add_imu(bad);
        return rig.quiet(c, 4, 0);
      },
      kImuHeld);
}

TEST_F(Watchdog, LostRobotCyclesFaultAtTheThresholdAndTheNextMessageGetsZero) {
  const int n = c.config().watchdog.robot_fault_cycles;
  for (int i = 1; i < n; ++i) {
    c.robot_lost(i % 2 ? RobotLoss::timeout : RobotLoss::malformed);
    EXPECT_EQ(c.state_machine().state(), State::zero_g);
  }
  c.robot_lost(RobotLoss::malformed);
  EXPECT_EQ(c.state_machine().fault(), Fault::robot_late);
  EXPECT_TRUE(c.black_box().frozen());
  const CycleRecord& last = c.black_box().at(c.black_box().size() - 1);
  EXPECT_EQ(last.fault, Fault::robot_late);
  EXPECT_NE(last.flags & kRobotLost, 0u);
  rig.message.ipoc += 12 * n;
  const std::uint64_t ipoc = rig.message.ipoc;
  const RsiReply r = rig.quiet(c);
  EXPECT_EQ(r.ipoc, ipoc);
  EXPECT_EQ(r.rkorr.x_mm, 0.0);
  EXPECT_EQ(c.counters().robot_timeouts + c.counters().robot_malformed,
            static_cast<std::uint64_t>(n));
}

TEST_F(Watchdog, WhileTheBoxIsFrozenLastIsTheLatestCycleAndTheBoxDoesNotChange) {
  for (int i = 0; i < c.config().watchdog.ft_fault_cycles; ++i) rig.quiet(c, 0, 24);
  ASSERT_TRUE(c.black_box().frozen());
  const Cycle::Box& box = c.black_box();
  const std::size_t n = box.size();
  std::vector<std::array<std::uint64_t, 3>> kept;
  for (std::size_t i = 0; i < n; ++i)
    kept.push_back({box.at(i).cycle, box.at(i).flags, box.at(i).ipoc});
  const std::uint64_t fault_cycle = box.at(n - 1).cycle;
  EXPECT_EQ(c.last().cycle, fault_cycle);
  // Full, lost and stale cycles after the fault: each is last(), none reaches the box.
  rig.quiet(c);
  EXPECT_EQ(c.last().cycle, fault_cycle + 1);
  EXPECT_EQ(c.last().state, State::fault);
  const double t_s = c.last().t_s;
  c.robot_lost(RobotLoss::timeout);
  EXPECT_EQ(c.last().cycle, fault_cycle + 1);
  EXPECT_EQ(c.last().flags, kRobotLost);
  EXPECT_EQ(c.last().t_s, t_s) << "a lost cycle keeps the last record's row";
  rig.message.ipoc -= 24;  // an older datagram
  rig.quiet(c);
  rig.message.ipoc += 12;  // back to the next one
  EXPECT_EQ(c.last().cycle, fault_cycle + 2);
  EXPECT_EQ(c.last().flags, kIpocStale);
  EXPECT_EQ(c.last().t_s, t_s);
  c.set_compute_ns(77);
  EXPECT_EQ(c.last().compute_ns, 77);
  ASSERT_EQ(box.size(), n);
  for (std::size_t i = 0; i < n; ++i) {
    EXPECT_EQ((std::array<std::uint64_t, 3>{box.at(i).cycle, box.at(i).flags, box.at(i).ipoc}),
              kept[i])
        << i;
  }
  // Released: the next cycles are kept again, a lost one after the full one it repeats.
  c.release_black_box();
  rig.quiet(c);
  EXPECT_EQ(box.at(box.size() - 1).cycle, c.last().cycle);
  EXPECT_EQ(&box.at(box.size() - 1), &c.last());
  const std::uint32_t full_flags = c.last().flags;
  c.robot_lost(RobotLoss::malformed);
  EXPECT_EQ(box.at(box.size() - 1).flags, kRobotLost);
  EXPECT_EQ(box.at(box.size() - 2).flags, full_flags);
  EXPECT_EQ(box.at(box.size() - 2).cycle, box.at(box.size() - 1).cycle);
  EXPECT_EQ(box.at(box.size() - 2).t_s, box.at(box.size() - 1).t_s);
}

TEST_F(Watchdog, AnIpocGapBelowTheThresholdIsCountedAndStepsTheBodyByTheElapsedTime) {
  rig.message.ipoc += 12;  // one datagram lost
  rig.quiet(c);
  EXPECT_EQ(c.state_machine().state(), State::zero_g);
  EXPECT_NE(c.last().flags & kIpocGap, 0u);
  EXPECT_DOUBLE_EQ(c.last().dt_s, 2 * kPeriod);
  EXPECT_EQ(c.counters().datagrams_lost, 1u);
  rig.message.ipoc += 12 * c.config().watchdog.robot_fault_cycles;
  rig.quiet(c);
  EXPECT_EQ(c.state_machine().fault(), Fault::robot_late);
}

TEST_F(Watchdog, GrowingRobotDelayMeansOurRepliesAreLateAndFaults) {
  for (int i = 1; i < c.config().watchdog.robot_late_cycles; ++i) {
    ++rig.message.delay;
    rig.quiet(c);
    EXPECT_EQ(c.state_machine().state(), State::zero_g);
    EXPECT_NE(c.last().flags & kRobotDelayGrew, 0u);
  }
  ++rig.message.delay;
  EXPECT_EQ(rig.quiet(c).rkorr.x_mm, 0.0);
  EXPECT_EQ(c.state_machine().fault(), Fault::robot_late);
}

TEST_F(Watchdog, DuplicateAndReorderedDatagramsAreAnsweredWithZeroAndChangeNothing) {
  rig.message.ipoc -= 12;  // the previous datagram again
  const Eigen::Vector3d v = c.motion().body().state().v_world_mps;
  const RsiReply r = rig.quiet(c);
  EXPECT_EQ(r.ipoc, rig.message.ipoc - 12);
  EXPECT_EQ(r.rkorr.x_mm, 0.0);
  EXPECT_NE(c.last().flags & kIpocStale, 0u);
  EXPECT_EQ(c.counters().ipoc_stale, 1u);
  EXPECT_EQ(c.motion().body().state().v_world_mps, v);
  EXPECT_NE(rig.quiet(c).rkorr.x_mm, 0.0);  // the next new one moves again
  EXPECT_EQ(c.state_machine().state(), State::zero_g);
}

TEST_F(Watchdog, ContactAboveTheLimitFaultsAtOnce) {
  const RsiReply r = rig.cycle(c, push(0.0, 500.0, 0.0));
  (void)r;
  // The contact is evaluated two rows back: the fault comes when the push reaches that row.
  rig.cycle(c, push(0.0, 500.0, 0.0));
  const RsiReply r3 = rig.cycle(c, push(0.0, 500.0, 0.0));
  EXPECT_EQ(c.state_machine().fault(), Fault::contact_over_limit);
  EXPECT_EQ(r3.rkorr.x_mm, 0.0);
}

TEST_F(Watchdog, ResetReturnsToIdleOnlyFromFault) {
  ASSERT_TRUE(c.request(Command::reset_fault));
  rig.quiet(c);
  EXPECT_NE(c.last().flags & kCommandRefused, 0u);
  for (int i = 0; i < c.config().watchdog.ft_fault_cycles; ++i) rig.quiet(c, 0, 24);
  ASSERT_EQ(c.state_machine().state(), State::fault);
  ASSERT_TRUE(c.request(Command::reset_fault));
  rig.quiet(c);
  EXPECT_EQ(c.state_machine().state(), State::idle);
}

TEST_F(Watchdog, AFaultBeforeTheLastBoxWasReleasedIsCountedAsALostBlackBox) {
  for (int i = 0; i < c.config().watchdog.ft_fault_cycles; ++i) rig.quiet(c, 0, 24);
  ASSERT_EQ(c.state_machine().fault(), Fault::ft_stale);
  ASSERT_TRUE(c.black_box().frozen());
  const std::uint64_t frozen_at = c.black_box().total_pushed();
  // Reset without the program having dumped and released the box, then a second fault.
  ASSERT_TRUE(c.request(Command::reset_fault));
  rig.quiet(c);
  ASSERT_EQ(c.state_machine().state(), State::idle);
  for (int i = 0; i < c.config().watchdog.ft_fault_cycles; ++i) rig.quiet(c, 0, 24);
  ASSERT_EQ(c.state_machine().state(), State::fault);
  EXPECT_EQ(c.counters().black_boxes_lost, 1u);
  EXPECT_EQ(c.black_box().total_pushed(), frozen_at) << "the first fault's box is kept";
  // Released in time, the next fault is kept again.
  c.release_black_box();
  ASSERT_TRUE(c.request(Command::reset_fault));
  rig.quiet(c);
  for (int i = 0; i < c.config().watchdog.ft_fault_cycles; ++i) rig.quiet(c, 0, 24);
  EXPECT_TRUE(c.black_box().frozen());
  EXPECT_EQ(c.counters().black_boxes_lost, 1u);
}

class RampPath final : public JointPath {
 public:
  RampPath(std::array<double, 6> start, double delta, double duration)
      : start_(start), delta_(delta), duration_(duration) {}
  double duration_s() const override { return duration_; }
  std::array<double, 6> at(double t) const override {
    std::array<double, 6> q = start_;
    q[0] += delta_ * std::clamp(t / duration_, 0.0, 1.0);
    return q;
  }

 private:
  std::array<double, 6> start_;
  double delta_, duration_;
};

TEST(Cycle, CollectionApproachesThePathThenFollowsItWithAxisCorrectionsAndStops) {
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
  StaticRobot rig;
  const std::array<double, 6> now = proto::rsi::joints_to_rad(rig.message.joints_deg);
  std::array<double, 6> start = now;
  start[1] += 0.05;  // the path starts 0.05 rad away on A2
  RampPath path(start, 0.2, 2.0);
  ASSERT_TRUE(c.request(Command::start_collection));
  rig.quiet(c);
  EXPECT_NE(c.last().flags & kCommandRefused, 0u);  // no path yet
  c.set_collection_path(&path);
  ASSERT_TRUE(c.request(Command::start_collection));
  std::array<double, 6> sum_deg{};
  int cycles = 0;
  bool done = false;
  for (; cycles < 2000 && !done; ++cycles) {
    const RsiReply r = rig.quiet(c);
    if (c.state_machine().state() == State::collecting || (c.last().flags & kCollectionDone)) {
      EXPECT_TRUE(r.axis);
      for (int k = 0; k < 6; ++k) {
        sum_deg[k] += r.akorr_deg[k];
        EXPECT_LE(std::abs(r.akorr_deg[k]), c.config().max_axis_step_rad / proto::rsi::kRadPerDeg);
      }
    }
    done = (c.last().flags & kCollectionDone) != 0;
  }
  ASSERT_TRUE(done);
  EXPECT_EQ(c.state_machine().state(), State::idle);
  EXPECT_NEAR(sum_deg[0] * proto::rsi::kRadPerDeg, 0.2, 1e-9);
  EXPECT_NEAR(sum_deg[1] * proto::rsi::kRadPerDeg, 0.05, 1e-6);
  for (int k = 2; k < 6; ++k) EXPECT_NEAR(sum_deg[k], 0.0, 1e-12);
  // Approach of 0.05 rad at ≤ 0.2 rad/s and the 2 s path: a bit over 2.25 s in all.
  EXPECT_GT(cycles * kPeriod, 2.25);
  EXPECT_LT(cycles * kPeriod, 3.0);
}

// The controller's RSI context for a collection takes AKorr and nothing else
// (firmware/rt/deploy/kuka/zerog_rsi_collect_ethernet.xml): with a path set, every reply is AKorr,
// zeros when not collecting (before, after, in fault), and zero-g (RKorr) cannot be enabled.
TEST(Cycle, ASessionWithACollectionPathAnswersAxisCorrectionsOnly) {
  Cycle c;
  ASSERT_EQ(c.configure(test_cycle_config(), payload_model()).text(), "");
  StaticRobot rig;
  const std::array<double, 6> now = proto::rsi::joints_to_rad(rig.message.joints_deg);
  RampPath path(now, 0.01, 0.1);
  for (int i = 0; i < 6; ++i) EXPECT_FALSE(rig.quiet(c).axis);  // no path: RKorr zeros
  c.set_collection_path(&path);
  for (int i = 0; i < 3; ++i) {
    const RsiReply r = rig.quiet(c);
    EXPECT_TRUE(r.axis);
    for (double a : r.akorr_deg) EXPECT_EQ(a, 0.0);
  }
  ASSERT_TRUE(c.request(Command::enable_zero_g));
  EXPECT_TRUE(rig.quiet(c).axis);
  EXPECT_EQ(c.state_machine().state(), State::idle);
  EXPECT_NE(c.last().flags & kCommandRefused, 0u);
  ASSERT_TRUE(c.request(Command::start_collection));
  bool done = false;
  for (int i = 0; i < 500 && !done; ++i) {
    EXPECT_TRUE(rig.quiet(c).axis);
    done = (c.last().flags & kCollectionDone) != 0;
  }
  ASSERT_TRUE(done);
  const RsiReply after = rig.quiet(c);
  EXPECT_TRUE(after.axis);
  for (double a : after.akorr_deg) EXPECT_EQ(a, 0.0);
  // A fault's zero correction is AKorr too.
  for (int i = 0; i < c.config().watchdog.imu_fault_cycles + 1; ++i) rig.quiet(c, 4, 0);
  ASSERT_EQ(c.state_machine().state(), State::fault);
  const RsiReply faulted = rig.quiet(c, 4, 0);
  EXPECT_TRUE(faulted.axis);
  for (double a : faulted.akorr_deg) EXPECT_EQ(a, 0.0);
}

}  // namespace
}  // namespace zerog::loop
