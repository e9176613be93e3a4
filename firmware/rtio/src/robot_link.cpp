#include "zerog/rtio/robot_link.hpp"

#include <cmath>

#include "zerog/proto/rsi_si.hpp"

namespace zerog::rtio {

const char* robot_start_status_name(RobotStartStatus status) {
  switch (status) {
    case RobotStartStatus::ok:
      return "ok";
    case RobotStartStatus::bad_config:
      return "bad_config";
    case RobotStartStatus::socket_failed:
      return "socket_failed";
    case RobotStartStatus::bind_failed:
      return "bind_failed";
  }
  return "?";
}

const char* robot_receive_status_name(RobotReceiveStatus status) {
  switch (status) {
    case RobotReceiveStatus::message:
      return "message";
    case RobotReceiveStatus::timeout:
      return "timeout";
    case RobotReceiveStatus::malformed:
      return "malformed";
    case RobotReceiveStatus::io_error:
      return "io_error";
    case RobotReceiveStatus::not_started:
      return "not_started";
  }
  return "?";
}

const char* robot_reply_status_name(RobotReplyStatus status) {
  switch (status) {
    case RobotReplyStatus::ok:
      return "ok";
    case RobotReplyStatus::no_peer:
      return "no_peer";
    case RobotReplyStatus::bad_correction:
      return "bad_correction";
    case RobotReplyStatus::would_block:
      return "would_block";
    case RobotReplyStatus::io_error:
      return "io_error";
    case RobotReplyStatus::not_started:
      return "not_started";
  }
  return "?";
}

RobotReceiveStatus RobotLink::receive_sample(samples::RobotSample& out) {
  const RobotReceiveStatus status = receive(wire_);
  if (status == RobotReceiveStatus::message) out = proto::rsi::robot_sample_from_message(wire_);
  return status;
}

RobotReplyStatus RobotLink::send_correction(const samples::RobotCorrection& correction) {
  const proto::rsi::Reply r = proto::rsi::reply_from_correction(correction);
  return r.has_akorr ? reply_axes(r.akorr_deg, r.ipoc) : reply(r.rkorr, r.ipoc);
}

bool FakeRobotLink::push(const proto::rsi::RobotMessage& message) {
  if (count_ == kCapacity) return false;
  script_[(head_ + count_) % kCapacity] = message;
  ++count_;
  return true;
}

RobotStartStatus FakeRobotLink::start() {
  started_ = true;
  return RobotStartStatus::ok;
}

RobotReceiveStatus FakeRobotLink::receive(proto::rsi::RobotMessage& out) {
  if (!started_) return RobotReceiveStatus::not_started;
  if (count_ == 0) {
    ++counters_.timeouts;
    return RobotReceiveStatus::timeout;
  }
  out = script_[head_];
  head_ = (head_ + 1) % kCapacity;
  --count_;
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
