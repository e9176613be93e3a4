#pragma once
// KUKA RSI-like XML over UDP (proto/rsi.md) behind the RobotLink interface. Binds to a configured
// IPv4 address (loopback unless configured otherwise: never the wildcard address by default),
// accepts datagrams only from the configured robot address (others: counted as foreign and
// ignored), parses with the codec into the caller's RobotMessage and answers the sender with
// the formatted <Sen> from a preallocated buffer. Malformed datagrams are counted (by parse
// status) and never stop the endpoint. RobotLink::receive_sample and send_correction convert at
// this border, so the cycle sees SI only (proto/rtio.md, proto/rsi.md "Units at the border").
#include <netinet/in.h>

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>

#include "zerog/proto/rsi.hpp"
#include "zerog/rtio/robot_link.hpp"

namespace zerog::rtio {

struct RsiEndpointConfig {
  std::string bind_address = "127.0.0.1";   ///< IPv4 dotted quad of a local interface
  std::uint16_t bind_port = 49152;          ///< 0: any free port (tests; see local_port())
  std::string robot_address = "127.0.0.1";  ///< the only sender accepted
  std::uint16_t robot_port = 0;             ///< 0: any source port of robot_address
  std::string sensor_type = "zerog";        ///< <Sen Type="…">, as in the robot's RSI config
  /// Longest wait in receive(): about one interpolation cycle (4 ms or 12 ms) plus slack.
  std::chrono::nanoseconds receive_timeout = std::chrono::milliseconds(20);
  int receive_buffer_bytes = 0;  ///< SO_RCVBUF request; 0 keeps the default
};

class RsiEndpoint final : public RobotLink {
 public:
  static constexpr std::size_t kMaxSensorTypeLength = 32;
  static constexpr std::size_t kReplyBufferBytes = 512;

  explicit RsiEndpoint(const RsiEndpointConfig& config);
  ~RsiEndpoint() override;
  RsiEndpoint(const RsiEndpoint&) = delete;
  RsiEndpoint& operator=(const RsiEndpoint&) = delete;

  /// Parses the addresses and binds the socket. Not real-time safe.
  RobotStartStatus start() override;
  void close();
  /// Skips foreign datagrams until a robot datagram comes or the timeout passes. Datagrams
  /// longer than rsi::kMaxMessageBytes are malformed (too_long). Real-time safe.
  RobotReceiveStatus receive(proto::rsi::RobotMessage& out) override;
  /// Formats into the preallocated buffer and sends it to the last robot sender. Real-time safe.
  RobotReplyStatus reply(const proto::rsi::Correction& correction, std::uint64_t ipoc) override;
  /// <Sen><AKorr A1..A6/><IPOC/></Sen> (rsi::format_axis_reply), degrees. Real-time safe.
  RobotReplyStatus reply_axes(const std::array<double, 6>& akorr_deg, std::uint64_t ipoc) override;
  const RobotLinkCounters& counters() const override { return counters_; }
  std::size_t discard_queued() override;

  /// The bound port (useful with bind_port 0).
  std::uint16_t local_port() const { return local_port_; }
  /// Why the last malformed datagram was rejected.
  const proto::rsi::ParseResult& last_parse() const { return last_parse_; }
  int last_errno() const { return last_errno_; }

 private:
  RobotReplyStatus send(const proto::rsi::FormatResult& formatted);
  RsiEndpointConfig config_;
  int fd_ = -1;
  std::uint16_t local_port_ = 0;
  in_addr robot_ip_{};
  sockaddr_in peer_{};  // sender of the last accepted message
  bool have_peer_ = false;
  std::array<char, kMaxSensorTypeLength> sensor_type_{};
  std::size_t sensor_type_length_ = 0;
  std::array<char, proto::rsi::kMaxMessageBytes> rx_{};
  std::array<char, kReplyBufferBytes> tx_{};
  proto::rsi::ParseResult last_parse_{};
  int last_errno_ = 0;
  RobotLinkCounters counters_;
};

}  // namespace zerog::rtio
