#pragma once
// LocalCanBus: classic CAN frames between two processes of one machine over an AF_UNIX datagram
// socket, for a kernel without CAN (no vcan): zerog-rt ([ft] transport = "local") against the
// emulated board of zerog-emu (--can-local PATH), without the qemu VM. proto/rtio.md, "CAN over
// a local socket", and proto/emulator.md document the transport.
//
// Wire: one frame per datagram in Linux's `struct can_frame` layout, 16 bytes in host byte order:
// can_id u32 (11- or 29-bit id with <linux/can.h>'s CAN_EFF_FLAG, CAN_RTR_FLAG, CAN_ERR_FLAG), len
// u8 (0..8), 3 pad bytes (0), data[8] (bytes past len are 0). The conversion is CanSocket's.
//
// Two ends:
// - the server (open_server) binds PATH: the bus as the emulated board sees it. It answers the
//   last named peer it received a datagram from (recvfrom's address); before any, write()
//   returns io_error (counted in tx_errors, last_errno() ENOTCONN). close() unlinks PATH if it
//   is still the socket this bus bound.
// - the client (open_client) autobinds (an abstract address the kernel picks) and connects to
//   PATH: zerog-rt's side. A client only receives from its server. When a write finds the server
//   gone (ECONNREFUSED, ENOTCONN), it connects to PATH again once and resends, so a restarted
//   server is found; if that fails it is io_error (last_errno() of the reconnect).
//
// What SocketCAN does in the kernel is done here in read(), with the same semantics (as
// CanSocket, can_socket.hpp): the acceptance filters of CanSocketConfig, a data frame passing if
// (id & mask) == (filter.id & mask) for any of them (the error flag cleared from both, as
// CanSocket does; filter_count 0 passes none), error frames passing only if their class bits meet
// error_mask; what does not pass is dropped silently, as the kernel would, and counted in
// `filtered`. A datagram that is not exactly 16 bytes or has len > 8 is bad_length (counted).
// Error frames are counted by class (count_error_frame). Receive timestamps: SO_TIMESTAMPNS works
// on AF_UNIX: the kernel stamps a datagram (CLOCK_REALTIME, moved onto CLOCK_MONOTONIC by the
// read loop) when it is queued to the receiver.
//
// Unlike a CAN bus, nothing is dropped on the way: a sender whose peer's queue is full gets
// would_block (counted in tx_would_block), so kernel_drops stays 0. The queue is bounded by the
// sender's SO_SNDBUF (net.core.wmem_default, 208 KiB: about 280 frames) and, towards the
// server (which is not connected), by net.unix.max_dgram_qlen datagrams (10 by default); SO_RCVBUF
// (receive_buffer_bytes) is set as CanSocket sets it but AF_UNIX does not limit by it.
//
// Non-blocking socket; reads wait with ppoll(). read() and write() are real-time safe: no
// allocation, no exceptions, no locks. open_*() and close() are start-up code.
#include <sys/socket.h>
#include <sys/un.h>

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "zerog/proto/can_frame.hpp"
#include "zerog/rtio/can_bus.hpp"
#include "zerog/rtio/can_socket.hpp"

namespace zerog::rtio {

class LocalCanBus final : public SocketCanBus {
 public:
  enum class Role : std::uint8_t { closed, server, client };
  /// The longest path a socket can bind: sun_path less its terminating NUL (107 bytes).
  static constexpr std::size_t kMaxPathBytes = sizeof(sockaddr_un::sun_path) - 1;

  LocalCanBus() = default;
  ~LocalCanBus() override;
  LocalCanBus(const LocalCanBus&) = delete;
  LocalCanBus& operator=(const LocalCanBus&) = delete;

  /// Binds `path` (which must not exist: bind_failed, EADDRINUSE) and serves the bus there.
  /// Closes a previously opened socket first. Start-up only.
  CanOpenResult open_server(std::string_view path, const CanSocketConfig& config = {});
  /// Autobinds and connects to the server at `path` (connect_failed if nobody serves it).
  /// Closes a previously opened socket first. Start-up only.
  CanOpenResult open_client(std::string_view path, const CanSocketConfig& config = {});
  /// Closes the socket; a server also unlinks its path if that is still the socket it bound.
  void close();

  Role role() const { return role_; }
  /// Server: whether a peer to answer is known (a named sender was read and not found gone).
  /// Client: true while open.
  bool has_peer() const { return role_ == Role::client || peer_length_ > 0; }

  /// See CanBus::read. Filters as described above; filtered frames are skipped within the same
  /// timeout. A server remembers the sender of every datagram from a named socket as its peer.
  CanReadStatus read(CanRxFrame& out, std::chrono::nanoseconds timeout) override;
  /// See CanBus::write: one datagram to the peer.
  CanWriteStatus write(const proto::CanFrame& frame) override;

 private:
  CanOpenResult open(Role role, std::string_view path, const CanSocketConfig& config);
  /// Whether a received frame passes the filters (data frames) or the error mask (error frames).
  bool accepts(const proto::CanFrame& frame) const;

  Role role_ = Role::closed;
  sockaddr_un path_{};  // the server's address (both roles)
  socklen_t path_length_ = 0;
  sockaddr_un peer_{};         // server: whom to answer
  socklen_t peer_length_ = 0;  // 0: no peer yet
  // Server: the socket file bound, so close() unlinks only that one.
  std::uint64_t bound_device_ = 0;
  std::uint64_t bound_inode_ = 0;
  bool bound_ = false;
  std::array<proto::CanFilter, kMaxCanFilters> filters_{};
  std::size_t filter_count_ = 0;
  std::uint32_t error_mask_ = 0;
};

}  // namespace zerog::rtio
