#pragma once
// Sensonor STIM300 IMU, normal-mode datagrams over the serial port (datasheet TS1524 rev.31,
// §5.5; the facts we use are summarised in ../shared/reference/stim300-datagrams.md). Layout,
// content table and scale factors: proto/stim300.md.
//
// A datagram (Table 5-20): identifier (u8); rate X,Y,Z (3 × 24-bit) + status; [acceleration +
// status]; [inclination + status]; [temperatures (3 × 16-bit) + status per cluster present];
// [PPS (24-bit) + status]; counter (u8); latency (u16, µs); CRC-32 (u32). Big-endian, two's
// complement. The CRC covers the datagram without the CRC plus 0–3 dummy zero bytes (Table 5-22;
// input length a multiple of 4). Optionally followed by CR LF.
//
// Everything here is real-time safe (no allocation, no exceptions, no locks, bounded time).
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

namespace zerog::proto::stim300 {

// --- Datagram content table ------------------------------------------------------------------

/// What one datagram identifier carries. Rate is always present.
struct DatagramContent {
  std::uint8_t identifier;
  bool accel;              ///< accelerometer X, Y, Z + status
  bool incl;               ///< inclinometer X, Y, Z + status
  bool temperature;        ///< a temperature triplet + status for each cluster present
  bool pps;                ///< PPS (24-bit) + status, after the temperatures (Table 5-20)
  std::uint8_t crc_dummy;  ///< CRC dummy bytes as Table 5-22 lists them (checked below)
};

/// The normal-mode content table of TS1524 rev.31 (Table 5-21, dummy bytes Table 5-22;
/// proto/stim300.md). The only place to change when the datasheet differs. There are no
/// 0x95–0x9C datagrams and no AUX content in rev.31; older revisions' AUX datagrams are left out
/// (unverified). Service datagrams (0xB1…0xBF, 0xD1/0xD2) are not decoded.
inline constexpr std::array<DatagramContent, 16> kDatagramTable{{
    {0x90, false, false, false, false, 2},  // rate
    {0x91, true, false, false, false, 0},   // rate, acc
    {0x92, false, true, false, false, 0},   // rate, incl
    {0x93, true, true, false, false, 2},    // rate, acc, incl
    {0x94, false, false, true, false, 3},   // rate, temp
    {0xA5, true, false, true, false, 2},    // rate, acc, temp
    {0xA6, false, true, true, false, 2},    // rate, incl, temp
    {0xA7, true, true, true, false, 1},     // rate, acc, incl, temp
    {0xF0, false, false, false, true, 2},   // rate, PPS
    {0xF1, true, false, false, true, 0},    // rate, acc, PPS
    {0xF2, false, true, false, true, 0},    // rate, incl, PPS
    {0xF3, true, true, false, true, 2},     // rate, acc, incl, PPS
    {0xF4, false, false, true, true, 3},    // rate, temp, PPS
    {0xF5, true, false, true, true, 2},     // rate, acc, temp, PPS
    {0xF6, false, true, true, true, 2},     // rate, incl, temp, PPS
    {0xF7, true, true, true, true, 1},      // rate, acc, incl, temp, PPS
}};

/// The table entry of `identifier`, or nullptr when it is not a known normal-mode identifier.
const DatagramContent* find_content(std::uint8_t identifier);

inline constexpr std::size_t kTripletBytes = 9 + 1;      // 3 × 24-bit + status
inline constexpr std::size_t kPpsBytes = 3 + 1;          // 24-bit + status
inline constexpr std::size_t kTemperatureBytes = 6 + 1;  // 3 × 16-bit + status
inline constexpr std::size_t kTrailerBytes = 1 + 2 + 4;  // counter, latency, CRC

/// Number of sensor clusters (rate, acc, incl) in a datagram.
constexpr int group_count(const DatagramContent& c) { return 1 + c.accel + c.incl; }
/// Datagram length in bytes, identifier to CRC inclusive, without CR LF.
constexpr std::size_t datagram_length(const DatagramContent& c) {
  return 1 + group_count(c) * kTripletBytes +
         (c.temperature ? group_count(c) * kTemperatureBytes : 0) + (c.pps ? kPpsBytes : 0) +
         kTrailerBytes;
}
/// Dummy zero bytes appended to the CRC input so its length is a multiple of 4 (§5.5.7).
constexpr std::size_t crc_dummy_bytes(const DatagramContent& c) {
  return (4 - (datagram_length(c) - 4) % 4) % 4;
}
/// Every row's layout gives the dummy byte count Table 5-22 lists for it.
constexpr bool table_matches_dummy_bytes() {
  for (const DatagramContent& c : kDatagramTable) {
    if (crc_dummy_bytes(c) != c.crc_dummy) return false;
  }
  return true;
}
static_assert(table_matches_dummy_bytes(), "kDatagramTable disagrees with TS1524 Table 5-22");
inline constexpr std::size_t kMaxDatagramLength =
    datagram_length({0, true, true, true, true, 0});  // 0xF7: 63 bytes

/// CRC-32/MPEG-2: polynomial 0x04C11DB7, no reflection, no final XOR. Pass the previous result
/// as `crc` to continue over several pieces. crc32_mpeg2("123456789") == 0x0376E6E7.
std::uint32_t crc32_mpeg2(std::span<const std::uint8_t> bytes, std::uint32_t crc = 0xFFFFFFFFu);

// --- Scale factors ---------------------------------------------------------------------------
// Unverified: not in our datasheet reference (identifiers, layout, CRC and status only); see
// proto/stim300.md.

inline constexpr double kStandardGravity = 9.80665;  ///< m/s² per g
inline constexpr double kPi = 3.14159265358979323846;

/// Accelerometer range (ordering code); sets the accelerometer scale.
enum class AccelRange : std::uint8_t { g5, g10, g30, g80 };

struct Scale {
  AccelRange accel_range = AccelRange::g10;

  /// Rate: 2^14 LSB per °/s.
  static constexpr double rate_rad_s_per_lsb() { return (kPi / 180.0) / 16384.0; }
  /// Acceleration: 2^20 (5 g), 2^19 (10 g), 2^18 (30 g), 2^16 (80 g) LSB per g.
  constexpr double accel_m_s2_per_lsb() const {
    switch (accel_range) {
      case AccelRange::g5:
        return kStandardGravity / 1048576.0;
      case AccelRange::g10:
        return kStandardGravity / 524288.0;
      case AccelRange::g30:
        return kStandardGravity / 262144.0;
      case AccelRange::g80:
        return kStandardGravity / 65536.0;
    }
    return kStandardGravity / 524288.0;
  }
  /// Inclination (specific force along the inclinometer axes): 2^22 LSB per g.
  static constexpr double incl_m_s2_per_lsb() { return kStandardGravity / 4194304.0; }
  /// Temperature: 2^8 LSB per °C.
  static constexpr double temperature_c_per_lsb() { return 1.0 / 256.0; }
};

// --- Datagram values -------------------------------------------------------------------------

struct Triplet24 {
  std::array<std::int32_t, 3> counts{};  ///< X, Y, Z, 24-bit two's complement range
  std::uint8_t status = 0;               ///< any bit set: the group's values are invalid
};
struct Triplet16 {
  std::array<std::int16_t, 3> counts{};
  std::uint8_t status = 0;
};

/// The wire content of one datagram (raw counts). Groups absent from the identifier's content
/// are left zero by the decoder and ignored by the encoder.
struct RawDatagram {
  std::uint8_t identifier = 0x93;
  Triplet24 rate;
  Triplet24 accel;
  Triplet24 incl;
  Triplet16 rate_temperature;
  Triplet16 accel_temperature;
  Triplet16 incl_temperature;
  /// PPS field, the raw 24 bits (0 … 2^24 − 1). Its meaning and unit are not in our reference
  /// (stim300-datagrams.md gives only its position and size): unverified, so no SI value.
  std::uint32_t pps = 0;
  std::uint8_t pps_status = 0;
  std::uint8_t counter = 0;
  std::uint16_t latency_us = 0;  ///< from sampling to the start of transmission
};

/// One datagram in SI units. `*_valid` is false when the group is absent or its status is set.
struct Sample {
  RawDatagram raw;
  std::array<double, 3> rate_rad_s{};
  std::array<double, 3> accel_m_s2{};  ///< specific force, as the accelerometers measure it
  std::array<double, 3> incl_m_s2{};   ///< specific force along the inclinometer axes
  std::array<double, 3> rate_temperature_c{};
  std::array<double, 3> accel_temperature_c{};
  std::array<double, 3> incl_temperature_c{};
  double latency_s = 0.0;
  bool rate_valid = false;
  bool accel_valid = false;
  bool incl_valid = false;
  bool pps_valid = false;  ///< PPS present and its status byte zero (raw.pps holds the value)
  bool rate_temperature_valid = false;
  bool accel_temperature_valid = false;
  bool incl_temperature_valid = false;
  std::uint8_t missed_before = 0;  ///< datagrams lost before this one (counter gap); stream only
};

enum class DecodeStatus : std::uint8_t { ok, unknown_identifier, too_short, crc_mismatch };

/// Decodes the datagram at the start of `bytes` (which may hold more). Checks identifier, length
/// and CRC.
DecodeStatus decode_datagram(std::span<const std::uint8_t> bytes, RawDatagram& out);
/// Converts counts to SI and sets the validity flags from content and status bytes.
Sample to_sample(const RawDatagram& raw, const Scale& scale);

enum class EncodeStatus : std::uint8_t {
  ok,
  unknown_identifier,
  buffer_too_small,
  value_out_of_range,  ///< a 24-bit field outside [−2^23, 2^23 − 1] (PPS: [0, 2^24 − 1])
};
struct EncodeResult {
  EncodeStatus status;
  std::size_t size;  ///< bytes written (0 unless ok)
};
/// Writes a valid datagram (with CRC, and CR LF when `crlf`) into `out`. For emulators and tests.
EncodeResult encode_datagram(const RawDatagram& raw, bool crlf, std::span<std::uint8_t> out);

/// Counts for an SI value (rounded, saturated to the 24-bit range), for emulators.
std::int32_t rate_counts(double rate_rad_s);
std::int32_t accel_counts(double accel_m_s2, const Scale& scale);
std::int32_t incl_counts(double incl_m_s2);
std::int16_t temperature_counts(double temperature_c);

// --- Stream decoder --------------------------------------------------------------------------

struct StreamCounters {
  std::uint64_t datagrams = 0;      ///< good datagrams decoded
  std::uint64_t bytes_skipped = 0;  ///< bytes discarded while (re)synchronising
  /// Bad CRC where the next datagram was due: right after a good datagram, or one datagram (+ CR
  /// LF) after a bad one counted here, so that a stream of framed datagrams with wrong CRCs
  /// counts each of them, and identifier-like bytes inside garbage count none.
  std::uint64_t crc_failures = 0;
  std::uint64_t sync_losses = 0;       ///< in sync, then something other than a good datagram
  std::uint64_t counter_gaps = 0;      ///< times the counter jumped by more than one
  std::uint64_t datagrams_missed = 0;  ///< sum of the counter gaps
  std::uint64_t invalid_samples = 0;   ///< datagrams with any group status set
};

struct StreamConfig {
  Scale scale;
  /// Only this identifier is accepted (others are treated as garbage); 0 accepts any identifier
  /// of kDatagramTable. Fixing it makes false synchronisation on garbage less likely.
  std::uint8_t identifier = 0;
};

/// Finds datagrams in a byte stream fed in arbitrary chunks: a candidate is a known identifier
/// followed by a matching CRC; anything else is skipped one byte at a time (resynchronisation).
/// CR LF right after a datagram is consumed silently. Fixed internal buffer; real-time safe.
///
///     decoder.feed(chunk, [&](const stim300::Sample& s) { ... });
class StreamDecoder {
 public:
  static constexpr std::size_t kBufferSize = 512;
  static_assert(kBufferSize > 2 * (kMaxDatagramLength + 2));

  explicit StreamDecoder(const StreamConfig& config = {}) : config_(config) {}

  /// Copies as many bytes as fit into the buffer; returns how many were taken.
  std::size_t push(std::span<const std::uint8_t> bytes);
  /// The next datagram in the buffer, if a complete one is there.
  bool pop(Sample& out);
  /// push + pop until `bytes` are used up, calling `sink(const Sample&)` per datagram.
  template <typename Sink>
  void feed(std::span<const std::uint8_t> bytes, Sink&& sink) {
    Sample sample;
    while (true) {
      const std::size_t taken = push(bytes);
      bytes = bytes.subspan(taken);
      bool any = false;
      while (pop(sample)) {
        sink(static_cast<const Sample&>(sample));
        any = true;
      }
      if (bytes.empty() || (taken == 0 && !any)) break;  // second: cannot happen (buffer > 2×max)
    }
  }

  const StreamCounters& counters() const { return counters_; }
  bool in_sync() const { return in_sync_; }
  /// Drops buffered bytes and the sync/counter state (counters are kept).
  void reset();

 private:
  void skip_byte();

  StreamConfig config_;
  std::array<std::uint8_t, kBufferSize> buffer_{};
  std::size_t head_ = 0;  // first unread byte
  std::size_t tail_ = 0;  // one past the last byte
  bool in_sync_ = false;
  std::uint8_t after_datagram_ = 0;  // 1: CR may follow, 2: LF may follow
  std::uint64_t base_ = 0;           // stream offset of buffer_[0]
  std::uint64_t bad_end_ = 0;        // stream offset after the last counted bad datagram
  bool have_bad_end_ = false;
  bool have_counter_ = false;
  std::uint8_t last_counter_ = 0;
  StreamCounters counters_;
};

}  // namespace zerog::proto::stim300
