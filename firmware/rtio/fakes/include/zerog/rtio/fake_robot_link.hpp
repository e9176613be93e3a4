#pragma once
// FakeRobotLink: a scripted RobotLink (zerog/rtio/robot_link.hpp) for tests. Part of
// zerog::rtio_fakes, which only tests and the emulators link, never zerog-rt.
#include <array>
#include <cstddef>
#include <cstdint>

#include "zerog/proto/rsi.hpp"
#include "zerog/rtio/robot_link.hpp"
#include "zerog/rtio/script_queue.hpp"

namespace zerog::rtio {

/// Scripted RobotLink for tests: receive() returns pushed messages in order, then timeout;
/// replies (RKorr and AKorr) are recorded in the order they were given.
class FakeRobotLink final : public RobotLink {
 public:
  static constexpr std::size_t kCapacity = 64;
  struct Reply {
    proto::rsi::Correction correction;  ///< valid if !axis
    std::uint64_t ipoc = 0;
    bool axis = false;                  ///< reply_axes(): akorr_deg holds the correction
    std::array<double, 6> akorr_deg{};  ///< valid if axis
  };

  bool push(const proto::rsi::RobotMessage& message);
  std::size_t reply_count() const { return reply_count_; }
  /// The i-th reply of the last kCapacity.
  const Reply& reply_at(std::size_t i) const { return replies_[i % kCapacity]; }

  RobotStartStatus start() override;
  RobotReceiveStatus receive(proto::rsi::RobotMessage& out) override;
  RobotReplyStatus reply(const proto::rsi::Correction& correction, std::uint64_t ipoc) override;
  RobotReplyStatus reply_axes(const std::array<double, 6>& akorr_deg, std::uint64_t ipoc) override;
  const RobotLinkCounters& counters() const override { return counters_; }

 private:
  RobotReplyStatus record(const Reply& reply, const double* values);
  ScriptQueue<proto::rsi::RobotMessage, kCapacity> script_;
  std::array<Reply, kCapacity> replies_{};
  std::size_t reply_count_ = 0;
  bool started_ = false;
  bool have_peer_ = false;
  RobotLinkCounters counters_;
};

}  // namespace zerog::rtio
