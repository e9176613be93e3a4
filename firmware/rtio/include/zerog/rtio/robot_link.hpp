#pragma once
// The robot controller as the loop sees it: one message per interpolation cycle in, one reply
// with the same IPOC out. Real: RsiEndpoint (KUKA RSI-like XML over UDP, rsi_endpoint.hpp);
// fake: FakeRobotLink (zerog/rtio/fake_robot_link.hpp in zerog::rtio_fakes, which only tests
// and the emulators link). Message and correction types are the codec's (proto/rsi.md).
#include <array>
#include <cstddef>
#include <cstdint>

#include "zerog/proto/rsi.hpp"
#include "zerog/samples/robot_sample.hpp"

namespace zerog::rtio {

enum class RobotStartStatus : std::uint8_t {
  ok,
  bad_config,     ///< unparsable address, bad sensor type
  socket_failed,  ///< socket() or a socket option failed
  bind_failed,    ///< address in use, not a local address
};
const char* robot_start_status_name(RobotStartStatus status);

enum class RobotReceiveStatus : std::uint8_t {
  message,    ///< `out` holds a parsed message from the robot
  timeout,    ///< no message from the robot in time (foreign datagrams are waited past)
  malformed,  ///< a datagram from the robot the codec rejected (counted; see last_parse())
  io_error,   ///< recv failed (counted)
  not_started,
};
const char* robot_receive_status_name(RobotReceiveStatus status);

enum class RobotReplyStatus : std::uint8_t {
  ok,
  no_peer,         ///< nothing has been received from the robot yet
  bad_correction,  ///< not finite, or the reply did not fit (counted; nothing sent)
  would_block,     ///< the socket's send buffer is full (counted)
  io_error,        ///< sendto failed (counted)
  not_started,
};
const char* robot_reply_status_name(RobotReplyStatus status);

inline constexpr std::size_t kParseStatusCount =
    static_cast<std::size_t>(proto::rsi::ParseStatus::bad_number) + 1;

struct RobotLinkCounters {
  std::uint64_t datagrams = 0;  ///< everything received
  std::uint64_t messages = 0;   ///< from the robot and parsed
  std::uint64_t foreign = 0;    ///< from another address or port: ignored
  std::uint64_t malformed = 0;  ///< from the robot but rejected by the parser
  std::array<std::uint64_t, kParseStatusCount> malformed_by_status{};  ///< by rsi::ParseStatus
  std::uint64_t timeouts = 0;
  std::uint64_t io_errors = 0;
  std::uint64_t replies = 0;
  std::uint64_t reply_would_block = 0;
  std::uint64_t reply_errors = 0;     ///< sendto failures other than would-block
  std::uint64_t bad_corrections = 0;  ///< replies refused by the formatter
  std::uint64_t discarded = 0;        ///< queued datagrams dropped by discard_queued()
};

class RobotLink {
 public:
  virtual ~RobotLink() = default;
  /// Not real-time safe.
  virtual RobotStartStatus start() = 0;
  /// Waits up to the configured receive timeout for the robot's next message. Real-time safe.
  virtual RobotReceiveStatus receive(proto::rsi::RobotMessage& out) = 0;
  /// Answers the robot (the sender of the last message) with `correction` and `ipoc`.
  /// Real-time safe.
  virtual RobotReplyStatus reply(const proto::rsi::Correction& correction, std::uint64_t ipoc) = 0;
  /// Answers with axis corrections A1..A6 in degrees (<AKorr>, zerog-rt's collection mode)
  /// and `ipoc`. Same statuses and counters as reply(). Real-time safe.
  virtual RobotReplyStatus reply_axes(const std::array<double, 6>& akorr_deg,
                                      std::uint64_t ipoc) = 0;
  virtual const RobotLinkCounters& counters() const = 0;
  /// Drops every datagram already queued (e.g. those that piled up while the program started:
  /// answering them now would be late and pointless). Returns how many; counted as `discarded`.
  /// Not real-time safe in general; call before the cycle starts.
  virtual std::size_t discard_queued() { return 0; }

  // --- SI at the border (what the cycle sees; proto/rsi.md, "Units at the border") -------------
  /// receive(), the message converted to SI (proto::rsi::robot_sample_from_message): joints in
  /// rad, RIst as position (m) and rotation matrix, IPOC and Delay as they came. `out` is written
  /// only when a message came. Real-time safe.
  RobotReceiveStatus receive_sample(samples::RobotSample& out);
  /// Answers with an SI correction, converted to KUKA units (proto::rsi::reply_from_correction):
  /// reply() with RKorr (Kind::cartesian, or zeros for Kind::none) or reply_axes() with AKorr
  /// (Kind::axes). Real-time safe.
  RobotReplyStatus send_correction(const samples::RobotCorrection& correction);

 private:
  proto::rsi::RobotMessage wire_;  ///< receive_sample()'s message, in the wire's units
};

}  // namespace zerog::rtio
