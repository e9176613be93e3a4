#pragma once
// SocketCAN raw socket, done the way can-utils' candump does it: acceptance filters in the
// kernel, error frames via CAN_RAW_ERR_FILTER (counted by class), the kernel's per-socket drop
// counter via SO_RXQ_OVFL, a sized receive buffer, SO_TIMESTAMPNS receive timestamps and an
// exact length check on every frame read. Non-blocking socket; reads wait with ppoll().
//
// CAN_RAW_RECV_OWN_MSGS stays off (the kernel default): our own frames never come back to us.
// Some responses (NETCANOEM set-calibration) are byte-identical to their request.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "zerog/proto/can_frame.hpp"
#include "zerog/rtio/can_bus.hpp"

namespace zerog::rtio {

inline constexpr std::size_t kMaxCanFilters = 8;
/// All error classes (CAN_ERR_MASK).
inline constexpr std::uint32_t kCanAllErrors = 0x1FFFFFFFu;

struct CanSocketConfig {
  /// Kernel acceptance filters (CAN_RAW_FILTER); the first `filter_count` are used. The default
  /// single filter {0, 0} passes every data frame; filter_count 0 receives no data frames.
  /// The error flag is cleared from ids and masks (error frames are chosen by error_mask).
  std::array<proto::CanFilter, kMaxCanFilters> filters{};
  std::size_t filter_count = 1;
  /// Error classes to receive as error frames (CAN_RAW_ERR_FILTER); 0 receives none.
  std::uint32_t error_mask = kCanAllErrors;
  /// Requested receive buffer in bytes: SO_RCVBUFFORCE when we may (CAP_NET_ADMIN), else
  /// SO_RCVBUF, capped by rmem_max (see CanReceiveBuffer::capped); 0 keeps the default.
  int receive_buffer_bytes = 0;
  bool timestamps = true;  ///< SO_TIMESTAMPNS
};

/// What the kernel granted of a CanSocket's or LocalCanBus's receive buffer.
struct CanReceiveBuffer {
  int bytes = 0;        ///< SO_RCVBUF as granted (bytes, including the kernel's bookkeeping)
  bool capped = false;  ///< granted less than asked (rmem_max without CAP_NET_ADMIN): say so
};

/// How opening a CanSocket or a LocalCanBus (local_can_bus.hpp) went.
enum class CanOpenStatus : std::uint8_t {
  ok,
  /// Interface name empty or too long, too many filters; LocalCanBus: path empty, with a NUL or
  /// longer than LocalCanBus::kMaxPathBytes (sun_path).
  bad_argument,
  no_such_interface,  ///< if_nametoindex failed
  socket_failed,      ///< socket(PF_CAN, SOCK_RAW, CAN_RAW) failed: no CAN in this kernel?
  option_failed,      ///< a setsockopt failed (`what` names it)
  bind_failed,        ///< LocalCanBus server: e.g. the path exists (EADDRINUSE)
  connect_failed,     ///< LocalCanBus client: nobody serves the path (ECONNREFUSED, ENOENT)
};
struct CanOpenResult {
  CanOpenStatus status = CanOpenStatus::ok;
  int error_number = 0;   ///< errno of the failing call
  const char* what = "";  ///< the failing call, static string
  bool ok() const { return status == CanOpenStatus::ok; }
};
const char* can_open_status_name(CanOpenStatus status);

/// What the two socket buses (CanSocket, LocalCanBus) hold alike: the non-blocking socket, what
/// the kernel granted of its receive buffer, the errno of the last failed read or write, and the
/// counters.
class SocketCanBus : public CanBus {
 public:
  bool is_open() const { return fd_ >= 0; }
  int fd() const { return fd_; }
  const CanReceiveBuffer& receive_buffer() const { return receive_buffer_; }
  int last_errno() const { return last_errno_; }  ///< errno of the last failed read or write
  const CanBusCounters& counters() const override { return counters_; }

 protected:
  int fd_ = -1;
  CanReceiveBuffer receive_buffer_;
  int last_errno_ = 0;
  CanBusCounters counters_;
};

class CanSocket final : public SocketCanBus {
 public:
  CanSocket() = default;
  ~CanSocket() override;
  CanSocket(const CanSocket&) = delete;
  CanSocket& operator=(const CanSocket&) = delete;

  /// Opens and binds a raw socket on `interface` (e.g. "can0", "vcan0"). Start-up only: not
  /// real-time safe. Closes a previously opened socket first.
  CanOpenResult open(std::string_view interface, const CanSocketConfig& config = {});
  void close();

  /// See CanBus::read. Checks that exactly sizeof(struct can_frame) bytes came with len ≤ 8;
  /// takes the timestamp and the SO_RXQ_OVFL drop count from the ancillary data.
  CanReadStatus read(CanRxFrame& out, std::chrono::nanoseconds timeout) override;
  CanWriteStatus write(const proto::CanFrame& frame) override;

 private:
  std::uint32_t last_overflow_count_ = 0;  // SO_RXQ_OVFL reports a running total
};

}  // namespace zerog::rtio
