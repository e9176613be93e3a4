// Smoke test for the vcan VM harness (tests/vm/run_in_vm.sh): a frame sent on a real
// SocketCAN raw socket must arrive, unchanged, on a second raw socket bound to the same
// interface. Natively (this host's kernel has no CAN) it skips; inside the VM
// (ZEROG_IN_VM=1) a missing interface is a harness failure, not a skip.

#include <gtest/gtest.h>

#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <string>

namespace {

std::string can_iface() {
  const char* env = std::getenv("ZEROG_CAN_IFACE");
  return (env != nullptr && *env != '\0') ? std::string(env) : std::string("vcan0");
}

bool in_vm() {
  const char* env = std::getenv("ZEROG_IN_VM");
  return env != nullptr && std::string(env) == "1";
}

// Owns one CAN_RAW socket bound to an interface.
class RawCanSocket {
 public:
  RawCanSocket() = default;
  RawCanSocket(const RawCanSocket&) = delete;
  RawCanSocket& operator=(const RawCanSocket&) = delete;
  ~RawCanSocket() {
    if (fd_ >= 0) ::close(fd_);
  }

  // Returns an empty string on success, otherwise what failed.
  std::string open(unsigned ifindex) {
    fd_ = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
    if (fd_ < 0) return std::string("socket(PF_CAN, SOCK_RAW, CAN_RAW): ") + std::strerror(errno);
    timeval timeout{};
    timeout.tv_sec = 2;  // a lost frame fails the test instead of hanging it
    if (::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout) != 0)
      return std::string("setsockopt(SO_RCVTIMEO): ") + std::strerror(errno);
    sockaddr_can addr{};
    addr.can_family = AF_CAN;
    addr.can_ifindex = static_cast<int>(ifindex);
    if (::bind(fd_, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) != 0)
      return std::string("bind: ") + std::strerror(errno);
    return {};
  }

  [[nodiscard]] int fd() const { return fd_; }

 private:
  int fd_ = -1;
};

class VcanSmoke : public ::testing::Test {
 protected:
  void SetUp() override {
    iface_ = can_iface();
    ifindex_ = ::if_nametoindex(iface_.c_str());
    if (ifindex_ == 0) {
      if (in_vm()) {
        FAIL() << "ZEROG_IN_VM=1 but CAN interface '" << iface_
               << "' does not exist: the VM harness did not set it up";
      }
      GTEST_SKIP() << "no CAN interface '" << iface_
                   << "' on this kernel (it has no vcan support); run this test through "
                      "tests/vm/run_in_vm.sh, e.g. ctest -L vm";
    }
    ASSERT_EQ(tx_.open(ifindex_), "");
    ASSERT_EQ(rx_.open(ifindex_), "");
  }

  // Sends `sent` on tx_ and expects the identical frame on rx_.
  void round_trip(const can_frame& sent) {
    const ssize_t written = ::write(tx_.fd(), &sent, sizeof sent);
    ASSERT_EQ(written, static_cast<ssize_t>(sizeof sent)) << "write: " << std::strerror(errno);

    can_frame got{};
    const ssize_t got_bytes = ::read(rx_.fd(), &got, sizeof got);
    ASSERT_EQ(got_bytes, static_cast<ssize_t>(sizeof got))
        << "read on the second socket: " << std::strerror(errno);
    EXPECT_EQ(got.can_id, sent.can_id);
    ASSERT_EQ(got.len, sent.len);
    for (unsigned i = 0; i < sent.len; ++i) {
      EXPECT_EQ(got.data[i], sent.data[i]) << "byte " << i;
    }
  }

  std::string iface_;
  unsigned ifindex_ = 0;
  RawCanSocket tx_;
  RawCanSocket rx_;
};

TEST_F(VcanSmoke, StandardFrameReachesSecondSocket) {
  can_frame frame{};
  frame.can_id = 0x123;
  frame.len = 8;
  const std::uint8_t payload[8] = {0xDE, 0xAD, 0xBE, 0xEF, 0x01, 0x02, 0x03, 0x04};
  std::memcpy(frame.data, payload, sizeof payload);
  round_trip(frame);
}

TEST_F(VcanSmoke, ExtendedFrameReachesSecondSocket) {
  can_frame frame{};
  frame.can_id = 0x1ABCDE0u | CAN_EFF_FLAG;
  frame.len = 3;
  frame.data[0] = 0x7F;
  frame.data[1] = 0x00;
  frame.data[2] = 0xA5;
  round_trip(frame);
}

}  // namespace
