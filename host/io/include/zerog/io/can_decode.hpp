#pragma once
// `zerog decode-can`: recorded CAN traffic (can-utils candump text: the -L log-file form or the
// default screen output, with or without -ta/-tz/-td/-tA timestamps; io/candump.hpp) of an
// ATI NETCANOEM F/T sensor → wrenches in N and N·m (proto/netcanoem.md). The calibration comes from
// the start-up read-out recorded in the log (matrix rows, counts, units), or from a file. Other
// traffic on the bus is ignored; every sample that cannot be used is counted.
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "zerog/io/candump.hpp"
#include "zerog/proto/netcanoem.hpp"

namespace zerog::io {

struct CanDecodeOptions {
  std::uint8_t base_id = 0x20;  ///< the board's 7-bit base id (CAN id = base << 4 | opcode)
  /// Use this calibration instead of the one recorded in the log.
  std::optional<proto::netcanoem::Calibration> calibration;
  std::array<double, proto::netcanoem::kGaugeCount> bias_gauges{};  ///< SG_bias, raw counts
  /// How to read the log's timestamps (default: decided from the log).
  io::CandumpClock clock = io::CandumpClock::automatic;
  /// The sensor's sample rate, Hz, for a log without timestamps (candump's default output):
  /// the k-th complete sample (usable or not) gets t = k / rate. Refused for a log with times.
  std::optional<double> assume_rate_hz;
  /// Thermistor counts → °C (proto::netcanoem::ThermistorConversion; UNVERIFIED, no default).
  /// Without it the thermistor readings are written as raw counts only, and no temp_C.
  std::optional<proto::netcanoem::ThermistorConversion> thermistor;
};

/// One thermistor reading (opcode 0x9 answer to a request for diagnostic index 2).
struct ThermistorReading {
  double t_s = 0.0;  ///< time of the answer, on the samples' clock
  std::uint16_t counts = 0;
};

struct DecodedWrench {
  /// Time of the second (0x1) response, s: on the log's clock (since 1970 for -L/-ta/-tA,
  /// since the first frame for -tz/-td), or k / assume_rate_hz without timestamps.
  double t_s = 0.0;
  std::array<double, 6> wrench{};  ///< Fx Fy Fz (N), Mx My Mz (N·m), sensor frame
  std::uint16_t status = 0;        ///< raw status word (non-critical bits may be set)
  /// The thermistor reading that goes with the sample: the latest at or before it, or the first
  /// one for samples before any (empty when the log has none).
  std::optional<std::uint16_t> thermistor_counts;
  std::optional<double> temperature_C;  ///< that reading in °C (only with a conversion)
};

/// The 0x9 (diagnostic ADC) traffic of the board: requests name a channel, the next answer is
/// that channel's reading (the answer itself does not say which).
struct DiagnosticCounters {
  std::size_t requests = 0;             ///< 0x9 requests (1 byte), any index
  std::size_t thermistor_readings = 0;  ///< answers to a thermistor (index 2) request: used
  std::size_t other_channel = 0;  ///< answers to a request of another known index (0–5): ignored
  std::size_t unknown_index = 0;  ///< requests of an index above 5: counted, answers ignored
  std::size_t unanswered = 0;     ///< requests followed by another request before an answer
  std::size_t unrequested = 0;    ///< answers with no request open: channel unknown, ignored
  std::size_t wrong_length = 0;   ///< 0x9 frames of neither 1 nor 2 bytes
};

struct CanDecodeResult {
  proto::netcanoem::Calibration calibration;
  bool calibration_from_log = false;
  std::vector<DecodedWrench> samples;            ///< usable samples only
  proto::netcanoem::AssemblerCounters counters;  ///< stray, wrong length, critical, saturated…
  std::size_t records = 0;                       ///< frames in the log
  std::size_t other_traffic = 0;                 ///< frames of other ids (ignored)
  std::size_t unusable = 0;  ///< samples dropped: critical status or saturated gauge
  /// Samples dropped because the run of pairings they belong to never emptied the queue of
  /// waiting 0x0 halves (a 0x1 lost somewhere, or the log ended): they may mix two polls.
  std::size_t unconfirmed = 0;
  io::CandumpLogInfo log;     ///< the log's form and clock (and why), frames, CAN FD frames
  bool time_assumed = false;  ///< t_s from assume_rate_hz (the log has no time)
  std::vector<ThermistorReading> thermistor;  ///< every thermistor reading, in log order
  DiagnosticCounters diagnostic;
  bool temperature_converted = false;  ///< thermistor readings and a conversion: temp_C written
};

/// Pairings in a row that may leave 0x0 halves waiting before decode_netcanoem_log takes a 0x1
/// for lost (proto/netcanoem.md, "pairing in order").
inline constexpr std::size_t kMaxUnconfirmedRun = 32;

/// Decodes a candump log. 0x0 and 0x1 responses are paired in order (a 0x1 overtaken by later
/// polls' 0x0 still completes its own 0x0; proto::netcanoem::SampleAssembler). Throws
/// formats::InputError (file, line, column) on a malformed line or a line in another form than the
/// log's first, and std::runtime_error when the log holds no complete calibration and none is
/// given, or has no timestamps and no assume_rate_hz (or has timestamps and an assume_rate_hz). CAN
/// FD frames are skipped (counted in `log.fd_frames`).
CanDecodeResult decode_netcanoem_log(const std::filesystem::path& candump,
                                     const CanDecodeOptions& options);

/// Writes the usable samples as an F/T recording (`# zerog-ft 1`, columns t_s, Fx_N … Mz_Nm,
/// status; then thermistor_counts when the log holds thermistor readings, and temp_C (°C) when
/// they were converted) that `zerog import` merges with pose and IMU recordings; atomic, never
/// over an input.
void write_ft_recording(const CanDecodeResult& result, const std::filesystem::path& out,
                        const std::vector<std::filesystem::path>& inputs);

}  // namespace zerog::io
