#include "bag_import.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <random>
#include <stdexcept>
#include <vector>

namespace zerog::cli {
namespace {

namespace fs = std::filesystem;

const char* const kInstallHint =
    "run scripts/install-deps.sh (it installs PyPI's rosbags into the project's .venv; no ROS "
    "installation is needed)";

fs::path python_path() {
  if (const char* env = std::getenv("ZEROG_PYTHON")) return env;
  return ZEROG_VENV_PYTHON;
}

fs::path script_path() {
  if (const char* env = std::getenv("ZEROG_BAG_SCRIPT")) return env;
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed =
        self.parent_path().parent_path() / "share" / "zerog" / "bag_to_csv.py";
    if (fs::exists(installed)) return installed;
  }
  if (fs::exists(ZEROG_BAG_SCRIPT_BUILD)) return ZEROG_BAG_SCRIPT_BUILD;
  return ZEROG_BAG_SCRIPT_INSTALL;
}

fs::path make_temp_dir() {
  std::random_device rd;
  for (int attempt = 0; attempt < 16; ++attempt) {
    const fs::path d = fs::temp_directory_path() /
                       ("zerog_bag_" + std::to_string(::getpid()) + "_" + std::to_string(rd()));
    if (fs::create_directory(d)) return d;
  }
  throw std::runtime_error("cannot make a temporary directory for the bag's CSV files");
}

// Runs argv with stderr into `err_file`; returns the exit status (-1: did not exit normally).
int run(const std::vector<std::string>& args, const fs::path& err_file) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error("cannot fork to run " + args[0]);
  if (pid == 0) {
    if (std::freopen(err_file.c_str(), "w", stderr) == nullptr) _exit(126);
    execv(argv[0], argv.data());
    std::perror("exec");
    _exit(127);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::string s{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r')) s.pop_back();
  return s;
}

}  // namespace

BagConversion::BagConversion(const BagTopics& t, const fs::path& keep_dir) {
  if (!fs::exists(t.bag)) throw std::runtime_error(t.bag + ": no such bag");
  const fs::path python = python_path();
  if (!fs::exists(python))
    throw std::runtime_error("zerog import --bag reads bags with Python's rosbags, but " +
                             python.string() + " does not exist: " + kInstallHint);
  const fs::path script = script_path();
  if (!fs::exists(script))
    throw std::runtime_error("the bag converter " + script.string() + " is missing");
  if (keep_dir.empty()) {
    dir_ = make_temp_dir();
  } else {
    fs::create_directories(keep_dir);
    dir_ = keep_dir;
    remove_ = false;
  }
  std::vector<std::string> args = {python.string(), script.string(), "--bag",    t.bag,
                                   "--out",         dir_.string(),   "--wrench", t.wrench};
  if (!t.imu.empty()) args.insert(args.end(), {"--imu", t.imu});
  if (!t.joints.empty()) args.insert(args.end(), {"--joints", t.joints});
  if (!t.temperature.empty()) args.insert(args.end(), {"--temperature", t.temperature});
  if (!t.joint_names.empty()) args.insert(args.end(), {"--joint-names", t.joint_names});
  if (!t.tf.empty()) args.insert(args.end(), {"--tf", t.tf});
  if (!t.rig.empty()) args.insert(args.end(), {"--rig", t.rig});
  if (!t.robot.empty()) args.insert(args.end(), {"--robot", t.robot});
  if (!t.flange.empty()) args.insert(args.end(), {"--flange", t.flange});
  const fs::path err = dir_ / "bag_to_csv.err";
  const int status = run(args, err);
  const std::string message = read_text(err);
  std::error_code ec;
  fs::remove(err, ec);
  if (status == 0) {
    if (!message.empty()) std::fprintf(stderr, "%s\n", message.c_str());
    mapping_ = dir_ / "mapping.toml";
    return;
  }
  if (remove_) fs::remove_all(dir_, ec);
  if (status == 3)
    throw std::runtime_error(message +
                             "\nzerog import --bag needs Python's rosbags: " + kInstallHint);
  throw std::runtime_error(message.empty() ? "the bag converter failed (" + script.string() + ")"
                                           : message);
}

BagConversion::~BagConversion() {
  if (!remove_) return;
  std::error_code ec;
  fs::remove_all(dir_, ec);
}

}  // namespace zerog::cli
