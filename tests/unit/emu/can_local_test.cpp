// zerog-emu --can-local PATH (proto/emulator.md, "The F/T board's bus"): the program serves its
// F/T board on a LocalCanBus at PATH, where zerog-rt's NetcanoemSensor on a client reads the
// calibration and samples; a stale socket file is replaced, a served socket or a file that is no
// socket is refused, and the socket is gone after the run.
#include <gtest/gtest.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "zerog/rtio/local_can_bus.hpp"
#include "zerog/rtio/netcanoem_sensor.hpp"

namespace zerog::emu {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

class ZerogEmuCanLocal : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "zerog-emu-can-XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
    path_ = (dir_ / "can.sock").string();
    std::ofstream(dir_ / "scenario.toml") << "[robot]\ncycle_ms = 12\n";
    // Where the emulator sends its RSI datagrams: a bound port nobody reads.
    rt_fd_ = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    socklen_t length = sizeof a;
    ASSERT_EQ(::bind(rt_fd_, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    ::getsockname(rt_fd_, reinterpret_cast<sockaddr*>(&a), &length);
    rt_port_ = ntohs(a.sin_port);
  }
  void TearDown() override {
    if (rt_fd_ >= 0) ::close(rt_fd_);
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  /// zerog-emu's command line with `can_args`, its stderr to dir_/err.txt.
  std::string command(const std::string& can_args, double duration_s) const {
    return std::string(ZEROG_EMU_EXE) + " --scenario " + (dir_ / "scenario.toml").string() + " " +
           can_args +
           " --robot-bind 127.0.0.1:0 --rt-address 127.0.0.1:" + std::to_string(rt_port_) +
           " --duration " + std::to_string(duration_s) + " 2> " + (dir_ / "err.txt").string() +
           " < /dev/null";
  }
  std::string err_text() const {
    std::ifstream in(dir_ / "err.txt");
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
  }
  /// Runs zerog-emu to the end; its exit code.
  int run(const std::string& can_args) const {
    const int status = std::system(command(can_args, 0.5).c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  fs::path dir_;
  std::string path_;
  int rt_fd_ = -1;
  std::uint16_t rt_port_ = 0;
};

TEST_F(ZerogEmuCanLocal, ServesTheBoardAtThePathReplacingAStaleSocketAndUnlinksItAtExit) {
  {  // A socket file that nobody serves, as a killed zerog-emu leaves it.
    const int fd = ::socket(AF_UNIX, SOCK_DGRAM, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::memcpy(a.sun_path, path_.data(), path_.size());
    ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a), 0);
    ::close(fd);
    ASSERT_TRUE(fs::is_socket(path_));
  }
  // stdout is the pipe: "zerog-emu: ready", then the shell's "exit=N" after the run.
  FILE* out = ::popen((command("--can-local " + path_, 2.0) + "; echo exit=$?").c_str(), "r");
  ASSERT_NE(out, nullptr);
  char line[256] = {};
  ASSERT_NE(std::fgets(line, sizeof line, out), nullptr);
  EXPECT_STREQ(line, "zerog-emu: ready\n") << err_text();
  EXPECT_TRUE(fs::is_socket(path_));

  rtio::LocalCanBus bus;
  const rtio::CanOpenResult opened =
      bus.open_client(path_, rtio::NetcanoemSensor::socket_config(0x20));
  EXPECT_TRUE(opened.ok()) << rtio::can_open_status_name(opened.status);
  rtio::NetcanoemConfig config;
  config.sample_timeout = 200ms;  // a busy host must not fail the test
  rtio::NetcanoemSensor sensor(bus, config);
  EXPECT_EQ(sensor.start(), rtio::FtStartStatus::ok);
  EXPECT_STREQ(sensor.calibration().serial_number.data(), "FT42007A");
  rtio::FtSample s;
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(sensor.read_sample(s), rtio::FtReadStatus::sample) << i;
    EXPECT_TRUE(s.valid);
  }

  std::string rest;
  while (std::fgets(line, sizeof line, out) != nullptr) rest += line;
  ::pclose(out);
  EXPECT_NE(rest.find("exit=0"), std::string::npos) << rest << err_text();
  EXPECT_NE(err_text().find("F/T board 0x20 on local:" + path_), std::string::npos) << err_text();
  EXPECT_FALSE(fs::exists(path_)) << "the socket is unlinked at exit";
}

TEST_F(ZerogEmuCanLocal, RefusesAPathThatIsNoSocketOrThatAnotherProcessServes) {
  std::ofstream(path_) << "not a socket\n";
  EXPECT_EQ(run("--can-local " + path_), 1);
  EXPECT_NE(err_text().find("--can-local " + path_ +
                            ": exists and is not a socket; refusing to replace it"),
            std::string::npos)
      << err_text();
  EXPECT_TRUE(fs::is_regular_file(path_));

  fs::remove(path_);
  rtio::LocalCanBus other;
  ASSERT_TRUE(other.open_server(path_).ok());
  EXPECT_EQ(run("--can-local " + path_), 1);
  EXPECT_NE(err_text().find("another process serves this socket"), std::string::npos) << err_text();
  EXPECT_TRUE(fs::is_socket(path_)) << "the other server's socket stays";

  EXPECT_NE(run("--can vcan0 --can-local " + path_), 0);  // one bus or the other
  EXPECT_NE(err_text().find("excludes"), std::string::npos) << err_text();
}

}  // namespace
}  // namespace zerog::emu
