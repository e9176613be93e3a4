#include "zerog/rtio/can_socket.hpp"

#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/uio.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>

#include "can_options.hpp"
#include "can_read.hpp"
#include "linux_can_frame.hpp"

namespace zerog::rtio {

static_assert(CAN_ERR_TX_TIMEOUT == 1u << static_cast<int>(CanErrorClass::tx_timeout));
static_assert(CAN_ERR_BUSOFF == 1u << static_cast<int>(CanErrorClass::bus_off));
static_assert(CAN_ERR_RESTARTED == 1u << static_cast<int>(CanErrorClass::restarted));

const char* can_error_class_name(CanErrorClass error_class) {
  switch (error_class) {
    case CanErrorClass::tx_timeout:
      return "tx_timeout";
    case CanErrorClass::lost_arbitration:
      return "lost_arbitration";
    case CanErrorClass::controller:
      return "controller";
    case CanErrorClass::protocol:
      return "protocol";
    case CanErrorClass::transceiver:
      return "transceiver";
    case CanErrorClass::no_ack:
      return "no_ack";
    case CanErrorClass::bus_off:
      return "bus_off";
    case CanErrorClass::bus_error:
      return "bus_error";
    case CanErrorClass::restarted:
      return "restarted";
    case CanErrorClass::error_counters:
      return "error_counters";
  }
  return "?";
}

void count_error_frame(const proto::CanFrame& frame, CanBusCounters& counters) {
  ++counters.error_frames;
  const std::uint32_t classes = frame.id & kCanErrorClassMask;
  for (std::size_t i = 0; i < kCanErrorClassCount; ++i) {
    if ((classes & (1u << i)) != 0) ++counters.error_classes[i];
  }
}

const char* can_open_status_name(CanOpenStatus status) {
  switch (status) {
    case CanOpenStatus::ok:
      return "ok";
    case CanOpenStatus::bad_argument:
      return "bad_argument";
    case CanOpenStatus::no_such_interface:
      return "no_such_interface";
    case CanOpenStatus::socket_failed:
      return "socket_failed";
    case CanOpenStatus::option_failed:
      return "option_failed";
    case CanOpenStatus::bind_failed:
      return "bind_failed";
    case CanOpenStatus::connect_failed:
      return "connect_failed";
  }
  return "?";
}

CanSocket::~CanSocket() { close(); }

void CanSocket::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

CanOpenResult CanSocket::open(std::string_view interface, const CanSocketConfig& config) {
  close();
  if (interface.empty() || interface.size() >= IFNAMSIZ || config.filter_count > kMaxCanFilters) {
    return {CanOpenStatus::bad_argument, EINVAL, "arguments"};
  }
  char name[IFNAMSIZ] = {};
  std::memcpy(name, interface.data(), interface.size());

  auto fail = [this](CanOpenStatus status, const char* what) {
    const CanOpenResult result{status, errno, what};
    close();
    return result;
  };

  fd_ = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd_ < 0) return fail(CanOpenStatus::socket_failed, "socket(PF_CAN, SOCK_RAW, CAN_RAW)");
  // Looked up after socket(): without CAN in the kernel, that failure is the telling one.
  const unsigned ifindex = ::if_nametoindex(name);
  if (ifindex == 0) return fail(CanOpenStatus::no_such_interface, "if_nametoindex");

  can_filter filters[kMaxCanFilters] = {};
  for (std::size_t i = 0; i < config.filter_count; ++i) {
    // CAN_ERR_FLAG in a mask makes the kernel file the filter under error frames
    // (af_can.c, can_rcv_list_find), so it would never pass a data frame. Data filters do not
    // see error frames anyway (those come through CAN_RAW_ERR_FILTER): drop the flag.
    filters[i].can_id = config.filters[i].id & ~CAN_ERR_FLAG;
    filters[i].can_mask = config.filters[i].mask & ~CAN_ERR_FLAG;
  }
  if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, config.filter_count > 0 ? filters : nullptr,
                   static_cast<socklen_t>(config.filter_count * sizeof(can_filter))) != 0) {
    return fail(CanOpenStatus::option_failed, "CAN_RAW_FILTER");
  }
  const can_err_mask_t error_mask = config.error_mask & CAN_ERR_MASK;
  if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &error_mask, sizeof error_mask) != 0) {
    return fail(CanOpenStatus::option_failed, "CAN_RAW_ERR_FILTER");
  }
  // CAN_RAW_RECV_OWN_MSGS is left off on purpose (see the header).
  const int on = 1;
  if (::setsockopt(fd_, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) != 0) {
    return fail(CanOpenStatus::option_failed, "SO_RXQ_OVFL");
  }
  if (const char* failed = detail::set_receive_options(fd_, config, receive_buffer_)) {
    return fail(CanOpenStatus::option_failed, failed);
  }

  sockaddr_can address{};
  address.can_family = AF_CAN;
  address.can_ifindex = static_cast<int>(ifindex);
  if (::bind(fd_, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
    return fail(CanOpenStatus::bind_failed, "bind");
  }
  last_overflow_count_ = 0;
  return {};
}

CanReadStatus CanSocket::read(CanRxFrame& out, std::chrono::nanoseconds timeout) {
  if (fd_ < 0) return CanReadStatus::not_open;
  // Room for SO_TIMESTAMPNS (or SO_TIMESTAMP) and SO_RXQ_OVFL, as in candump; no filter in user
  // space (the kernel's).
  struct Read {
    static constexpr std::size_t control_bytes() {
      return CMSG_SPACE(sizeof(timespec)) + CMSG_SPACE(sizeof(std::uint32_t));
    }
    static constexpr int recv_flags() { return 0; }
    CanBusCounters& counters;
    std::uint32_t& last_overflow_count;
    void name(msghdr& /*message*/) const {}
    void received(const msghdr& /*message*/) const {}
    void ancillary(cmsghdr* c) const {
      if (c->cmsg_type != SO_RXQ_OVFL) return;
      std::uint32_t total = 0;
      std::memcpy(&total, CMSG_DATA(c), sizeof total);
      counters.kernel_drops += static_cast<std::uint32_t>(total - last_overflow_count);
      last_overflow_count = total;
    }
    bool accepts(const proto::CanFrame& /*frame*/) const { return true; }
  };
  Read bus{counters_, last_overflow_count_};
  return detail::read_can_frame(fd_, bus, out, timeout, counters_, last_errno_);
}

CanWriteStatus CanSocket::write(const proto::CanFrame& frame) {
  if (fd_ < 0) return CanWriteStatus::not_open;
  if (frame.len > proto::kCanMaxDataLength) return CanWriteStatus::bad_frame;
  const can_frame raw = detail::to_can_frame(frame);
  while (true) {
    switch (detail::classify_write(::write(fd_, &raw, sizeof raw), counters_, last_errno_)) {
      case detail::WriteOutcome::sent:
        return CanWriteStatus::ok;
      case detail::WriteOutcome::retry:
        continue;
      case detail::WriteOutcome::would_block:
        return CanWriteStatus::would_block;
      case detail::WriteOutcome::failed:
        break;
    }
    ++counters_.tx_errors;
    return CanWriteStatus::io_error;
  }
}

}  // namespace zerog::rtio
