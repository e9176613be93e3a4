// The log CSV (proto/log_format.md) as `zerog fit`, compare, diagnose … read it: read_log on a
// fuzzed `NAME.csv` beside a valid rig sidecar (rig_toml_fuzz covers the sidecar). read_log
// throws formats::InputError naming file, line and column; any other exception, a crash or a hang
// is a finding.
//
// Property: a log that reads writes back (write_log: t_s exact, other values to 9 significant
// digits) and reads again to the same samples within that precision.
#include <cstddef>
#include <cstdint>

#include "fuzz_util.hpp"
#include "io_compare.hpp"
#include "zerog/formats/log.hpp"

namespace formats = zerog::formats;
using zerog::fuzz::near;
using zerog::fuzz::near_rotation;
using zerog::fuzz::near_vec;

namespace {

constexpr const char* kRig = R"(format = "zerog-rig"
version = 1
name = "fuzz"
robot = "KR 210 R2700"
sample_period_s = 0.012
[flange_sensor]
p_m = [0.0, 0.0, 0.06]
q_wxyz = [1.0, 0.0, 0.0, 0.0]
[sensor_imu]
p_m = [0.0, 0.0, -0.03]
q_wxyz = [1.0, 0.0, 0.0, 0.0]
)";

constexpr double k9Digits = 1e-8;  // 9 significant digits, plus the reader's rounding

bool same_sample(const formats::Sample& a, const formats::Sample& b,
                 const formats::Columns& columns) {
  if (a.t_s != b.t_s) return false;  // written in shortest round-trip form
  if (columns.joints) {
    for (int j = 0; j < 6; ++j)
      if (!near(a.joints_rad[j], b.joints_rad[j], 1e-300, k9Digits)) return false;
  }
  if (columns.specific_force &&
      !near_vec(a.specific_force_imu_mps2, b.specific_force_imu_mps2, k9Digits))
    return false;
  if (columns.angular_rate &&
      !near_vec(a.angular_rate_imu_radps, b.angular_rate_imu_radps, k9Digits))
    return false;
  if (columns.temperature && !near(a.temperature_C, b.temperature_C, 1e-300, k9Digits))
    return false;
  return near_vec(a.p_base_sensor_m, b.p_base_sensor_m, k9Digits) &&
         near_rotation(a.q_base_sensor, b.q_base_sensor, 1e-8) &&
         near_vec(a.force_sensor_N, b.force_sensor_N, k9Digits) &&
         near_vec(a.torque_sensor_Nm, b.torque_sensor_Nm, k9Digits);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto& dir = zerog::fuzz::scratch_dir();
  const auto csv = dir / "input.csv";
  static const bool rig_written = [&] {
    zerog::fuzz::write_bytes(formats::rig_path_for(csv), kRig);
    return true;
  }();
  (void)rig_written;
  zerog::fuzz::write_bytes(csv, zerog::fuzz::as_text(data, size));
  formats::Log log;
  try {
    log = formats::read_log(csv);
  } catch (const formats::InputError&) {
    return 0;
  }
  for (std::size_t i = 1; i < log.samples.size(); ++i)
    ZEROG_FUZZ_CHECK(log.samples[i].t_s > log.samples[i - 1].t_s);

  const auto again = dir / "again.csv";
  formats::write_log(log, again, {csv});
  const formats::Log back = formats::read_log(again);
  ZEROG_FUZZ_CHECK(back.columns == log.columns);
  ZEROG_FUZZ_CHECK(back.samples.size() == log.samples.size());
  for (std::size_t i = 0; i < log.samples.size(); ++i)
    ZEROG_FUZZ_CHECK(same_sample(log.samples[i], back.samples[i], log.columns));
  return 0;
}
