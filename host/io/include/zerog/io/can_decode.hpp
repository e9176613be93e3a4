#pragma once
// `zerog decode-can`: recorded CAN traffic (can-utils `candump -L` text) of an ATI NETCANOEM
// F/T sensor → wrenches in N and N·m (proto/netcanoem.md). The calibration comes from the
// start-up read-out recorded in the log (matrix rows, counts, units), or from a file.
// Other traffic on the bus is ignored; every sample that cannot be used is counted.
#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "zerog/proto/netcanoem.hpp"

namespace zerog::io {

struct CanDecodeOptions {
  std::uint8_t base_id = 0x20;  ///< the board's 7-bit base id (CAN id = base << 4 | opcode)
  /// Use this calibration instead of the one recorded in the log.
  std::optional<proto::netcanoem::Calibration> calibration;
  std::array<double, proto::netcanoem::kGaugeCount> bias_gauges{};  ///< SG_bias, raw counts
};

struct DecodedWrench {
  double t_s = 0.0;                ///< candump timestamp of the second (0x1) response
  std::array<double, 6> wrench{};  ///< Fx Fy Fz (N), Mx My Mz (N·m), sensor frame
  std::uint16_t status = 0;        ///< raw status word (non-critical bits may be set)
};

struct CanDecodeResult {
  proto::netcanoem::Calibration calibration;
  bool calibration_from_log = false;
  std::vector<DecodedWrench> samples;            ///< usable samples only
  proto::netcanoem::AssemblerCounters counters;  ///< stray, wrong length, critical, saturated…
  std::size_t records = 0;                       ///< frames in the log
  std::size_t other_traffic = 0;                 ///< frames of other ids (ignored)
  std::size_t unusable = 0;  ///< samples dropped: critical status or saturated gauge
};

/// Decodes a candump log. Throws io::InputError (file, line, column) on a malformed line, and
/// std::runtime_error when the log holds no complete calibration and none is given.
CanDecodeResult decode_netcanoem_log(const std::filesystem::path& candump,
                                     const CanDecodeOptions& options);

/// Writes the usable samples as an F/T recording (`# zerog-ft 1`, columns t_s, Fx_N … Mz_Nm,
/// status) that `zerog import` merges with pose and IMU recordings; atomic, never over an input.
void write_ft_recording(const CanDecodeResult& result, const std::filesystem::path& out,
                        const std::vector<std::filesystem::path>& inputs);

}  // namespace zerog::io
