#pragma once
// Shared by the zerog::rt tests (and rtio_bench): the loop's fixtures (payload model, cycle
// configuration, static robot, push: tests/unit/loop/loop_fixtures.hpp) with the payload model
// fitted for a real rig and written as files for the configuration, and a temporary folder.
// Test code; header-only.
#include <stdlib.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "../loop/loop_fixtures.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/infer/deploy_file.hpp"
#include "zerog/rt/setup.hpp"

namespace zerog::rt::test {

namespace fs = std::filesystem;

using loop::test::kMass;
using loop::test::kPeriod;
using loop::test::push;
using loop::test::StaticRobot;
using loop::test::test_cycle_config;

class TempDir {
 public:
  TempDir() {
    std::string pattern = (fs::temp_directory_path() / "zerog-rt-test-XXXXXX").string();
    if (::mkdtemp(pattern.data()) != nullptr) path_ = pattern;
  }
  ~TempDir() {
    std::error_code ec;
    if (!path_.empty()) fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const fs::path& path() const { return path_; }

 private:
  fs::path path_;
};

inline std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

inline void write_text(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary);
  out << text;
}

/// The rig of the sample configuration (firmware/rt/zerog-rt.sample.toml names its files).
inline formats::Rig test_rig() {
  formats::Rig rig;
  rig.name = "kr210-omega191-stim300";
  rig.robot = "KR 210 R2700";
  rig.flange_sensor.p_m = {0.0, 0.0, 0.06};
  rig.sensor_imu.p_m = {0.0, 0.0, -0.03};
  rig.sample_period_s = kPeriod;
  rig.floor_z_m = -0.675;
  return rig;
}

/// The loop's payload model, fitted for `rig` (its poses) at the rig's sample period.
inline infer::DeployedModel payload_model(const formats::Rig& rig = test_rig()) {
  return loop::test::payload_model(running_rig(rig, rig.sample_period_s));
}

/// Writes `deploy.zgm` and `rig.rig.toml` (the sample configuration's names) into `dir`.
inline void write_model_and_rig(const fs::path& dir, const formats::Rig& rig = test_rig()) {
  write_text(dir / "deploy.zgm", infer::serialise_deployed_model(payload_model(rig)));
  formats::write_rig(rig, dir / "rig.rig.toml");
}

}  // namespace zerog::rt::test
