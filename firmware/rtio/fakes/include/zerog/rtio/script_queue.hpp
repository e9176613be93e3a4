#pragma once
// The scripted part the fakes share (FakeFtSensor, FakeImu, FakeRobotLink): a fixed-size queue of
// what the next calls return, in the order a test pushed it. Real-time safe like the devices it
// stands in for: no allocation, no exceptions, no locks. Single-threaded.
#include <array>
#include <cstddef>

namespace zerog::rtio {

template <typename Step, std::size_t N>
class ScriptQueue {
 public:
  static constexpr std::size_t kCapacity = N;

  /// Appends a step; false when the queue is full.
  bool push(const Step& step) {
    if (count_ == N) return false;
    steps_[(head_ + count_) % N] = step;
    ++count_;
    return true;
  }
  bool empty() const { return count_ == 0; }
  /// Takes the oldest step. Requires !empty(). The reference stays valid until the next push().
  const Step& pop() {
    const Step& step = steps_[head_];
    head_ = (head_ + 1) % N;
    --count_;
    return step;
  }

 private:
  std::array<Step, N> steps_{};
  std::size_t head_ = 0;
  std::size_t count_ = 0;
};

}  // namespace zerog::rtio
