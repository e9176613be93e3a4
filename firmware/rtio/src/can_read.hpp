#pragma once
// The read loop and the write outcome the socket buses share (CanSocket: SocketCAN; LocalCanBus:
// the same frames over AF_UNIX datagrams): a non-blocking recvmsg of one struct can_frame with its
// receive time, retried (EINTR, or readable again) until the deadline; the arrival time on
// CLOCK_MONOTONIC. Private to zerog::rtio. Real-time safe: no allocation, buffers on the stack.
#include <sys/socket.h>
#include <sys/uio.h>

#include <cerrno>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <ctime>

#include "linux_can_frame.hpp"
#include "wait.hpp"
#include "zerog/handover/clock.hpp"
#include "zerog/rtio/can_bus.hpp"

namespace zerog::rtio::detail {

/// One frame for a bus's read(): `bus` is what differs between the buses, an object with
///   - control_bytes(): room for the ancillary data its socket has switched on;
///   - recv_flags(): recvmsg's flags besides MSG_DONTWAIT;
///   - name(msghdr&): where the sender's address goes (or nothing);
///   - received(const msghdr&): called for every datagram, before it is checked;
///   - ancillary(cmsghdr*): an SOL_SOCKET message other than SO_TIMESTAMPNS;
///   - accepts(const proto::CanFrame&): false drops the frame (counted as filtered) and reads on.
/// Counts in `counters` as CanBus documents; keeps errno of a failed read in `last_errno`.
template <typename Bus>
CanReadStatus read_can_frame(int fd, Bus& bus, CanRxFrame& out, std::chrono::nanoseconds timeout,
                             CanBusCounters& counters, int& last_errno) {
  const std::int64_t deadline = monotonic_ns() + timeout.count();
  can_frame frame{};
  alignas(cmsghdr) char control[Bus::control_bytes()];
  iovec iov{&frame, sizeof frame};
  msghdr message{};
  while (true) {
    bus.name(message);
    message.msg_iov = &iov;
    message.msg_iovlen = 1;
    message.msg_control = control;
    message.msg_controllen = sizeof control;
    message.msg_flags = 0;
    const ssize_t n = ::recvmsg(fd, &message, MSG_DONTWAIT | Bus::recv_flags());
    if (n >= 0) {
      bus.received(message);
      std::int64_t stamp_realtime_ns = 0;
      if ((message.msg_flags & MSG_CTRUNC) != 0) ++counters.control_truncated;
      for (cmsghdr* c = CMSG_FIRSTHDR(&message); c != nullptr; c = CMSG_NXTHDR(&message, c)) {
        if (c->cmsg_level != SOL_SOCKET) continue;
        if (c->cmsg_type == SO_TIMESTAMPNS) {
          timespec ts{};
          std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
          stamp_realtime_ns = static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
        } else {
          bus.ancillary(c);
        }
      }
      out.arrived_ns = stamp_realtime_ns != 0
                           ? handover::realtime_to_monotonic_ns(stamp_realtime_ns)
                           : monotonic_ns();
      // Exactly one classic frame (candump's check); CAN FD is not enabled on these sockets.
      if (!from_can_frame(frame, static_cast<std::size_t>(n), out.frame)) {
        ++counters.bad_length;
        return CanReadStatus::bad_length;
      }
      if (!bus.accepts(out.frame)) {
        ++counters.filtered;  // dropped, as the kernel's filters would: read on
        continue;
      }
      if (out.frame.error()) {
        count_error_frame(out.frame, counters);
        return CanReadStatus::error_frame;
      }
      ++counters.frames_received;
      return CanReadStatus::frame;
    }
    const AfterEmptyRead next = wait_after_empty_read(fd, errno, deadline);
    if (next == AfterEmptyRead::timeout) return CanReadStatus::timeout;
    if (next == AfterEmptyRead::error) {
      last_errno = errno;
      ++counters.io_errors;
      return CanReadStatus::io_error;
    }
  }
}

/// What one write of a frame (write(2), send(2) or sendto(2)) that returned `n` came to, with
/// errno as the call left it, counted in `counters` as CanBus documents: sent, retry (EINTR),
/// would_block (the queue is full) or failed, with errno (EIO for a short write) in `last_errno`.
/// A failure is not counted yet: the caller may still recover (LocalCanBus reconnects) before it
/// counts tx_errors.
enum class WriteOutcome : std::uint8_t { sent, retry, would_block, failed };
inline WriteOutcome classify_write(ssize_t n, CanBusCounters& counters, int& last_errno) {
  if (n == static_cast<ssize_t>(sizeof(can_frame))) {
    ++counters.frames_sent;
    return WriteOutcome::sent;
  }
  if (n < 0 && errno == EINTR) return WriteOutcome::retry;
  last_errno = n < 0 ? errno : EIO;
  if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == ENOBUFS)) {
    ++counters.tx_would_block;
    return WriteOutcome::would_block;
  }
  return WriteOutcome::failed;
}

}  // namespace zerog::rtio::detail
