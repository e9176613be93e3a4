#pragma once
// A classic CAN frame as a plain value type: the layout idea of Linux's `struct can_frame`
// (flags in the top bits of the identifier) without depending on Linux headers, so the protocol
// code builds and tests anywhere. The SocketCAN driver (later) copies field by field.
#include <array>
#include <cstdint>

namespace zerog::proto {

/// Identifier flags, same values as <linux/can.h> CAN_EFF_FLAG / CAN_RTR_FLAG / CAN_ERR_FLAG.
inline constexpr std::uint32_t kCanExtendedFlag = 0x80000000u;
inline constexpr std::uint32_t kCanRemoteFlag = 0x40000000u;
inline constexpr std::uint32_t kCanErrorFlag = 0x20000000u;
inline constexpr std::uint32_t kCanStandardIdMask = 0x000007FFu;
inline constexpr std::uint32_t kCanExtendedIdMask = 0x1FFFFFFFu;
inline constexpr std::uint8_t kCanMaxDataLength = 8;

/// One classic CAN frame. `id` holds the 11- or 29-bit identifier plus the flags above; `len` is
/// the number of valid bytes in `data` (0–8). Trivially copyable, fixed size.
struct CanFrame {
  std::uint32_t id = 0;
  std::uint8_t len = 0;
  std::array<std::uint8_t, kCanMaxDataLength> data{};

  constexpr bool extended() const { return (id & kCanExtendedFlag) != 0; }
  constexpr bool remote() const { return (id & kCanRemoteFlag) != 0; }
  constexpr bool error() const { return (id & kCanErrorFlag) != 0; }
  /// The identifier without flags.
  constexpr std::uint32_t raw_id() const {
    return id & (extended() ? kCanExtendedIdMask : kCanStandardIdMask);
  }
  /// Equal identifier (with flags), length and the `len` valid data bytes.
  friend constexpr bool operator==(const CanFrame& a, const CanFrame& b) {
    if (a.id != b.id || a.len != b.len) return false;
    for (std::uint8_t i = 0; i < a.len && i < kCanMaxDataLength; ++i) {
      if (a.data[i] != b.data[i]) return false;
    }
    return true;
  }
};

/// An acceptance filter with SocketCAN's semantics (`struct can_filter`): a frame passes when
/// `(frame.id & mask) == (id & mask)`. Include the flag bits in `mask` to tell standard from
/// extended frames. Real-time safe.
struct CanFilter {
  std::uint32_t id = 0;
  std::uint32_t mask = 0;  ///< 0 passes everything

  constexpr bool matches(const CanFrame& frame) const { return (frame.id & mask) == (id & mask); }
};

}  // namespace zerog::proto
