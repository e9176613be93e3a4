#pragma once
// FakeFtSensor: a scripted FtSensor (zerog/rtio/ft_sensor.hpp) for tests. Part of
// zerog::rtio_fakes, which only tests and the emulators link, never zerog-rt.
#include <cstddef>
#include <cstdint>

#include "zerog/rtio/ft_sensor.hpp"
#include "zerog/rtio/script_queue.hpp"

namespace zerog::rtio {

/// Scripted FtSensor for tests: queue results with push(); read_sample returns them in order,
/// then `timeout` when the script is empty. Counts like a real device.
class FakeFtSensor final : public FtSensor {
 public:
  static constexpr std::size_t kScriptCapacity = 64;

  void set_start_status(FtStartStatus status) { start_status_ = status; }
  /// Appends a result; false when the script is full.
  bool push(FtReadStatus status, const FtSample& sample = {});

  FtStartStatus start() override;
  FtReadStatus read_sample(FtSample& out) override;
  FtCounters counters() const override { return counters_; }

 private:
  struct Step {
    FtReadStatus status = FtReadStatus::timeout;
    FtSample sample;
  };
  ScriptQueue<Step, kScriptCapacity> script_;
  FtStartStatus start_status_ = FtStartStatus::ok;
  bool started_ = false;
  std::uint64_t sequence_ = 0;
  FtCounters counters_;
};

}  // namespace zerog::rtio
