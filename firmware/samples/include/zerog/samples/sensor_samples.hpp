#pragma once
// The sensor samples the devices hand the cycle (proto/rtio.md): plain values in SI units,
// fixed size, trivially copyable, no I/O. zerog::rtio produces them (its devices and fakes name
// them rtio::FtSample, rtio::ImuSample) and zerog::loop consumes them, so the loop depends on
// these types, not on the device code.
#include <array>
#include <cstdint>

namespace zerog::samples {

enum class FtSampleStatus : std::uint8_t {
  ok,
  warning,    ///< non-critical status bits (e.g. the sensor's CAN bus error bit): usable
  critical,   ///< a critical status bit: the sample must not be used
  saturated,  ///< a gauge at its rail: the sample must not be used
};

/// One F/T sample. Fixed size, trivially copyable.
struct FtSample {
  /// Fx, Fy, Fz in N and Tx, Ty, Tz in N·m, in the sensor frame, bias subtracted. Computed even
  /// when !valid (for diagnosis); never use it then.
  std::array<double, 6> wrench_si{};
  std::array<std::int16_t, 6> gauges{};  ///< raw strain gauge counts SG0..SG5
  std::uint16_t status_word = 0;         ///< the sensor's raw status word
  FtSampleStatus status = FtSampleStatus::ok;
  std::uint8_t saturated_mask = 0;  ///< bit i: gauge i saturated
  bool valid = false;               ///< status is ok or warning
  /// When the frame that completed the sample arrived, CLOCK_MONOTONIC ns (0: unknown; proto/
  /// rtio.md, "When a sample arrived").
  std::int64_t arrived_ns = 0;
  std::uint64_t sequence = 0;  ///< +1 per sample returned by this device, from 1
  /// The sensor's own temperature, read between samples (NETCANOEM: the thermistor, opcode 0x9,
  /// about once a second; proto/netcanoem.md). thermistor_valid: a reading came since start-up
  /// (raw counts, whatever the configuration). temperature_valid: that reading converted to °C
  /// by the configured conversion (none configured: false, temperature_C unused).
  bool thermistor_valid = false;
  std::uint16_t thermistor_counts = 0;  ///< latest raw reading of the thermistor channel
  bool temperature_valid = false;
  double temperature_C = 0.0;  ///< sensor temperature of that reading, °C
  /// arrived_ns − arrival time of that reading, s (0 when either time is unknown).
  double temperature_age_s = 0.0;
  /// A temperature is expected (a conversion configured, reads on) but the latest reading is
  /// older than the device's maximum age (NETCANOEM: thermistor_max_age_polls sample requests;
  /// or none came that long after start-up): temperature_valid is false, the reading is not to
  /// be used any more. Cleared by the next reading.
  bool temperature_stale = false;
};

/// One IMU sample in SI units, in the IMU's axes. Fixed size, trivially copyable.
struct ImuSample {
  std::array<double, 3> rate_rad_s{};
  std::array<double, 3> accel_m_s2{};  ///< specific force, as the accelerometers measure it
  std::array<double, 3> incl_m_s2{};   ///< specific force along the inclinometer axes
  bool rate_valid = false;             ///< false: group absent or its status byte set
  bool accel_valid = false;
  bool incl_valid = false;
  std::uint8_t rate_status = 0;  ///< raw status bytes (any bit set: group invalid)
  std::uint8_t accel_status = 0;
  std::uint8_t incl_status = 0;
  std::uint8_t counter = 0;        ///< the device's datagram counter
  std::uint8_t missed_before = 0;  ///< datagrams lost right before this one (counter gap)
  double latency_s = 0.0;          ///< sampling → start of transmission, as the device reports
  /// When the bytes completing this sample were read, CLOCK_MONOTONIC ns (0: unknown; proto/
  /// rtio.md, "When a sample arrived").
  std::int64_t arrived_ns = 0;
  std::uint64_t sequence = 0;  ///< +1 per sample returned by this device, from 1
};

}  // namespace zerog::samples
