#include "report_script.hpp"

#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>

namespace zerog::cli {
namespace {

namespace fs = std::filesystem;

fs::path report_script() {
  if (const char* env = std::getenv("ZEROG_REPORT_SCRIPT")) return env;
  // Installed layout first (…/bin/zerog → …/share/zerog), then the source tree of this build.
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path installed =
        self.parent_path().parent_path() / "share" / "zerog" / "make_report.py";
    if (fs::exists(installed)) return installed;
  }
  if (fs::exists(ZEROG_REPORT_SCRIPT_BUILD)) return ZEROG_REPORT_SCRIPT_BUILD;
  return ZEROG_REPORT_SCRIPT_INSTALL;
}

}  // namespace

void run_report_script(const std::vector<std::string>& args) {
  // Debian's python3 has python3-matplotlib; a python3 earlier on PATH may not.
  const std::string python = fs::exists("/usr/bin/python3") ? "/usr/bin/python3" : "python3";
  const std::string script = report_script().string();
  // Its interactive page (interactive_report.py) needs plotly, a PyPI package in the project's
  // .venv (scripts/install-deps.sh): make_report.py runs that part with $ZEROG_PYTHON, the venv's
  // python as for `zerog import --bag` (bag_import.cpp), unless the user named another.
  ::setenv("ZEROG_PYTHON", ZEROG_VENV_PYTHON, /*overwrite=*/0);
  std::vector<char*> argv;
  argv.push_back(const_cast<char*>(python.c_str()));
  argv.push_back(const_cast<char*>(script.c_str()));
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  std::fflush(stdout);
  const pid_t pid = fork();
  if (pid < 0) throw std::runtime_error("cannot fork to run " + script);
  if (pid == 0) {
    execvp(argv[0], argv.data());
    std::perror("zerog: cannot run python3");
    _exit(127);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw std::runtime_error("the report script " + script + " failed; nothing written");
}

}  // namespace zerog::cli
