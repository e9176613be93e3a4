// zerog-rt's configuration file (proto/rt_config.md), parsed at start-up of the program that moves
// the robot. parse_config throws rt::ConfigError (file, key, line, column, why); any other
// exception, a crash or a hang is a finding.
//
// Properties: an accepted configuration has the checked ranges the loop relies on (positive
// mass, RSI cycle of 4 or 12 ms, finite limits), and parsing the same text again gives the same
// result (no hidden state).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>

#include "fuzz_util.hpp"
#include "zerog/rt/config.hpp"

namespace rt = zerog::rt;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // The file need not exist: parse_config only anchors relative paths at its folder.
  const auto path = zerog::fuzz::scratch_dir() / "zerog-rt.toml";
  const std::string text(zerog::fuzz::as_text(data, size));
  rt::RtConfig config;
  try {
    config = rt::parse_config(text, path);
  } catch (const rt::ConfigError& e) {
    ZEROG_FUZZ_CHECK(e.what() != nullptr && e.what()[0] != '\0');
    return 0;
  }
  ZEROG_FUZZ_CHECK(config.robot.cycle_ms == 4 || config.robot.cycle_ms == 12);
  ZEROG_FUZZ_CHECK(std::isfinite(config.body.mass_kg) && config.body.mass_kg > 0.0);
  ZEROG_FUZZ_CHECK(config.body.inertia_body_kgm2.allFinite());
  ZEROG_FUZZ_CHECK(config.com_sensor_m.allFinite());
  ZEROG_FUZZ_CHECK(std::isfinite(config.temperature_C));
  ZEROG_FUZZ_CHECK(std::isfinite(config.robot.receive_timeout_ms) &&
                   config.robot.receive_timeout_ms > 0.0);
  ZEROG_FUZZ_CHECK(config.ft.base_id >= 0 && config.ft.base_id <= 127);
  ZEROG_FUZZ_CHECK(config.ft.calibration >= 0 && config.ft.calibration <= 15);
  ZEROG_FUZZ_CHECK(std::isfinite(config.ft.rate_hz) && config.ft.rate_hz > 0.0);
  ZEROG_FUZZ_CHECK(!config.model_file.empty() && !config.rig_file.empty());

  const rt::RtConfig again = rt::parse_config(text, path);
  ZEROG_FUZZ_CHECK(again.model_file == config.model_file && again.rig_file == config.rig_file);
  ZEROG_FUZZ_CHECK(again.body.mass_kg == config.body.mass_kg);
  (void)rt::cycle_config(config);
  return 0;
}
