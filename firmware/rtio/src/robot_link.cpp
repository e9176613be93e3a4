#include "zerog/rtio/robot_link.hpp"

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

}  // namespace zerog::rtio
