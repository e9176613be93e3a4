// `zerog export-mcap`: a zerog-rt recording (--record DIR) as one MCAP file with ROS 2's message
// types, the rig (and the model) attached (proto/ros2_bags.md, "MCAP from a recording"). The work
// is host/io/record_to_mcap.py, run with the project's venv python (PyPI's mcap and rosbags).
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "commands.hpp"

namespace zerog::cli {

namespace {

namespace fs = std::filesystem;

fs::path mcap_python() {
  if (const char* env = std::getenv("ZEROG_PYTHON")) return env;
  return ZEROG_VENV_PYTHON;
}

// $ZEROG_MCAP_SCRIPT, else the installed script beside the binary's share/, else the source
// tree's (a build tree), else the install prefix's.
fs::path mcap_script() {
  if (const char* env = std::getenv("ZEROG_MCAP_SCRIPT")) return env;
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed =
        self.parent_path().parent_path() / "share" / "zerog" / "record_to_mcap.py";
    if (fs::exists(installed)) return installed;
  }
  if (fs::exists(ZEROG_MCAP_SCRIPT_BUILD)) return ZEROG_MCAP_SCRIPT_BUILD;
  return ZEROG_MCAP_SCRIPT_INSTALL;
}

}  // namespace

void add_export_mcap_command(CLI::App& app) {
  struct Args {
    std::string record, out, model, ns = "/zerog", base = "base_link", sensor = "ft_sensor",
                                    imu = "imu_link", joints;
    bool force = false;
  };
  auto a = std::make_shared<Args>();
  CLI::App* s = app.add_subcommand(
      "export-mcap",
      "A zerog-rt recording (its --record folder) as one MCAP file with ROS 2's message types: "
      "every cycle on the rt/ topics' types, the sensor pose on /tf, the IMU's mounting on "
      "/tf_static, the rig (and --model) attached; `zerog import --bag FILE` reads it back "
      "(proto/ros2_bags.md, \"MCAP from a recording\")");
  s->add_option("record", a->record, "zerog-rt's --record folder (cycles.csv, run.rig.toml)")
      ->required()
      ->check(CLI::ExistingDirectory);
  s->add_option("-o,--out", a->out, "The MCAP file (default: RECORD/run.mcap, beside the input)");
  s->add_flag("--force", a->force, "Write over an existing output file");
  s->add_option("--model", a->model, "The deployed model zerog-rt ran, attached byte for byte")
      ->check(CLI::ExistingFile);
  s->add_option("--namespace", a->ns, "ROS namespace of the topics")->capture_default_str();
  s->add_option("--base-frame", a->base, "frame_id of the base frame")->capture_default_str();
  s->add_option("--sensor-frame", a->sensor, "frame_id of the F/T sensor frame S")
      ->capture_default_str();
  s->add_option("--imu-frame", a->imu, "frame_id of the IMU frame I")->capture_default_str();
  s->add_option("--joint-names", a->joints,
                "JointState names of A1..A6, comma separated (default joint_a1,…,joint_a6)");
  s->callback([a] {
    const fs::path python = mcap_python();
    if (!fs::exists(python))
      throw std::runtime_error(
          "zerog export-mcap writes MCAP with Python's mcap and rosbags, but " + python.string() +
          " does not exist: run scripts/install-deps.sh (no ROS installation "
          "is needed)");
    const fs::path script = mcap_script();
    if (!fs::exists(script))
      throw std::runtime_error("the MCAP writer " + script.string() + " is missing");
    std::vector<std::string> args = {python.string(), script.string(), a->record, "--namespace",
                                     a->ns,           "--base-frame",  a->base,   "--sensor-frame",
                                     a->sensor,       "--imu-frame",   a->imu};
    if (!a->out.empty()) args.insert(args.end(), {"--out", a->out});
    if (a->force) args.emplace_back("--force");
    if (!a->model.empty()) args.insert(args.end(), {"--model", a->model});
    if (!a->joints.empty()) args.insert(args.end(), {"--joint-names", a->joints});
    std::vector<char*> argv;
    for (const std::string& arg : args) argv.push_back(const_cast<char*>(arg.c_str()));
    argv.push_back(nullptr);
    std::fflush(stdout);
    std::fflush(stderr);
    execv(argv[0], argv.data());  // returns only on failure
    throw std::runtime_error("cannot run " + python.string() + ": " + std::strerror(errno));
  });
}

}  // namespace zerog::cli
