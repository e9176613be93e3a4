#include "zerog/loop/state_machine.hpp"

#include <gtest/gtest.h>

#include "zerog/loop/black_box.hpp"

namespace zerog::loop {
namespace {

TEST(StateMachine, AllowedAndRefusedCommands) {
  StateMachine sm;
  EXPECT_FALSE(sm.command(Command::stop, 1));         // nothing to stop in idle
  EXPECT_FALSE(sm.command(Command::reset_fault, 1));  // no fault
  EXPECT_TRUE(sm.command(Command::enable_zero_g, 2));
  EXPECT_EQ(sm.state(), State::zero_g);
  EXPECT_FALSE(sm.command(Command::start_collection, 3));  // only from idle
  EXPECT_TRUE(sm.command(Command::stop, 4));
  EXPECT_TRUE(sm.command(Command::start_collection, 5));
  EXPECT_EQ(sm.state(), State::collecting);
  EXPECT_EQ(sm.total_transitions(), 3u);
}

TEST(StateMachine, FaultIsStickyUntilResetAndLogged) {
  StateMachine sm;
  sm.command(Command::enable_zero_g, 10);
  sm.raise(Fault::ft_stale, 42);
  sm.raise(Fault::robot_late, 43);  // the first fault is kept
  EXPECT_EQ(sm.state(), State::fault);
  EXPECT_EQ(sm.fault(), Fault::ft_stale);
  EXPECT_FALSE(sm.command(Command::enable_zero_g, 44));
  EXPECT_TRUE(sm.command(Command::reset_fault, 50));
  EXPECT_EQ(sm.state(), State::idle);
  EXPECT_EQ(sm.fault(), Fault::none);
  ASSERT_EQ(sm.log_size(), 3u);
  EXPECT_TRUE(sm.log_at(1).by_fault);
  EXPECT_EQ(sm.log_at(1).fault, Fault::ft_stale);
  EXPECT_EQ(sm.log_at(1).cycle, 42u);
  EXPECT_EQ(sm.log_at(1).from, State::zero_g);
  EXPECT_STREQ(fault_name(sm.log_at(1).fault), "ft_stale");
}

TEST(StateMachine, LogKeepsTheNewestTransitionsInOrder) {
  StateMachine sm;
  for (std::uint64_t c = 0; c < 200; ++c) {
    sm.command(c % 2 == 0 ? Command::enable_zero_g : Command::stop, c);
  }
  EXPECT_EQ(sm.total_transitions(), 200u);
  ASSERT_EQ(sm.log_size(), StateMachine::kLogCapacity);
  EXPECT_EQ(sm.log_at(0).cycle, 200u - StateMachine::kLogCapacity);
  EXPECT_EQ(sm.log_at(StateMachine::kLogCapacity - 1).cycle, 199u);
}

TEST(BlackBox, KeepsTheLastNAndFreezesOnFault) {
  BlackBox<int, 250> box;  // one second of 4 ms cycles
  for (int i = 0; i < 1000; ++i) box.push(i);
  ASSERT_EQ(box.size(), 250u);
  EXPECT_EQ(box.at(0), 750);
  EXPECT_EQ(box.at(249), 999);
  box.freeze();
  box.push(1000);
  EXPECT_EQ(box.at(249), 999);  // frozen: the moment of the fault stays
  box.release();
  box.push(1000);
  EXPECT_EQ(box.at(249), 1000);
  EXPECT_EQ(box.at(0), 751);
}

TEST(BlackBox, ARecordFilledInPlaceIsKeptOnCommit) {
  BlackBox<int, 4> box;
  for (int i = 0; i < 6; ++i) {
    box.next() = i;
    box.commit();
  }
  ASSERT_EQ(box.size(), 4u);
  EXPECT_EQ(box.at(0), 2);
  EXPECT_EQ(box.at(3), 5);
  EXPECT_EQ(&box.newest(), &box.at(3));
  EXPECT_EQ(box.total_pushed(), 6u);
  box.next() = 6;  // written, not committed: the slot was the oldest's, the newest is unchanged
  EXPECT_EQ(box.at(3), 5);
  EXPECT_EQ(box.size(), 4u);
  EXPECT_EQ(box.total_pushed(), 6u);
}

}  // namespace
}  // namespace zerog::loop
