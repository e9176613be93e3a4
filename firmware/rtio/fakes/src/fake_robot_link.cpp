#include "zerog/rtio/fake_robot_link.hpp"

#include <cmath>

namespace zerog::rtio {

bool FakeRobotLink::push(const proto::rsi::RobotMessage& message) { return script_.push(message); }

RobotStartStatus FakeRobotLink::start() {
  started_ = true;
  return RobotStartStatus::ok;
}

RobotReceiveStatus FakeRobotLink::receive(proto::rsi::RobotMessage& out) {
  if (!started_) return RobotReceiveStatus::not_started;
  if (script_.empty()) {
    ++counters_.timeouts;
    return RobotReceiveStatus::timeout;
  }
  out = script_.pop();
  ++counters_.datagrams;
  ++counters_.messages;
  have_peer_ = true;
  return RobotReceiveStatus::message;
}

RobotReplyStatus FakeRobotLink::record(const Reply& reply, const double* values) {
  if (!started_) return RobotReplyStatus::not_started;
  if (!have_peer_) return RobotReplyStatus::no_peer;
  for (int k = 0; k < 6; ++k) {
    if (!std::isfinite(values[k])) {
      ++counters_.bad_corrections;
      return RobotReplyStatus::bad_correction;
    }
  }
  replies_[reply_count_ % kCapacity] = reply;
  ++reply_count_;
  ++counters_.replies;
  return RobotReplyStatus::ok;
}

RobotReplyStatus FakeRobotLink::reply(const proto::rsi::Correction& correction,
                                      std::uint64_t ipoc) {
  const std::array<double, 6> values{correction.x_mm,  correction.y_mm,  correction.z_mm,
                                     correction.a_deg, correction.b_deg, correction.c_deg};
  Reply r;
  r.correction = correction;
  r.ipoc = ipoc;
  return record(r, values.data());
}

RobotReplyStatus FakeRobotLink::reply_axes(const std::array<double, 6>& akorr_deg,
                                           std::uint64_t ipoc) {
  Reply r;
  r.ipoc = ipoc;
  r.axis = true;
  r.akorr_deg = akorr_deg;
  return record(r, akorr_deg.data());
}

}  // namespace zerog::rtio
