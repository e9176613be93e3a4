// The contact's tare (CycleConfig::tare_s, stages::tare_contact; proto/loop.md, "The tare"):
// through the cycle, on a robot standing still whose F/T samples are the model's payload plus
// a contact the test chooses.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <cmath>

#include "loop_fixtures.hpp"
#include "zerog/loop/cycle.hpp"

namespace zerog::loop {
namespace {

using test::kPeriod;
using test::payload_model;
using test::push;
using test::StaticRobot;
using test::test_cycle_config;
using Wrench6 = Eigen::Matrix<double, 6, 1>;

constexpr double kTareS = 0.5;
// Rows the tare sums: the first row whose summed time reaches tare_s.
const int kTareRows = static_cast<int>(std::ceil(kTareS / kPeriod - 0.5));

// A constant offset the model does not know (an accelerometer's turn-on bias × mass, the F/T
// sensor's zero since its calibration): below the gate, so only the tare sees it.
Wrench6 offset() {
  Wrench6 w;
  w << 0.3, -0.2, 0.1, 0.04, -0.05, 0.02;
  return w;
}

double contact_error(const Cycle& c, const Wrench6& expected) {
  double e = 0.0;
  for (int k = 0; k < 6; ++k) e = std::max(e, std::abs(c.last().contact[k] - expected[k]));
  return e;
}

// Zero-g entered with `contact` on every row from the start (so that the model's rows, D back,
// carry it too); the enabling row is the tare's first flagged one.
void start_zero_g_with(Cycle& c, StaticRobot& rig, const Wrench6& contact) {
  for (int i = 0; i < 6; ++i) rig.cycle(c, contact);
  ASSERT_TRUE(c.request(Command::enable_zero_g));
  rig.cycle(c, contact);
  ASSERT_EQ(c.state_machine().state(), State::zero_g);
}

CycleConfig tare_config(double tare_s = kTareS) {
  CycleConfig config = test_cycle_config();
  config.tare_s = tare_s;
  return config;
}

// The offset stands in the contact until tare_s of rows in zero-g are summed (each such row
// flagged kContactTaring, and a push then is not confirmed); from the next row the contact is
// zero, unflagged, and a push is confirmed as without a tare, its whole impulse passed.
TEST(Tare, AnOffsetAtRestIsTheContactsZeroAfterTareS) {
  Cycle c;
  ASSERT_EQ(c.configure(tare_config(), payload_model()).text(), "");
  StaticRobot rig;
  start_zero_g_with(c, rig, offset());
  ASSERT_NE(c.last().flags & kContactTaring, 0u) << "zero-g's first row: taring";
  int taring = 1;
  for (int i = 0; i < 3 * kTareRows; ++i) {
    rig.cycle(c, offset());
    if ((c.last().flags & kContactTaring) != 0) {
      ++taring;
      EXPECT_LT(contact_error(c, offset()), 1e-9) << "row " << i << ": not zeroed yet";
    } else {
      EXPECT_LT(contact_error(c, Wrench6::Zero()), 1e-9) << "row " << i << ": zeroed";
    }
  }
  // The enabling row, then the rows summed but the last (it is zeroed): tare_s of rows.
  EXPECT_EQ(taring, kTareRows);
  EXPECT_EQ(c.motion().body().state().v_world_mps.norm(), 0.0) << "the part stayed at rest";
  // A push now: confirmed on its third row as ever, its impulse (over the offset) passed.
  const int n = 20;
  for (int i = 0; i < n; ++i) rig.cycle(c, offset() + push(30.0, 0.0, 0.0));
  for (int i = 0; i < 10; ++i) rig.cycle(c, offset());
  const Eigen::Vector3d J_world = rig.R * Eigen::Vector3d(30.0 * n * kPeriod, 0.0, 0.0);
  EXPECT_NEAR((c.motion().body().state().v_world_mps - J_world / test::kMass).norm(), 0.0,
              1e-9 * J_world.norm());
}

// A push while the tare is taken is not confirmed (the gate stays closed, as while the estimator
// settles) and does not move the part.
TEST(Tare, NoPushIsConfirmedBeforeTheTareIsTaken) {
  Cycle c;
  ASSERT_EQ(c.configure(tare_config(), payload_model()).text(), "");
  StaticRobot rig;
  start_zero_g(c, rig);
  for (int i = 0; i < kTareRows / 2; ++i) {
    rig.cycle(c, push(30.0, 0.0, 0.0));
    ASSERT_NE(c.last().flags & kContactTaring, 0u) << "row " << i;
  }
  EXPECT_EQ(c.motion().body().state().v_world_mps.norm(), 0.0);
}

// A hand resting on the part when zero-g is enabled (5 N, above the 2 N gate, for 0.3 s): the
// gate's contact_confirm_cycles rows over it start the tare again, so the zero is taken after
// the hand let go and the part stays at rest. The mutant that keeps the hand in the zero
// (zerog-rt --test-mutant tare_unguarded) sends the part off against the hand's force when it
// lets go: this test's checks fail on it.
TEST(Tare, AHandOnThePartIsNotItsZero) {
  for (const bool mutant : {false, true}) {
    SCOPED_TRACE(mutant ? "mutant tare_unguarded" : "guarded");
    CycleConfig config = tare_config();
    config.mutant_tare_unguarded = mutant;
    Cycle c;
    ASSERT_EQ(c.configure(config, payload_model()).text(), "");
    StaticRobot rig;
    start_zero_g_with(c, rig, offset());
    const Wrench6 hand = push(5.0, 0.0, 0.0);
    const int hand_rows = 25;
    for (int i = 0; i < hand_rows; ++i) rig.cycle(c, offset() + hand);
    int taring_after = 0;
    for (int i = 0; i < 3 * kTareRows; ++i) {
      rig.cycle(c, offset());
      if ((c.last().flags & kContactTaring) != 0) ++taring_after;
    }
    const double v = c.motion().body().state().v_world_mps.norm();
    const double e = contact_error(c, Wrench6::Zero());
    if (mutant) {
      EXPECT_GT(v, 1e-3) << "the hand's force in the zero pushes the part off";
      EXPECT_GT(e, 1.0);
    } else {
      EXPECT_EQ(v, 0.0) << "the part stayed at rest";
      EXPECT_LT(e, 1e-9) << "the zero is the offset, not the hand";
      // The hand's rows from its contact_confirm_cycles-th on (the model's row D late) are not
      // summed: the tare ends tare_s after the hand let go.
      EXPECT_GE(taring_after, kTareRows - c.delay_rows() - 1);
    }
  }
}

// Leaving zero-g forgets the zero: in idle the contact is measured − predicted as it comes;
// entering zero-g again takes a new tare (the offset may have drifted meanwhile).
TEST(Tare, EachSpellOfZeroGTakesItsOwn) {
  Cycle c;
  ASSERT_EQ(c.configure(tare_config(), payload_model()).text(), "");
  StaticRobot rig;
  start_zero_g_with(c, rig, offset());
  for (int i = 0; i < 2 * kTareRows; ++i) rig.cycle(c, offset());
  ASSERT_LT(contact_error(c, Wrench6::Zero()), 1e-9);
  ASSERT_TRUE(c.request(Command::stop));
  rig.cycle(c, offset());
  rig.cycle(c, offset());
  ASSERT_EQ(c.state_machine().state(), State::idle);
  EXPECT_LT(contact_error(c, offset()), 1e-9) << "idle: no tare";
  EXPECT_EQ(c.last().flags & kContactTaring, 0u);
  const Wrench6 drifted = 2.0 * offset();
  for (int i = 0; i < 6; ++i) rig.cycle(c, drifted);
  ASSERT_TRUE(c.request(Command::enable_zero_g));
  rig.cycle(c, drifted);
  ASSERT_EQ(c.state_machine().state(), State::zero_g);
  EXPECT_NE(c.last().flags & kContactTaring, 0u);
  for (int i = 0; i < 2 * kTareRows; ++i) rig.cycle(c, drifted);
  EXPECT_LT(contact_error(c, Wrench6::Zero()), 1e-9) << "the new offset is the new zero";
}

// A held row's contact stays zero (the body coasts) and is not summed; tare_s 0 is no tare.
TEST(Tare, HeldRowsAreNotSummedAndZeroIsOff) {
  Cycle c;
  ASSERT_EQ(c.configure(tare_config(), payload_model()).text(), "");
  StaticRobot rig;
  start_zero_g_with(c, rig, offset());
  const Wrench6 other = 3.0 * offset();  // what a held row would add, were it summed
  int taring = 1;
  for (int i = 0; i < 3 * kTareRows; ++i) {
    const bool held = i >= 5 && i < 8;
    rig.cycle(c, held ? other : offset(), held ? 0 : 4);
    if ((c.last().flags & kContactHeld) != 0) {
      for (int k = 0; k < 6; ++k) EXPECT_EQ(c.last().contact[k], 0.0);
    }
    if ((c.last().flags & kContactTaring) != 0) ++taring;
  }
  EXPECT_EQ(taring, kTareRows + 3) << "three held rows not summed";
  EXPECT_LT(contact_error(c, Wrench6::Zero()), 1e-9);

  Cycle off;
  ASSERT_EQ(off.configure(tare_config(0.0), payload_model()).text(), "");
  StaticRobot rig2;
  start_zero_g_with(off, rig2, offset());
  for (int i = 0; i < 2 * kTareRows; ++i) {
    rig2.cycle(off, offset());
    EXPECT_EQ(off.last().flags & kContactTaring, 0u);
  }
  EXPECT_LT(contact_error(off, offset()), 1e-9);
}

TEST(Tare, ConfigureRefusesANegativeOrHugeTare) {
  for (const double bad : {-0.1, 61.0, std::nan("")}) {
    Cycle c;
    EXPECT_EQ(c.configure(tare_config(bad), payload_model()).setting(), "tare_s") << bad;
  }
}

}  // namespace
}  // namespace zerog::loop
