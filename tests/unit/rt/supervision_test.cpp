// What zerog-rt tells its operators, apart from the cycle: StatusAnnouncer (the main thread's
// lines from the cycle's statuses, proto/rt_config.md, each said once; --enable-zero-g /
// --collect pending until their state or a fault) and SecondWindow (the supervisor's period,
// compute p99 and jitter per second, proto/modbus.md), on hand-made inputs.
#include <gtest/gtest.h>

#include "zerog/rt/runtime.hpp"

namespace zerog::rt {
namespace {

CycleStatus status(std::uint64_t cycle, loop::State state) {
  CycleStatus s;
  s.cycle = cycle;
  s.state = state;
  return s;
}

TEST(StatusAnnouncer, EnableZeroGIsAnnouncedOnceAtTheCycleOfItsTransition) {
  StatusAnnouncer a(/*auto_enable_zero_g=*/true, /*auto_collect=*/false);
  EXPECT_TRUE(a.auto_pending());
  SupervisorEvents ev = a.update(status(3, loop::State::idle));
  EXPECT_TRUE(ev.out.empty());
  EXPECT_TRUE(ev.err.empty());
  EXPECT_TRUE(a.auto_pending());

  CycleStatus s = status(9, loop::State::zero_g);
  s.transitions = 1;
  s.last_transition.cycle = 7;
  s.last_transition.from = loop::State::idle;
  s.last_transition.to = loop::State::zero_g;
  s.last_transition.command = loop::Command::enable_zero_g;
  ev = a.update(s);
  ASSERT_EQ(ev.out.size(), 1u);
  EXPECT_EQ(ev.out[0], "zerog-rt: zero-g enabled at cycle 7");
  ASSERT_EQ(ev.err.size(), 1u);
  EXPECT_NE(ev.err[0].find("cycle 7: idle -> zero_g"), std::string::npos) << ev.err[0];
  EXPECT_FALSE(a.auto_pending());
  // The same status again: nothing new.
  ev = a.update(s);
  EXPECT_TRUE(ev.out.empty());
  EXPECT_TRUE(ev.err.empty());
}

// In zero-g while no push is taken (the estimator settling, then the contact's tare): said
// once when seen, and once when it ends; leaving zero-g starts over.
TEST(StatusAnnouncer, HandsOffUntilThePartTakesPushes) {
  StatusAnnouncer a(false, false);
  CycleStatus s = status(10, loop::State::zero_g);
  s.flags = loop::kEstimatorSettling | loop::kContactTaring;
  SupervisorEvents ev = a.update(s);
  ASSERT_EQ(ev.out.size(), 1u);
  EXPECT_EQ(ev.out[0],
            "zerog-rt: zero-g: hands off the part, no push is taken yet (the motion estimator "
            "settling, then the contact's tare)");
  s.cycle = 80;
  s.flags = loop::kContactTaring;
  EXPECT_TRUE(a.update(s).out.empty()) << "said once";
  s.cycle = 210;
  s.flags = 0;
  ev = a.update(s);
  ASSERT_EQ(ev.out.size(), 1u);
  EXPECT_EQ(ev.out[0], "zerog-rt: zero-g: the part takes pushes from cycle 210");
  EXPECT_TRUE(a.update(s).out.empty());
  // Idle (the tare forgotten), zero-g again, straight into the tare.
  EXPECT_TRUE(a.update(status(300, loop::State::idle)).out.empty());
  s = status(302, loop::State::zero_g);
  s.flags = loop::kContactTaring;
  ev = a.update(s);
  ASSERT_EQ(ev.out.size(), 1u);
  EXPECT_NE(ev.out[0].find("(the contact's tare)"), std::string::npos) << ev.out[0];
  // The IMU's path: nothing to wait for, nothing said.
  StatusAnnouncer b(false, false);
  EXPECT_TRUE(b.update(status(10, loop::State::zero_g)).out.empty());
}

TEST(StatusAnnouncer, CollectGivesUpOnAFaultAndCountsMissedTransitions) {
  StatusAnnouncer a(false, true);
  CycleStatus s = status(20, loop::State::fault);
  s.fault = loop::Fault::ft_stale;
  s.transitions = 3;  // two were not seen: said, not listed
  s.last_transition.cycle = 20;
  s.last_transition.from = loop::State::idle;
  s.last_transition.to = loop::State::fault;
  s.last_transition.by_fault = true;
  s.last_transition.fault = loop::Fault::ft_stale;
  const SupervisorEvents ev = a.update(s);
  EXPECT_TRUE(ev.out.empty());
  ASSERT_EQ(ev.err.size(), 3u);
  EXPECT_EQ(ev.err[0], "zerog-rt: 2 more state transitions (in the summary)");
  EXPECT_NE(ev.err[2].find("--collect gave up: fault ft_stale"), std::string::npos) << ev.err[2];
  EXPECT_FALSE(a.auto_pending());
  EXPECT_FALSE(a.collection_finished());
}

TEST(StatusAnnouncer, RefusedCommandsAndFinishedCollectionsAreSaidOnce) {
  StatusAnnouncer a(false, true);
  CycleStatus s = status(40, loop::State::idle);
  s.commands_refused = 1;
  s.collections_done = 1;
  SupervisorEvents ev = a.update(s);
  ASSERT_EQ(ev.err.size(), 1u);
  EXPECT_EQ(ev.err[0], "zerog-rt: command refused in state idle (proto/states.md)");
  ASSERT_EQ(ev.out.size(), 1u);
  EXPECT_EQ(ev.out[0], "zerog-rt: collection finished at cycle 40");
  EXPECT_TRUE(a.collection_finished());
  ev = a.update(s);
  EXPECT_TRUE(ev.out.empty());
  EXPECT_TRUE(ev.err.empty());

  StatusAnnouncer plain(false, false);  // without --collect a finished path does not end the run
  EXPECT_FALSE(plain.auto_pending());
  ev = plain.update(s);
  EXPECT_EQ(ev.out.size(), 1u);
  EXPECT_FALSE(plain.collection_finished());
}

TEST(SecondWindow, PeriodEveryMessageP99AndJitterOncePerSecond) {
  SecondWindow w;
  constexpr std::int64_t kNominal = 4'000'000;  // 4 ms
  const std::int64_t t0 = 5'000'000'000;
  SecondWindow::Figures f = w.on_message(t0, kNominal, 0, false);  // first message: no period
  EXPECT_FALSE(f.has_period);
  EXPECT_FALSE(f.second_ended);
  // 250 messages 4 ms apart, one late by 1.5 ms; compute times 1..250 µs.
  std::int64_t t = t0;
  for (int i = 1; i <= 250; ++i) {
    t += kNominal + (i == 100 ? 1'500'000 : 0);
    f = w.on_message(t, kNominal, i * 1000, true);
    ASSERT_TRUE(f.has_period);
    EXPECT_EQ(f.period_ns, kNominal + (i == 100 ? 1'500'000 : 0));
    if (t - t0 < SecondWindow::kSecondNs) {
      EXPECT_FALSE(f.second_ended) << i;
    }
  }
  // t - t0 = 1.0015 s: the last message ended the second.
  ASSERT_TRUE(f.second_ended);
  ASSERT_TRUE(f.has_compute_p99);
  EXPECT_EQ(f.compute_p99_ns, 247'000);  // rank (250 - 1) * 99 / 100 = 246 of 1..250 µs
  EXPECT_EQ(f.jitter_max_ns, 1'500'000);
  // The next second starts afresh.
  t += kNominal;
  f = w.on_message(t, kNominal, 1000, false);
  EXPECT_FALSE(f.second_ended);
  t += SecondWindow::kSecondNs;
  f = w.on_message(t, kNominal, 0, false);
  ASSERT_TRUE(f.second_ended);
  EXPECT_FALSE(f.has_compute_p99);  // no compute time counted in it
  EXPECT_EQ(f.jitter_max_ns, SecondWindow::kSecondNs - kNominal);
}

}  // namespace
}  // namespace zerog::rt
