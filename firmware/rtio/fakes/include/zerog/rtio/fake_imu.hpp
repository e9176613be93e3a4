#pragma once
// FakeImu: a scripted Imu (zerog/rtio/imu.hpp) for tests. Part of zerog::rtio_fakes, which only
// tests and the emulators link, never zerog-rt.
#include <cstddef>
#include <cstdint>

#include "zerog/rtio/imu.hpp"
#include "zerog/rtio/script_queue.hpp"

namespace zerog::rtio {

/// Scripted Imu for tests: read_sample returns the pushed results in order, then `timeout`.
class FakeImu final : public Imu {
 public:
  static constexpr std::size_t kScriptCapacity = 64;

  void set_start_status(ImuStartStatus status) { start_status_ = status; }
  bool push(ImuReadStatus status, const ImuSample& sample = {});

  ImuStartStatus start() override;
  ImuReadStatus read_sample(ImuSample& out) override;
  ImuCounters counters() const override { return counters_; }

 private:
  struct Step {
    ImuReadStatus status = ImuReadStatus::timeout;
    ImuSample sample;
  };
  ScriptQueue<Step, kScriptCapacity> script_;
  ImuStartStatus start_status_ = ImuStartStatus::ok;
  bool started_ = false;
  std::uint64_t sequence_ = 0;
  ImuCounters counters_;
};

}  // namespace zerog::rtio
