// LockstepClient (proto/lockstep.md), zerog-rt's end of the lockstep with the emulated rig, against
// a plain unix datagram socket playing the emulator: hello and done carry what the emulator needs,
// events come through whole, anything else is a counted bad message, the guard bounds the wait,
// and wait/done do not allocate (they run in the cycle thread).
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>

#include "alloc_count.hpp"
#include "zerog/rtio/lockstep.hpp"

namespace zerog::rtio {
namespace {

using namespace std::chrono_literals;

// The emulator's end: bound at a path, answers whoever spoke last.
class Emulator {
 public:
  Emulator() {
    path_ = (std::filesystem::temp_directory_path() /
             ("zerog-lockstep-test-" + std::to_string(::getpid())))
                .string();
    ::unlink(path_.c_str());
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::memcpy(a.sun_path, path_.c_str(), path_.size());
    EXPECT_EQ(::bind(fd_, reinterpret_cast<const sockaddr*>(&a), sizeof a), 0);
  }
  ~Emulator() {
    ::close(fd_);
    ::unlink(path_.c_str());
  }
  const std::string& path() const { return path_; }
  // Receives one reply (blocking) and remembers its sender.
  LockstepReply receive() {
    LockstepReply r{};
    peer_length_ = sizeof peer_;
    const ssize_t n =
        ::recvfrom(fd_, &r, sizeof r, 0, reinterpret_cast<sockaddr*>(&peer_), &peer_length_);
    EXPECT_EQ(n, static_cast<ssize_t>(sizeof r));
    return r;
  }
  void send(const void* data, std::size_t size) {
    ASSERT_EQ(::sendto(fd_, data, size, 0, reinterpret_cast<const sockaddr*>(&peer_), peer_length_),
              static_cast<ssize_t>(size));
  }

 private:
  std::string path_;
  int fd_ = -1;
  sockaddr_un peer_{};
  socklen_t peer_length_ = 0;
};

TEST(Lockstep, OpenSaysWhyWhenNobodyListens) {
  LockstepClient client;
  const Status nobody = client.open("/nonexistent/zerog-lockstep");
  EXPECT_EQ(nobody.code(), StatusCode::system_error);
  EXPECT_EQ(nobody.text(), "no emulator listens there (connect failed: No such file or directory)");
  EXPECT_EQ(client.last_errno(), ENOENT);
  const Status too_long = client.open(std::string(200, 'x'));
  EXPECT_EQ(too_long.code(), StatusCode::invalid_setting);
  EXPECT_EQ(too_long.setting(), "path");
  EXPECT_EQ(too_long.text(), "path: is empty or longer than 107 bytes");
  EXPECT_EQ(client.open("").setting(), "path");
  LockstepEvent ev;
  EXPECT_EQ(client.wait(ev, 1ms), LockstepStatus::not_open);
}

TEST(Lockstep, HelloCarriesTheTimeoutsAndRateAndDoneTheReplies) {
  Emulator emu;
  LockstepClient client;
  ASSERT_EQ(client.open(emu.path()).text(), "");
  ASSERT_EQ(client.hello(18ms, 250.0, 3ms), LockstepStatus::ok);
  const LockstepReply hello = emu.receive();
  EXPECT_EQ(hello.magic, kLockstepMagic);
  EXPECT_EQ(hello.version, kLockstepVersion);
  EXPECT_EQ(hello.kind, LockstepKind::hello);
  EXPECT_EQ(hello.receive_timeout_ns, 18'000'000);
  EXPECT_EQ(hello.ft_rate_hz, 250.0);
  EXPECT_EQ(hello.ft_sample_timeout_ns, 3'000'000);
  ASSERT_EQ(client.done(7, 42), LockstepStatus::ok);
  const LockstepReply done = emu.receive();
  EXPECT_EQ(done.kind, LockstepKind::done);
  EXPECT_EQ(done.seq, 7u);
  EXPECT_EQ(done.replies_sent, 42u);
}

TEST(Lockstep, EventsComeWholeAndAnythingElseIsACountedBadMessage) {
  Emulator emu;
  LockstepClient client;
  ASSERT_EQ(client.open(emu.path()).text(), "");
  ASSERT_EQ(client.hello(18ms, 250.0, 3ms), LockstepStatus::ok);
  emu.receive();

  LockstepEvent sent;
  sent.kind = LockstepKind::timeout;
  sent.seq = 3;
  sent.time_ns = 36'000'000;
  sent.ft_samples = 9;
  sent.imu_bytes = 12345;
  sent.imu_epoch = 1;
  sent.imu_plugged = 0;
  sent.ft_answers = 0;
  emu.send(&sent, sizeof sent);
  LockstepEvent got;
  ASSERT_EQ(client.wait(got, 1s), LockstepStatus::ok);
  EXPECT_EQ(got.kind, LockstepKind::timeout);
  EXPECT_EQ(got.seq, 3u);
  EXPECT_EQ(got.time_ns, 36'000'000);
  EXPECT_EQ(got.ft_samples, 9u);
  EXPECT_EQ(got.imu_bytes, 12345u);
  EXPECT_EQ(got.imu_epoch, 1u);
  EXPECT_EQ(got.imu_plugged, 0u);
  EXPECT_EQ(got.ft_answers, 0u);

  emu.send(&sent, sizeof sent - 1);  // short
  EXPECT_EQ(client.wait(got, 1s), LockstepStatus::bad_message);
  LockstepEvent foreign = sent;
  foreign.magic = 0x12345678;
  emu.send(&foreign, sizeof foreign);
  EXPECT_EQ(client.wait(got, 1s), LockstepStatus::bad_message);
  LockstepEvent hello_kind = sent;
  hello_kind.kind = LockstepKind::hello;  // zerog-rt's kind, never the emulator's
  emu.send(&hello_kind, sizeof hello_kind);
  EXPECT_EQ(client.wait(got, 1s), LockstepStatus::bad_message);
  EXPECT_EQ(client.bad_messages(), 3u);
}

TEST(Lockstep, TheGuardBoundsTheWait) {
  Emulator emu;
  LockstepClient client;
  ASSERT_EQ(client.open(emu.path()).text(), "");
  LockstepEvent got;
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_EQ(client.wait(got, 30ms), LockstepStatus::timeout);
  const auto waited = std::chrono::steady_clock::now() - t0;
  EXPECT_GE(waited, 30ms);
  EXPECT_LT(waited, 5s);  // bounded (a generous bound: timings here are noisy)
}

TEST(Lockstep, WaitAndDoneDoNotAllocate) {
  Emulator emu;
  LockstepClient client;
  ASSERT_EQ(client.open(emu.path()).text(), "");
  ASSERT_EQ(client.hello(18ms, 250.0, 3ms), LockstepStatus::ok);
  emu.receive();
  LockstepEvent sent;
  sent.seq = 1;
  emu.send(&sent, sizeof sent);
  LockstepEvent got;
  const std::size_t before = test::allocation_count();
  const LockstepStatus waited = client.wait(got, 1s);
  const LockstepStatus done = client.done(got.seq, 1);
  const std::size_t after = test::allocation_count();
  EXPECT_EQ(waited, LockstepStatus::ok);
  EXPECT_EQ(done, LockstepStatus::ok);
  EXPECT_EQ(after, before);
}

}  // namespace
}  // namespace zerog::rtio
