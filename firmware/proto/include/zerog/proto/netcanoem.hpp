#pragma once
// ATI NETCANOEM: the CAN protocol of ATI's OEM F/T interface board (ATI manual 9610-05-1030).
// Described in proto/netcanoem.md and proto/netcanoem.dbc.
//
// CAN id = (7-bit base id << 4) | opcode, standard 11-bit frames, payload big-endian. A request
// and its response(s) share the id of their opcode; they differ in length.
//
// Everything here is real-time safe (no allocation, no exceptions, no locks, bounded time)
// unless a comment says otherwise. Decoders return a status and fill an output struct.
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>

#include "zerog/proto/can_frame.hpp"

namespace zerog::proto::netcanoem {

enum class Opcode : std::uint8_t {
  sample_a = 0x0,            ///< request: read gauges (no data); response: status, SG0, SG2, SG4
  sample_b = 0x1,            ///< response only: SG1, SG3, SG5
  matrix_sg01 = 0x2,         ///< request: read matrix row (1 byte); response: C[r][0], C[r][1]
  matrix_sg23 = 0x3,         ///< response: C[r][2], C[r][3]
  matrix_sg45 = 0x4,         ///< response: C[r][4], C[r][5]
  serial_number = 0x5,       ///< response: 8 ASCII characters
  active_calibration = 0x6,  ///< request: index 0–15; response: the same byte echoed
  counts = 0x7,              ///< response: counts per force (u32), counts per torque (u32)
  units = 0x8,               ///< response: force unit code (u8), torque unit code (u8)
  diagnostic_adc = 0x9,      ///< request: diagnostic index (1 byte); response: its ADC reading
  firmware_version = 0xF,    ///< response: major (u8), minor (u8), build (u16)
};

inline constexpr std::uint8_t kMaxBaseId = 0x7F;
inline constexpr std::uint8_t kMaxCalibrationIndex = 15;
inline constexpr int kGaugeCount = 6;
/// Counts per force unit and per torque unit assumed when the firmware predates opcode 0x7.
inline constexpr std::uint32_t kDefaultCounts = 1'000'000;

/// Response lengths in bytes (a frame of another length is an error).
inline constexpr std::uint8_t kSampleALength = 8;
inline constexpr std::uint8_t kSampleBLength = 6;
inline constexpr std::uint8_t kMatrixPartLength = 8;
inline constexpr std::uint8_t kSerialNumberLength = 8;
inline constexpr std::uint8_t kActiveCalibrationLength = 1;
inline constexpr std::uint8_t kCountsLength = 8;
inline constexpr std::uint8_t kUnitsLength = 2;
inline constexpr std::uint8_t kFirmwareVersionLength = 4;
inline constexpr std::uint8_t kDiagnosticAdcLength = 2;
/// The 0x9 request carries the diagnostic index (1 byte): so a request (1) and a response (2)
/// of the same id differ in length.
inline constexpr std::uint8_t kDiagnosticRequestLength = 1;

/// CAN identifier of `opcode` for a board at `base_id` (0–127; higher bits are masked off).
constexpr std::uint32_t can_id(std::uint8_t base_id, Opcode opcode) {
  return (static_cast<std::uint32_t>(base_id & kMaxBaseId) << 4) |
         static_cast<std::uint32_t>(opcode);
}
/// Base id and opcode of a standard data frame's identifier.
constexpr std::uint8_t base_id_of(std::uint32_t id) {
  return static_cast<std::uint8_t>((id >> 4) & kMaxBaseId);
}
constexpr std::uint8_t opcode_of(std::uint32_t id) { return static_cast<std::uint8_t>(id & 0xFu); }
/// A filter passing the standard data frames (no remote, no error, no extended) of one board.
constexpr CanFilter filter_for(std::uint8_t base_id) {
  return CanFilter{static_cast<std::uint32_t>(base_id & kMaxBaseId) << 4,
                   kCanExtendedFlag | kCanRemoteFlag | kCanErrorFlag | 0x7F0u};
}

// ---------------------------------------------------------------------------------------------
// Requests (host → board). Each returns no frame when an argument is out of range.

std::optional<CanFrame> request_sample(std::uint8_t base_id);
/// `row` 0–5 selects Fx, Fy, Fz, Tx, Ty, Tz.
std::optional<CanFrame> request_matrix_row(std::uint8_t base_id, std::uint8_t row);
std::optional<CanFrame> request_serial_number(std::uint8_t base_id);
/// `index` 0–15.
std::optional<CanFrame> request_set_active_calibration(std::uint8_t base_id, std::uint8_t index);
std::optional<CanFrame> request_counts(std::uint8_t base_id);
std::optional<CanFrame> request_units(std::uint8_t base_id);
std::optional<CanFrame> request_firmware_version(std::uint8_t base_id);

/// Diagnostic ADC channels of opcode 0x9 ("Read Diagnostic ADC Voltages"; the manual as
/// reproduced in a public driver, proto/netcanoem.md). The response does not say which channel
/// it answers: the caller must know what it asked.
enum class DiagnosticIndex : std::uint8_t {
  mid_vsg = 0,
  unused = 1,
  thermistor = 2,  ///< the sensor's thermistor (what the temperature comes from)
  power = 3,
  dac = 4,
  ground = 5,
};
inline constexpr std::uint8_t kMaxDiagnosticIndex = 5;
/// Read one diagnostic ADC channel (0x9, 1 byte: `index` 0–5).
std::optional<CanFrame> request_diagnostic_adc(std::uint8_t base_id, DiagnosticIndex index);

// ---------------------------------------------------------------------------------------------
// Status word of a sample (manual 9610-05-1030, status code table).

/// Bits 1–7, 11 and 12: the gauge data must not be used.
inline constexpr std::uint16_t kStatusCriticalMask = 0x18FEu;
/// Bit 14: CAN bus error; warn and keep using the data.
inline constexpr std::uint16_t kStatusCanBusError = 1u << 14;
/// Bit 15: set whenever any error bit is set.
inline constexpr std::uint16_t kStatusAnyError = 1u << 15;

enum class StatusClass : std::uint8_t {
  ok,        ///< status word 0
  warning,   ///< only non-critical bits (CAN bus error, any-error, reserved bits)
  critical,  ///< at least one critical bit: stop using the data
};
constexpr StatusClass classify_status(std::uint16_t status) {
  if (status & kStatusCriticalMask) return StatusClass::critical;
  return status == 0 ? StatusClass::ok : StatusClass::warning;
}

/// One gauge sample, assembled from the 0x0 and 0x1 responses and put in gauge order.
struct GaugeSample {
  std::array<std::int16_t, kGaugeCount> gauges{};  ///< SG0..SG5, raw counts
  std::uint16_t status = 0;                        ///< raw status word
  StatusClass status_class = StatusClass::ok;
  std::uint8_t saturated_mask = 0;  ///< bit i set: SG i at +32767 or −32768 (saturated)
  /// The tag the caller gave with the 0x0 frame of this sample (SampleAssembler::feed): e.g. the
  /// poll it answers (zerog-rt) or its time. 0 when none was given.
  std::uint64_t tag = 0;

  /// False when a critical status bit is set or any gauge is saturated.
  constexpr bool usable() const {
    return status_class != StatusClass::critical && saturated_mask == 0;
  }
};

/// Bit mask of the gauges at a rail (+32767 or −32768).
std::uint8_t saturated_gauges(const std::array<std::int16_t, kGaugeCount>& gauges);

enum class FeedResult : std::uint8_t {
  pending,           ///< first half (0x0) queued, waiting for its 0x1
  sample,            ///< a complete sample was written to `out`
  dropped_previous,  ///< the queue was full: its oldest half was dropped (counted), this one queued
  request,           ///< a zero-length 0x0 frame: a read request (our own, looped back)
  stray,             ///< not a 0x0/0x1 data frame of this board (counted, ignored)
  wrong_length,      ///< a 0x0/0x1 frame of the wrong length (counted, ignored)
  out_of_order,      ///< a 0x1 without a pending 0x0 (counted, ignored)
};

struct AssemblerCounters {
  std::uint64_t samples = 0;
  std::uint64_t stray = 0;
  std::uint64_t wrong_length = 0;
  std::uint64_t out_of_order = 0;
  /// First halves dropped before their 0x1 came: queue full, or drop_pending_before().
  std::uint64_t dropped_incomplete = 0;
  /// Samples whose 0x1 was overtaken by a later 0x0 (another half was queued behind theirs).
  std::uint64_t overtaken = 0;
  std::uint64_t requests = 0;
  std::uint64_t critical = 0;   ///< samples with a critical status bit
  std::uint64_t warning = 0;    ///< samples with only non-critical status bits
  std::uint64_t saturated = 0;  ///< samples with at least one saturated gauge
};

/// Assembles gauge samples from received frames, one frame at a time, pairing in order: the
/// board sends 0x0 then 0x1 per poll, but its 0x1 can be overtaken on the bus by the next poll's
/// 0x0 (the lower id wins arbitration while the 0x1 waits: A1 A2 B1 B2 with A = 0x0, B = 0x1,
/// digit = poll). So first halves wait in a FIFO of kPendingCapacity and each 0x1 completes the
/// oldest (proto/netcanoem.md). Real-time safe (fixed capacity, no allocation). A wrong-length
/// frame leaves the state untouched; timeouts and stale halves are the caller's (reset(),
/// drop_pending_before()).
class SampleAssembler {
 public:
  /// First halves waiting at most; one more drops the oldest (counted dropped_incomplete).
  static constexpr std::size_t kPendingCapacity = 4;

  explicit SampleAssembler(std::uint8_t base_id) : base_id_(base_id & kMaxBaseId) {}

  /// Feeds one frame. `out` is written only when the result is FeedResult::sample. `tag` is
  /// kept with a 0x0 half and handed back in GaugeSample::tag (ignored for other frames).
  FeedResult feed(const CanFrame& frame, GaugeSample& out, std::uint64_t tag = 0);
  /// Forgets all waiting first halves (not counted as dropped).
  void reset() { pending_count_ = 0; }
  /// Drops (and counts as dropped_incomplete) waiting first halves whose tag is below `tag`;
  /// returns how many.
  std::size_t drop_pending_before(std::uint64_t tag);
  bool pending() const { return pending_count_ != 0; }
  /// First halves waiting for their 0x1.
  std::size_t pending_count() const { return pending_count_; }
  const AssemblerCounters& counters() const { return counters_; }
  std::uint8_t base_id() const { return base_id_; }

 private:
  struct Half {
    std::uint16_t status = 0;
    std::array<std::int16_t, 3> even{};  // SG0, SG2, SG4
    std::uint64_t tag = 0;
  };
  std::uint8_t base_id_;
  std::array<Half, kPendingCapacity> pending_{};  // ring: oldest at pending_head_
  std::size_t pending_head_ = 0;
  std::size_t pending_count_ = 0;
  AssemblerCounters counters_;
};

// ---------------------------------------------------------------------------------------------
// Calibration and device information.

struct FirmwareVersion {
  std::uint8_t major = 0;
  std::uint8_t minor = 0;
  std::uint16_t build = 0;
  /// Opcode 0x7 (counts per unit) exists from firmware 3.7 on.
  constexpr bool has_counts() const { return major > 3 || (major == 3 && minor >= 7); }
};

/// Force unit codes (opcode 0x8, first byte), ATI's usual numbering.
enum class ForceUnit : std::uint8_t { lbf = 1, N = 2, klbf = 3, kN = 4, kgf = 5, gf = 6 };
/// Torque unit codes (opcode 0x8, second byte).
enum class TorqueUnit : std::uint8_t {
  lbf_in = 1,
  lbf_ft = 2,
  N_m = 3,
  N_mm = 4,
  kgf_cm = 5,
  kN_m = 6
};
/// N per force unit, or empty for an unknown code.
std::optional<double> newton_per_force_unit(std::uint8_t code);
/// N·m per torque unit, or empty for an unknown code.
std::optional<double> newton_metre_per_torque_unit(std::uint8_t code);

/// Everything the board tells about its active calibration.
struct Calibration {
  std::uint8_t active_calibration = 0;
  FirmwareVersion firmware;
  std::array<char, kSerialNumberLength + 1> serial_number{};  ///< NUL-terminated ASCII
  /// Rows Fx, Fy, Fz, Tx, Ty, Tz; columns SG0..SG5 (float32 on the wire).
  std::array<std::array<double, kGaugeCount>, kGaugeCount> matrix{};
  std::uint32_t counts_per_force = kDefaultCounts;
  std::uint32_t counts_per_torque = kDefaultCounts;
  bool counts_from_device = false;  ///< false: firmware < 3.7, the defaults above apply
  std::uint8_t force_unit = 0;      ///< ForceUnit code
  std::uint8_t torque_unit = 0;     ///< TorqueUnit code
};

enum class DecodeStatus : std::uint8_t {
  ok,
  wrong_id,      ///< not this board's frame for this opcode (or extended/remote/error frame)
  wrong_length,  ///< length differs from the response length
  bad_value,     ///< e.g. an echo that does not match, a non-finite coefficient
};

// Single-response decoders (board → host).
DecodeStatus decode_matrix_part(const CanFrame& frame, std::uint8_t base_id, int part,
                                std::array<double, 2>& coefficients);  ///< part 0–2 = 0x2–0x4
DecodeStatus decode_serial_number(const CanFrame& frame, std::uint8_t base_id,
                                  std::array<char, kSerialNumberLength + 1>& serial);
/// Checks the echo against `expected_index`; bad_value when it differs.
DecodeStatus decode_active_calibration(const CanFrame& frame, std::uint8_t base_id,
                                       std::uint8_t expected_index);
DecodeStatus decode_counts(const CanFrame& frame, std::uint8_t base_id, std::uint32_t& per_force,
                           std::uint32_t& per_torque);
DecodeStatus decode_units(const CanFrame& frame, std::uint8_t base_id, std::uint8_t& force_unit,
                          std::uint8_t& torque_unit);
DecodeStatus decode_firmware_version(const CanFrame& frame, std::uint8_t base_id,
                                     FirmwareVersion& version);
/// The 0x9 response: the requested channel's raw ADC reading (big-endian, read as unsigned 16
/// bit: UNVERIFIED, the manual we have says neither the signedness nor volts per count).
/// wrong_length for a frame of this id that is not 2 bytes long (a looped-back request is 1).
DecodeStatus decode_diagnostic_adc(const CanFrame& frame, std::uint8_t base_id,
                                   std::uint16_t& counts);
/// "ok", "wrong_id", "wrong_length", "bad_value": for messages.
const char* decode_status_name(DecodeStatus status);

// ---------------------------------------------------------------------------------------------
// Thermistor (0x9, DiagnosticIndex::thermistor) → temperature.

/// A linear map from the thermistor channel's raw counts to the sensor temperature:
/// T = celsius_at_zero_counts + celsius_per_count · counts. UNVERIFIED: no datasheet fact. ATI's
/// manual (as we have it) gives neither the ADC's volts per count nor the thermistor circuit,
/// so there is no default: the rig configuration gives both numbers (e.g. fitted to two
/// temperatures read with a reference thermometer), and without them the reading stays raw
/// counts (proto/netcanoem.md, "Thermistor").
struct ThermistorConversion {
  double celsius_at_zero_counts = 0.0;  ///< °C at 0 counts
  double celsius_per_count = 0.0;       ///< K per count; must not be 0
};
/// True when both numbers are finite and celsius_per_count is not 0.
bool thermistor_conversion_valid(const ThermistorConversion& conversion);
/// The one place counts become °C (the sensor, decode-can); the emulator uses the inverse
/// below. Real-time safe.
double thermistor_celsius(const ThermistorConversion& conversion, std::uint16_t counts);
/// The inverse, rounded to the nearest count: what the board sends at `celsius`; empty when the
/// conversion is invalid or the temperature maps outside 0–65535 counts.
std::optional<std::uint16_t> thermistor_counts(const ThermistorConversion& conversion,
                                               double celsius);

enum class ReadoutState : std::uint8_t { send_request, awaiting_response, done, failed };
enum class ReadoutError : std::uint8_t {
  none,
  bad_argument,   ///< base id or calibration index out of range
  echo_mismatch,  ///< the active-calibration echo differs from the request
  wrong_length,   ///< an expected response had the wrong length
  out_of_order,   ///< matrix responses not in the order 0x2, 0x3, 0x4
  bad_value,      ///< a non-finite matrix coefficient
};

/// Reads the device information and calibration: set active calibration (checked echo),
/// firmware version, serial number, the 6 matrix rows, counts per unit (only from firmware 3.7
/// on, else kDefaultCounts), units. Pure state machine; sending, receiving and timeouts are the
/// caller's:
///
///     while (readout.state() != done && != failed) {
///       if (readout.state() == send_request) send(readout.take_request());
///       else if (receive_with_timeout(frame)) readout.feed(frame); else readout.retry();
///     }
///
/// Frames of other ids, the 0x0/0x1 sample stream, our own looped-back request and unexpected
/// opcodes are ignored (counted in ignored_frames()). Real-time safe (but meant for start-up).
class CalibrationReadout {
 public:
  CalibrationReadout(std::uint8_t base_id, std::uint8_t calibration_index);

  ReadoutState state() const { return state_; }
  ReadoutError error() const { return error_; }
  /// The request to send now (meaningful in send_request); moves to awaiting_response.
  CanFrame take_request();
  /// Back to send_request for the current step (after a timeout).
  void retry();
  ReadoutState feed(const CanFrame& frame);
  /// Complete once state() == done.
  const Calibration& calibration() const { return calibration_; }
  std::uint32_t ignored_frames() const { return ignored_; }

 private:
  enum class Step : std::uint8_t { set_calibration, firmware, serial, matrix, counts, units };
  CanFrame current_request() const;
  void advance();
  ReadoutState fail(ReadoutError error);

  std::uint8_t base_id_;
  std::uint8_t index_;
  Step step_ = Step::set_calibration;
  std::uint8_t row_ = 0;   // matrix row being read
  std::uint8_t part_ = 0;  // next matrix part expected (0–2)
  ReadoutState state_ = ReadoutState::send_request;
  ReadoutError error_ = ReadoutError::none;
  CanFrame sent_{};
  Calibration calibration_;
  std::uint32_t ignored_ = 0;
};

/// wrench = diag(1/CpF ×3, 1/CpT ×3) · C · (SG − SG_bias): Fx, Fy, Fz in the calibration's force
/// unit, Tx, Ty, Tz in its torque unit (manual 9610-05-1030, "calculating F/T values").
/// `bias_gauges` are gauge readings of the unloaded sensor (raw counts, may be averaged).
std::array<double, 6> gauges_to_wrench(const Calibration& calibration,
                                       const std::array<std::int16_t, kGaugeCount>& gauges,
                                       const std::array<double, kGaugeCount>& bias_gauges);
/// As gauges_to_wrench, converted to N and N·m; empty when a unit code is unknown.
std::optional<std::array<double, 6>> gauges_to_wrench_si(
    const Calibration& calibration, const std::array<std::int16_t, kGaugeCount>& gauges,
    const std::array<double, kGaugeCount>& bias_gauges);

// ---------------------------------------------------------------------------------------------
// Responses (board → host), for emulators and tests. Empty when an argument is out of range.

/// The two sample frames (0x0 then 0x1) carrying `gauges` (SG0..SG5) and `status`.
std::optional<std::array<CanFrame, 2>> encode_sample(std::uint8_t base_id,
                                                     const std::array<std::int16_t, 6>& gauges,
                                                     std::uint16_t status);
/// The three frames (0x2, 0x3, 0x4) answering a read of one matrix row (float32 coefficients).
std::optional<std::array<CanFrame, 3>> encode_matrix_row(std::uint8_t base_id,
                                                         const std::array<double, 6>& row);
std::optional<CanFrame> encode_serial_number(std::uint8_t base_id,
                                             const std::array<char, kSerialNumberLength>& serial);
std::optional<CanFrame> encode_active_calibration(std::uint8_t base_id, std::uint8_t index);
std::optional<CanFrame> encode_counts(std::uint8_t base_id, std::uint32_t per_force,
                                      std::uint32_t per_torque);
std::optional<CanFrame> encode_units(std::uint8_t base_id, std::uint8_t force_unit,
                                     std::uint8_t torque_unit);
std::optional<CanFrame> encode_firmware_version(std::uint8_t base_id, FirmwareVersion version);
/// The 0x9 response carrying one diagnostic ADC reading (raw counts).
std::optional<CanFrame> encode_diagnostic_adc(std::uint8_t base_id, std::uint16_t counts);

}  // namespace zerog::proto::netcanoem
