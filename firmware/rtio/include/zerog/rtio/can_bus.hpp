#pragma once
// A CAN bus as the devices see it: read one frame with a timeout, write one frame, counters.
// Implementations: CanSocket (SocketCAN raw socket, can_socket.hpp: the real bus); LocalCanBus
// (classic frames over an AF_UNIX datagram socket between two processes, local_can_bus.hpp: for
// zerog-rt against zerog-emu on a kernel without CAN); fake: FakeCanBus (fake_can_bus.hpp,
// zerog::rtio_fakes).
#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>

#include "zerog/proto/can_frame.hpp"

namespace zerog::rtio {

/// A received frame and when it arrived.
struct CanRxFrame {
  proto::CanFrame frame;
  /// When the frame arrived, CLOCK_MONOTONIC ns (proto/rtio.md, "When a sample arrived"): the
  /// kernel's receive stamp (SO_TIMESTAMPNS) moved onto the monotonic clock, or the time the read
  /// returned when the kernel gave none (timestamps off, ancillary data truncated). Fake buses:
  /// what the test injects (0: unknown).
  std::int64_t arrived_ns = 0;
};

enum class CanReadStatus : std::uint8_t {
  frame,        ///< a data or remote frame is in `out`
  error_frame,  ///< an error frame is in `out` (counted, and per class in error_classes)
  timeout,     ///< nothing arrived within the timeout (not counted: the caller knows why it waited)
  bad_length,  ///< the kernel returned something other than one classic CAN frame (dropped)
  io_error,    ///< the read failed, e.g. the interface went down (counted, errno kept)
  not_open,
};

enum class CanWriteStatus : std::uint8_t {
  ok,
  would_block,  ///< the TX queue is full (EAGAIN/ENOBUFS); frame not sent (counted)
  bad_frame,    ///< more than 8 data bytes
  io_error,     ///< e.g. the interface is down (counted, errno kept)
  not_open,
};

/// The error classes of an error frame, one per bit of the identifier (<linux/can/error.h>
/// CAN_ERR_TX_TIMEOUT … CAN_ERR_CNT, in bit order).
enum class CanErrorClass : std::uint8_t {
  tx_timeout,        ///< 0x001
  lost_arbitration,  ///< 0x002
  controller,        ///< 0x004: controller problems (data[1]: error passive/warning, overflow)
  protocol,          ///< 0x008: protocol violations (data[2], data[3])
  transceiver,       ///< 0x010
  no_ack,            ///< 0x020: nobody acknowledged our frame (e.g. sensor unplugged)
  bus_off,           ///< 0x040
  bus_error,         ///< 0x080
  restarted,         ///< 0x100: controller restarted after bus-off
  error_counters,    ///< 0x200: TX/RX error counters in data[6], data[7] (kernel ≥ 5.11)
};
inline constexpr std::size_t kCanErrorClassCount = 10;
/// The class bits of an error frame's identifier we know of (0x3FF).
inline constexpr std::uint32_t kCanErrorClassMask = (1u << kCanErrorClassCount) - 1;
const char* can_error_class_name(CanErrorClass error_class);

struct CanBusCounters {
  std::uint64_t frames_received = 0;  ///< data and remote frames returned by read()
  std::uint64_t error_frames = 0;
  std::array<std::uint64_t, kCanErrorClassCount> error_classes{};  ///< indexed by CanErrorClass
  std::uint64_t bad_length = 0;  ///< reads that were not exactly one classic frame (or len > 8)
  /// Frames the kernel dropped for this socket (SO_RXQ_OVFL: a full receive queue). Known only
  /// when the next frame after the drops is read.
  std::uint64_t kernel_drops = 0;
  std::uint64_t control_truncated = 0;  ///< ancillary data cut (MSG_CTRUNC): timestamp lost
  /// Frames the acceptance filters or the error mask dropped (LocalCanBus, which filters in
  /// user space; SocketCAN filters in the kernel, uncounted, so CanSocket leaves this 0).
  std::uint64_t filtered = 0;
  std::uint64_t io_errors = 0;
  std::uint64_t frames_sent = 0;
  std::uint64_t tx_would_block = 0;
  std::uint64_t tx_errors = 0;
};

/// Counts an error frame in `counters` (total and each class bit set). Real-time safe.
void count_error_frame(const proto::CanFrame& frame, CanBusCounters& counters);

class CanBus {
 public:
  virtual ~CanBus() = default;
  /// Waits up to `timeout` (0: just look) for one frame. Real-time safe: no allocation, no
  /// exceptions, bounded by `timeout`. Returns on the first event, so a caller waiting for a
  /// particular frame calls it again with the time left.
  virtual CanReadStatus read(CanRxFrame& out, std::chrono::nanoseconds timeout) = 0;
  /// Queues one frame without blocking. Real-time safe.
  virtual CanWriteStatus write(const proto::CanFrame& frame) = 0;
  /// Counters of this bus (read them from the thread that uses the bus).
  virtual const CanBusCounters& counters() const = 0;
};

}  // namespace zerog::rtio
