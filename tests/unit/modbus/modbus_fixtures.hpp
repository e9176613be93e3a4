#pragma once
// A SupervisorTarget over a REAL loop::Cycle, stepped by a test thread with a robot standing
// still (loop_fixtures.hpp), so commands and proposals go through the cycle's lock-free paths.
// The snapshot is published under a mutex here (test code); zerog-rt uses a LatestValue.
#include <atomic>
#include <chrono>
#include <mutex>
#include <thread>

#include "loop_fixtures.hpp"
#include "zerog/modbus/target.hpp"

namespace zerog::modbus::test {

class CycleTarget : public SupervisorTarget {
 public:
  explicit CycleTarget(std::chrono::microseconds period = std::chrono::microseconds(2000))
      : period_(period) {
    EXPECT_EQ(cycle_.configure(loop::test::test_cycle_config(), loop::test::payload_model()).text(),
              "");
    initial_ = cycle_.tunables();
  }
  ~CycleTarget() override { stop(); }

  /// Steps the cycle every `period` on a thread of its own (robot messages).
  void start() {
    running_ = true;
    thread_ = std::thread([this] {
      while (running_.load()) {
        robot_.quiet(cycle_);
        // zerog-rt publishes after the cycle's other work (records, telemetry): a delay here
        // widens that window so tests can show a reply does not run ahead of the snapshot.
        if (publish_delay_.count() > 0) std::this_thread::sleep_for(publish_delay_);
        publish();
        steps_.fetch_add(1);
        std::this_thread::sleep_for(period_);
      }
    });
  }
  /// Time between a step and the publication of its snapshot (default none).
  void set_publish_delay(std::chrono::microseconds d) { publish_delay_ = d; }
  /// Stops stepping (the cycle is then the caller's: cycle() may be read).
  void stop() {
    running_ = false;
    if (thread_.joinable()) thread_.join();
  }
  /// Without a thread: one robot cycle now (the caller's thread).
  void step_once() {
    robot_.quiet(cycle_);
    publish();
  }
  /// Waits (up to 5 s) until the snapshot satisfies `pred`.
  template <typename Pred>
  bool wait_for(Pred pred) {
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (std::chrono::steady_clock::now() < deadline) {
      if (pred(snapshot())) return true;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return false;
  }

  const loop::Cycle& cycle() const { return cycle_; }
  std::uint64_t steps() const { return steps_.load(); }

  SupervisorSnapshot snapshot() const override {
    std::lock_guard lock(mutex_);
    return snapshot_;
  }
  std::uint64_t request(loop::Command c) override { return cycle_.request(c); }
  loop::CommandOutcome command_outcome(std::uint64_t ticket) const override {
    return cycle_.command_outcome(ticket);
  }
  bool propose(const loop::Tunables& t) override { return cycle_.propose(t); }
  loop::ProposalStatus proposal_status() const override { return cycle_.proposal_status(); }
  bool withdraw_proposal() override { return cycle_.withdraw_proposal(); }
  loop::Tunables tunables() const override { return initial_; }

 private:
  void publish() {
    SupervisorSnapshot s;
    fill_from_cycle(cycle_, s);
    s.model_crc32 = 0xC0FFEE42u;
    std::lock_guard lock(mutex_);
    snapshot_ = s;
  }

  std::chrono::microseconds period_;
  std::chrono::microseconds publish_delay_{0};
  loop::Cycle cycle_;
  loop::test::StaticRobot robot_;
  loop::Tunables initial_;
  mutable std::mutex mutex_;
  SupervisorSnapshot snapshot_;
  std::atomic<bool> running_{false};
  std::atomic<std::uint64_t> steps_{0};
  std::thread thread_;
};

}  // namespace zerog::modbus::test
