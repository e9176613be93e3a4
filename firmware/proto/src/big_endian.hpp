#pragma once
// Big-endian field access on byte buffers (internal to zerog::proto). Callers check bounds.
#include <bit>
#include <cstdint>

namespace zerog::proto::detail {

inline std::uint16_t load_u16(const std::uint8_t* p) {
  return static_cast<std::uint16_t>((p[0] << 8) | p[1]);
}
inline std::int16_t load_i16(const std::uint8_t* p) {
  return static_cast<std::int16_t>(load_u16(p));
}
/// 24-bit two's complement, sign-extended.
inline std::int32_t load_i24(const std::uint8_t* p) {
  std::uint32_t u = (std::uint32_t{p[0]} << 16) | (std::uint32_t{p[1]} << 8) | p[2];
  if (u & 0x800000u) u |= 0xFF000000u;
  return static_cast<std::int32_t>(u);
}
inline std::uint32_t load_u32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
         p[3];
}
inline float load_f32(const std::uint8_t* p) { return std::bit_cast<float>(load_u32(p)); }

inline void store_u16(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v >> 8);
  p[1] = static_cast<std::uint8_t>(v);
}
inline void store_i16(std::uint8_t* p, std::int16_t v) {
  store_u16(p, static_cast<std::uint16_t>(v));
}
/// Low 24 bits of `v` (two's complement).
inline void store_i24(std::uint8_t* p, std::int32_t v) {
  const auto u = static_cast<std::uint32_t>(v);
  p[0] = static_cast<std::uint8_t>(u >> 16);
  p[1] = static_cast<std::uint8_t>(u >> 8);
  p[2] = static_cast<std::uint8_t>(u);
}
inline void store_u32(std::uint8_t* p, std::uint32_t v) {
  p[0] = static_cast<std::uint8_t>(v >> 24);
  p[1] = static_cast<std::uint8_t>(v >> 16);
  p[2] = static_cast<std::uint8_t>(v >> 8);
  p[3] = static_cast<std::uint8_t>(v);
}
inline void store_f32(std::uint8_t* p, float v) { store_u32(p, std::bit_cast<std::uint32_t>(v)); }

}  // namespace zerog::proto::detail
