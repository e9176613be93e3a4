#include "zerog/rt/setup.hpp"

#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <system_error>

#include "zerog/formats/design_csv.hpp"
#include "zerog/infer/deploy_file.hpp"
#include "zerog/status.hpp"

namespace zerog::rt {

namespace fs = std::filesystem;

infer::RigDescription running_rig(const formats::Rig& rig, double cycle_period_s) {
  infer::RigDescription out;
  out.name = rig.name;
  out.robot = rig.robot;
  out.p_flange_sensor_m = rig.flange_sensor.p_m;
  out.q_flange_sensor = rig.flange_sensor.q;
  out.p_sensor_imu_m = rig.sensor_imu.p_m;
  out.q_sensor_imu = rig.sensor_imu.q;
  out.sample_period_s = cycle_period_s;
  return out;
}

namespace {

// A missing or unreadable file named by the configuration: say which key names it and why.
void check_input(const fs::path& path, const char* key, const fs::path& config) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  std::string why;
  if (ec || !fs::exists(st)) {
    why = ec && ec != std::errc::no_such_file_or_directory ? ec.message() : "no such file";
  } else if (!fs::is_regular_file(st)) {
    why = "not a regular file";
  } else if (::access(path.c_str(), R_OK) != 0) {
    why = std::error_code(errno, std::generic_category()).message();
  }
  if (!why.empty()) {
    throw std::runtime_error(path.string() + ": " + why + " (" + key + " in " + config.string() +
                             ")");
  }
}

}  // namespace

Setup load_setup(const RtConfig& config) {
  Setup s;
  s.config = config;
  check_input(config.rig_file, "[rig] file", config.file);
  check_input(config.model_file, "[model] file", config.file);
  try {
    s.rig = formats::read_rig(config.rig_file);
  } catch (const formats::InputError& e) {
    throw std::runtime_error(std::string("[rig] file: ") + e.what());
  }
  const double period_s = config.robot.cycle_s();
  s.rig.sample_period_s = period_s;
  infer::LoadResult loaded =
      infer::load_deployed_model_file(config.model_file, running_rig(s.rig, period_s));
  if (!loaded.ok()) {
    std::string why = loaded.message;
    if (loaded.error == infer::LoadError::wrong_rig &&
        why.find("sample period") != std::string::npos) {
      why +=
          " (the model's rows are robot cycles: a model fitted at one row period runs only "
          "with an RSI cycle of that period; [robot] cycle_ms = " +
          std::to_string(config.robot.cycle_ms) + " in " + config.file.string() + ")";
    } else if (loaded.error == infer::LoadError::wrong_rig) {
      why += " (running rig: " + config.rig_file.string() + ")";
    }
    throw std::runtime_error("[model] file: " + why);
  }
  s.model = std::move(*loaded.model);
  {
    std::ifstream in(config.model_file, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    s.model_file_crc32 = infer::crc32(bytes);
  }
  s.cycle = cycle_config(config);
  // The rig's robot (its flange_sensor is the rig's): the pose from AIPos without RIst, and the
  // check of RIst (proto/rt_config.md, "[robot]").
  s.cycle.robot = s.rig.robot_model;
  s.cycle.motion.imu_rate_hz = s.rig.imu_rate_hz;
  // The loop's own checks, on a scratch cycle (configure takes the model). The configuration's
  // own fields passed them when the file was read (rt/config.cpp names the key); what is new
  // here is the rig's robot and the model.
  auto scratch = std::make_unique<loop::Cycle>();
  if (const Status st = scratch->configure(s.cycle, s.model); !st.ok()) {
    if (st.setting() == "robot" || st.setting().starts_with("robot.")) {
      throw std::runtime_error("[rig] file: " + config.rig_file.string() +
                               ": the loop refuses the rig's robot: " + st.text());
    }
    throw std::runtime_error(config.file.string() +
                             ": the loop refuses the configuration: " + st.text());
  }
  return s;
}

PtpJointPath::PtpJointPath(std::vector<robot::JointVector6> points_rad, double speed_fraction,
                           double dwell_s)
    : trajectory_(std::move(points_rad), robot::kr210_ptp_limits(speed_fraction), dwell_s) {}

std::unique_ptr<PtpJointPath> load_collection_path(const fs::path& design,
                                                   const CollectionSection& settings) {
  std::vector<formats::DesignPoint> points = formats::read_design(design);
  if (points.empty()) throw std::runtime_error(design.string() + ": the design has no points");
  return std::make_unique<PtpJointPath>(std::move(points), settings.speed_fraction,
                                        settings.dwell_s);
}

}  // namespace zerog::rt
