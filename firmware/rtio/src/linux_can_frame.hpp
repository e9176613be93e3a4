#pragma once
// proto::CanFrame <-> Linux `struct can_frame` (<linux/can.h>): the one conversion CanSocket
// (SocketCAN) and LocalCanBus (AF_UNIX datagrams in the same layout) share. Private to
// zerog::rtio. Real-time safe.
#include <linux/can.h>

#include <cstddef>
#include <cstring>

#include "zerog/proto/can_frame.hpp"

namespace zerog::rtio::detail {

static_assert(sizeof(can_frame) == CAN_MTU, "struct can_frame is the classic CAN MTU");
static_assert(sizeof(can_frame) == 16 && offsetof(can_frame, len) == 4 &&
                  offsetof(can_frame, data) == 8,
              "can_id u32, len u8, 3 pad bytes, data[8]");
static_assert(proto::kCanErrorFlag == CAN_ERR_FLAG && proto::kCanExtendedFlag == CAN_EFF_FLAG &&
              proto::kCanRemoteFlag == CAN_RTR_FLAG);
static_assert(proto::kCanMaxDataLength == CAN_MAX_DLEN);

/// `frame` as struct can_frame: identifier with its flags, len, the `len` data bytes; the pad and
/// the bytes past `len` are zero. The caller has checked len ≤ 8.
inline can_frame to_can_frame(const proto::CanFrame& frame) {
  can_frame raw{};
  raw.can_id = frame.id;
  raw.len = frame.len;
  std::memcpy(raw.data, frame.data.data(), frame.len);
  return raw;
}

/// The frame in `raw`, of which `bytes` were received. False (and `out` untouched) unless that
/// is exactly one classic frame with len ≤ 8 (candump's check): the caller counts bad_length.
inline bool from_can_frame(const can_frame& raw, std::size_t bytes, proto::CanFrame& out) {
  if (bytes != sizeof raw || raw.len > CAN_MAX_DLEN) return false;
  out.id = raw.can_id;
  out.len = raw.len;
  std::memcpy(out.data.data(), raw.data, proto::kCanMaxDataLength);
  return true;
}

}  // namespace zerog::rtio::detail
