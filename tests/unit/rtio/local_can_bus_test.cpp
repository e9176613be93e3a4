// LocalCanBus: classic CAN frames over an AF_UNIX datagram socket (the transport zerog-rt and
// zerog-emu use on a kernel without CAN). Round trips both ways with every kind of identifier,
// the wire layout (Linux struct can_frame), error frames by class, bad lengths sent with a raw
// socket, the user-space filters and error mask, timeouts, a missing or vanished peer, open
// failures, no allocation in read/write, and NetcanoemSensor against emu::AtiBoard end to end.
#include "zerog/rtio/local_can_bus.hpp"

#include <gtest/gtest.h>
#include <linux/can.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "alloc_count.hpp"
#include "zerog/emu/ati_board.hpp"
#include "zerog/proto/netcanoem.hpp"
#include "zerog/rtio/netcanoem_sensor.hpp"

namespace zerog::rtio {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

std::int64_t monotonic_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

proto::CanFrame make_frame(std::uint32_t id, std::uint8_t len, std::uint8_t first = 0x10) {
  proto::CanFrame f;
  f.id = id;
  f.len = len;
  for (std::uint8_t i = 0; i < len; ++i) f.data[i] = static_cast<std::uint8_t>(first + i);
  return f;
}

sockaddr_un unix_address(const std::string& path) {
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  std::memcpy(a.sun_path, path.data(), path.size());
  return a;
}

/// A plain AF_UNIX datagram socket for what LocalCanBus never sends: datagrams of the wrong size.
/// Unbound (an unnamed sender) unless `bind_path` is given, then it plays a server.
class RawSocket {
 public:
  explicit RawSocket(const std::string& bind_path = {}) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (!bind_path.empty()) {
      const sockaddr_un a = unix_address(bind_path);
      if (::bind(fd_, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0) {
        ::close(fd_);
        fd_ = -1;
      }
    }
  }
  ~RawSocket() {
    if (fd_ >= 0) ::close(fd_);
  }
  RawSocket(const RawSocket&) = delete;
  RawSocket& operator=(const RawSocket&) = delete;
  bool ok() const { return fd_ >= 0; }

  /// Sends `bytes` to `path`.
  bool send_to(const std::string& path, const void* bytes, std::size_t size) const {
    const sockaddr_un a = unix_address(path);
    return ::sendto(fd_, bytes, size, 0, reinterpret_cast<const sockaddr*>(&a), sizeof a) ==
           static_cast<ssize_t>(size);
  }
  /// Receives one datagram (waiting up to 1 s) and remembers its sender; its bytes.
  std::vector<unsigned char> receive() {
    timeval tv{1, 0};
    ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    std::vector<unsigned char> bytes(64);
    from_length_ = sizeof from_;
    const ssize_t n = ::recvfrom(fd_, bytes.data(), bytes.size(), 0,
                                 reinterpret_cast<sockaddr*>(&from_), &from_length_);
    bytes.resize(n > 0 ? static_cast<std::size_t>(n) : 0);
    return bytes;
  }
  /// Sends `bytes` to the sender of the last receive().
  bool reply(const void* bytes, std::size_t size) const {
    return ::sendto(fd_, bytes, size, 0, reinterpret_cast<const sockaddr*>(&from_), from_length_) ==
           static_cast<ssize_t>(size);
  }

 private:
  int fd_ = -1;
  sockaddr_un from_{};
  socklen_t from_length_ = 0;
};

class LocalCanBusTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "zerog-can-XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
    path_ = (dir_ / "bus.sock").string();
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  /// Server at path_ and a client connected to it, both with `config`.
  void open_pair(const CanSocketConfig& server_config = {},
                 const CanSocketConfig& client_config = {}) {
    const CanOpenResult s = server_.open_server(path_, server_config);
    ASSERT_TRUE(s.ok()) << can_open_status_name(s.status) << " " << s.what;
    const CanOpenResult c = client_.open_client(path_, client_config);
    ASSERT_TRUE(c.ok()) << can_open_status_name(c.status) << " " << c.what;
  }
  /// Client → server once, so the server knows whom to answer.
  void introduce_client() {
    ASSERT_EQ(client_.write(make_frame(0x7E0, 0)), CanWriteStatus::ok);
    CanRxFrame rx;
    ASSERT_EQ(server_.read(rx, 1s), CanReadStatus::frame);
    ASSERT_TRUE(server_.has_peer());
  }

  fs::path dir_;
  std::string path_;
  LocalCanBus server_;
  LocalCanBus client_;
};

TEST_F(LocalCanBusTest, FramesGoBothWaysWithReceiveTimestamps) {
  open_pair();
  EXPECT_EQ(server_.role(), LocalCanBus::Role::server);
  EXPECT_EQ(client_.role(), LocalCanBus::Role::client);
  EXPECT_FALSE(server_.has_peer());
  EXPECT_TRUE(fs::is_socket(path_));

  const proto::CanFrame request = make_frame(0x200, 0);
  const std::int64_t before = monotonic_ns();
  ASSERT_EQ(client_.write(request), CanWriteStatus::ok);
  CanRxFrame rx;
  ASSERT_EQ(server_.read(rx, 1s), CanReadStatus::frame);
  const std::int64_t after = monotonic_ns();
  EXPECT_EQ(rx.frame, request);
  EXPECT_GE(rx.arrived_ns, before);  // SO_TIMESTAMPNS, moved onto CLOCK_MONOTONIC
  EXPECT_LE(rx.arrived_ns, after);
  EXPECT_TRUE(server_.has_peer());

  const proto::CanFrame answer = make_frame(0x201, 8, 0xA0);
  ASSERT_EQ(server_.write(answer), CanWriteStatus::ok);
  ASSERT_EQ(client_.read(rx, 1s), CanReadStatus::frame);
  EXPECT_EQ(rx.frame, answer);
  EXPECT_GT(rx.arrived_ns, 0);

  EXPECT_EQ(client_.counters().frames_sent, 1u);
  EXPECT_EQ(client_.counters().frames_received, 1u);
  EXPECT_EQ(server_.counters().frames_sent, 1u);
  EXPECT_EQ(server_.counters().frames_received, 1u);
  EXPECT_EQ(server_.counters().kernel_drops, 0u);
}

// A frame's arrival is when the kernel queued it (SO_TIMESTAMPNS, moved onto CLOCK_MONOTONIC), not
// when read() got round to it: a frame read 50 ms late still arrived before the wait began.
TEST_F(LocalCanBusTest, ArrivalIsWhenTheKernelQueuedTheFrameNotWhenItWasRead) {
  open_pair();
  ASSERT_EQ(client_.write(make_frame(0x200, 0)), CanWriteStatus::ok);
  const std::int64_t written = monotonic_ns();
  std::this_thread::sleep_for(50ms);
  CanRxFrame rx;
  ASSERT_EQ(server_.read(rx, 1s), CanReadStatus::frame);
  const std::int64_t read = monotonic_ns();
  EXPECT_LE(rx.arrived_ns, written);
  EXPECT_GE(read - rx.arrived_ns, 50'000'000);
  EXPECT_LT(read - rx.arrived_ns, 1'000'000'000);  // and on the monotonic clock, not the wall's
}

TEST_F(LocalCanBusTest, StandardExtendedAndRemoteFramesKeepIdsFlagsAndData) {
  open_pair();
  introduce_client();
  const std::array<proto::CanFrame, 6> frames{
      make_frame(0x000, 0),
      make_frame(0x7FF, 8, 0xF0),
      make_frame(0x1FFFFFFFu | proto::kCanExtendedFlag, 8),
      make_frame(0x00000123u | proto::kCanExtendedFlag, 3),
      make_frame(0x321u | proto::kCanRemoteFlag, 0),
      make_frame(0x0ABCDEFu | proto::kCanExtendedFlag | proto::kCanRemoteFlag, 0),
  };
  CanRxFrame rx;
  for (const proto::CanFrame& f : frames) {
    ASSERT_EQ(client_.write(f), CanWriteStatus::ok);
    ASSERT_EQ(server_.read(rx, 1s), CanReadStatus::frame);
    EXPECT_EQ(rx.frame, f) << std::hex << f.id;
    EXPECT_EQ(rx.frame.extended(), f.extended());
    EXPECT_EQ(rx.frame.remote(), f.remote());
    EXPECT_EQ(rx.frame.raw_id(), f.raw_id());
    ASSERT_EQ(server_.write(f), CanWriteStatus::ok);
    ASSERT_EQ(client_.read(rx, 1s), CanReadStatus::frame);
    EXPECT_EQ(rx.frame, f) << std::hex << f.id;
  }
}

TEST_F(LocalCanBusTest, TheWireIsLinuxStructCanFrame) {
  RawSocket fake_server(path_);
  ASSERT_TRUE(fake_server.ok());
  ASSERT_TRUE(client_.open_client(path_).ok());
  proto::CanFrame f = make_frame(0x123u | proto::kCanExtendedFlag, 3, 0x41);
  f.data[5] = 0x99;  // past len: never on the wire
  ASSERT_EQ(client_.write(f), CanWriteStatus::ok);
  const std::vector<unsigned char> bytes = fake_server.receive();
  ASSERT_EQ(bytes.size(), 16u);
  can_frame raw{};
  std::memcpy(&raw, bytes.data(), sizeof raw);
  EXPECT_EQ(raw.can_id, 0x123u | CAN_EFF_FLAG);
  EXPECT_EQ(raw.len, 3);
  EXPECT_EQ(bytes[5], 0);  // pad
  EXPECT_EQ(bytes[6], 0);
  EXPECT_EQ(bytes[7], 0);
  EXPECT_EQ(bytes[8], 0x41);
  EXPECT_EQ(bytes[10], 0x43);
  for (std::size_t i = 11; i < 16; ++i) EXPECT_EQ(bytes[i], 0) << i;

  // And a struct can_frame written by someone else reads back as that frame.
  can_frame answer{};
  answer.can_id = 0x456 | CAN_RTR_FLAG;
  answer.len = 2;
  ASSERT_TRUE(fake_server.reply(&answer, sizeof answer));
  CanRxFrame rx;
  ASSERT_EQ(client_.read(rx, 1s), CanReadStatus::frame);
  EXPECT_EQ(rx.frame.id, 0x456u | proto::kCanRemoteFlag);
  EXPECT_EQ(rx.frame.len, 2);
}

TEST_F(LocalCanBusTest, ErrorFramesAreReturnedAndCountedByClass) {
  open_pair();
  introduce_client();
  // Controller problem + bus-off, then no-ack: as a CAN controller reports them.
  const proto::CanFrame first = make_frame(proto::kCanErrorFlag | 0x004u | 0x040u, 8, 0);
  const proto::CanFrame second = make_frame(proto::kCanErrorFlag | 0x020u, 8, 0);
  ASSERT_EQ(server_.write(first), CanWriteStatus::ok);
  ASSERT_EQ(server_.write(second), CanWriteStatus::ok);
  CanRxFrame rx;
  ASSERT_EQ(client_.read(rx, 1s), CanReadStatus::error_frame);
  EXPECT_EQ(rx.frame, first);
  ASSERT_EQ(client_.read(rx, 1s), CanReadStatus::error_frame);
  EXPECT_EQ(rx.frame, second);
  const CanBusCounters& c = client_.counters();
  EXPECT_EQ(c.error_frames, 2u);
  EXPECT_EQ(c.error_classes[static_cast<std::size_t>(CanErrorClass::controller)], 1u);
  EXPECT_EQ(c.error_classes[static_cast<std::size_t>(CanErrorClass::bus_off)], 1u);
  EXPECT_EQ(c.error_classes[static_cast<std::size_t>(CanErrorClass::no_ack)], 1u);
  EXPECT_EQ(c.error_classes[static_cast<std::size_t>(CanErrorClass::tx_timeout)], 0u);
  EXPECT_EQ(c.frames_received, 0u);
}

TEST_F(LocalCanBusTest, DatagramsThatAreNotOneClassicFrameAreBadLength) {
  ASSERT_TRUE(server_.open_server(path_).ok());
  RawSocket sender;
  std::array<unsigned char, 17> bytes{};
  can_frame too_long{};  // 16 bytes, len 9
  too_long.can_id = 0x100;
  too_long.len = 9;
  ASSERT_TRUE(sender.send_to(path_, bytes.data(), 15));
  ASSERT_TRUE(sender.send_to(path_, bytes.data(), 17));
  ASSERT_TRUE(sender.send_to(path_, &too_long, sizeof too_long));
  ASSERT_TRUE(sender.send_to(path_, bytes.data(), 0));
  CanRxFrame rx;
  for (int i = 0; i < 4; ++i) EXPECT_EQ(server_.read(rx, 1s), CanReadStatus::bad_length) << i;
  EXPECT_EQ(server_.counters().bad_length, 4u);
  EXPECT_EQ(server_.counters().frames_received, 0u);
  // An unnamed sender cannot be answered: it does not become the peer.
  EXPECT_FALSE(server_.has_peer());
  // A good frame after them is read as usual.
  can_frame good{};
  good.can_id = 0x100;
  good.len = 1;
  good.data[0] = 7;
  ASSERT_TRUE(sender.send_to(path_, &good, sizeof good));
  ASSERT_EQ(server_.read(rx, 1s), CanReadStatus::frame);
  EXPECT_EQ(rx.frame, make_frame(0x100, 1, 7));
}

TEST_F(LocalCanBusTest, TheClientCountsBadLengthFromItsServerToo) {
  RawSocket fake_server(path_);
  ASSERT_TRUE(fake_server.ok());
  ASSERT_TRUE(client_.open_client(path_).ok());
  ASSERT_EQ(client_.write(make_frame(0x200, 0)), CanWriteStatus::ok);
  ASSERT_EQ(fake_server.receive().size(), 16u);
  std::array<unsigned char, 17> bytes{};
  ASSERT_TRUE(fake_server.reply(bytes.data(), 15));
  ASSERT_TRUE(fake_server.reply(bytes.data(), 17));
  CanRxFrame rx;
  EXPECT_EQ(client_.read(rx, 1s), CanReadStatus::bad_length);
  EXPECT_EQ(client_.read(rx, 1s), CanReadStatus::bad_length);
  EXPECT_EQ(client_.counters().bad_length, 2u);
}

TEST_F(LocalCanBusTest, WritingMoreThanEightBytesIsRefused) {
  open_pair();
  proto::CanFrame f = make_frame(0x100, 8);
  f.len = 9;
  EXPECT_EQ(client_.write(f), CanWriteStatus::bad_frame);
  EXPECT_EQ(client_.counters().frames_sent, 0u);
  CanRxFrame rx;
  EXPECT_EQ(server_.read(rx, 0ns), CanReadStatus::timeout);
}

TEST_F(LocalCanBusTest, AcceptanceFiltersDropOtherIdsSilentlyAndCountThem) {
  // The client takes 0x120..0x12F, standard data frames only (flags in the mask), as
  // NetcanoemSensor::socket_config does for its board.
  CanSocketConfig client_config;
  client_config.filters[0] = {0x120, 0x7F0u | proto::kCanExtendedFlag | proto::kCanRemoteFlag};
  client_config.filters[1] = {0x300, 0x7FF};  // and exactly 0x300 (remote too: RTR not masked)
  client_config.filter_count = 2;
  open_pair({}, client_config);
  introduce_client();
  const std::array<std::pair<proto::CanFrame, bool>, 8> frames{{
      {make_frame(0x121, 2), true},
      {make_frame(0x200, 2), false},
      {make_frame(0x121u | proto::kCanExtendedFlag, 2), false},
      {make_frame(0x12Fu | proto::kCanRemoteFlag, 0), false},
      {make_frame(0x300, 1), true},
      {make_frame(0x300u | proto::kCanRemoteFlag, 0), true},
      {make_frame(0x301, 1), false},
      {make_frame(0x12F, 8), true},
  }};
  for (const auto& [frame, passes] : frames) ASSERT_EQ(server_.write(frame), CanWriteStatus::ok);
  CanRxFrame rx;
  for (const auto& [frame, passes] : frames) {
    if (!passes) continue;
    ASSERT_EQ(client_.read(rx, 1s), CanReadStatus::frame);
    EXPECT_EQ(rx.frame, frame) << std::hex << rx.frame.id;
  }
  EXPECT_EQ(client_.read(rx, 20ms), CanReadStatus::timeout);  // the filtered ones never come
  EXPECT_EQ(client_.counters().filtered, 4u);
  EXPECT_EQ(client_.counters().frames_received, 4u);
}

TEST_F(LocalCanBusTest, NoFiltersPassNoDataFramesButErrorFramesStillCome) {
  CanSocketConfig client_config;
  client_config.filter_count = 0;
  open_pair({}, client_config);
  introduce_client();
  ASSERT_EQ(server_.write(make_frame(0x100, 1)), CanWriteStatus::ok);
  ASSERT_EQ(server_.write(make_frame(proto::kCanErrorFlag | 0x080u, 8, 0)), CanWriteStatus::ok);
  CanRxFrame rx;
  EXPECT_EQ(client_.read(rx, 1s), CanReadStatus::error_frame);
  EXPECT_EQ(client_.counters().filtered, 1u);
}

TEST_F(LocalCanBusTest, TheErrorMaskChoosesErrorFramesByClass) {
  CanSocketConfig client_config;
  client_config.error_mask = 0x040u;  // bus-off only
  open_pair({}, client_config);
  introduce_client();
  const proto::CanFrame controller = make_frame(proto::kCanErrorFlag | 0x004u, 8, 0);
  const proto::CanFrame bus_off = make_frame(proto::kCanErrorFlag | 0x044u, 8, 0);
  ASSERT_EQ(server_.write(controller), CanWriteStatus::ok);
  ASSERT_EQ(server_.write(bus_off), CanWriteStatus::ok);
  CanRxFrame rx;
  ASSERT_EQ(client_.read(rx, 1s), CanReadStatus::error_frame);
  EXPECT_EQ(rx.frame, bus_off);
  EXPECT_EQ(client_.counters().filtered, 1u);
  EXPECT_EQ(client_.counters().error_frames, 1u);

  LocalCanBus deaf;  // error_mask 0: no error frames at all
  CanSocketConfig none;
  none.error_mask = 0;
  client_.close();
  ASSERT_TRUE(deaf.open_client(path_, none).ok());
  ASSERT_EQ(deaf.write(make_frame(0x7E0, 0)), CanWriteStatus::ok);
  ASSERT_EQ(server_.read(rx, 1s), CanReadStatus::frame);  // now the server answers `deaf`
  ASSERT_EQ(server_.write(bus_off), CanWriteStatus::ok);
  EXPECT_EQ(deaf.read(rx, 20ms), CanReadStatus::timeout);
  EXPECT_EQ(deaf.counters().filtered, 1u);
}

TEST_F(LocalCanBusTest, ReadTimesOutWithinItsBound) {
  open_pair();
  CanRxFrame rx;
  for (const std::chrono::milliseconds timeout : {5ms, 30ms}) {
    const auto start = Clock::now();
    EXPECT_EQ(client_.read(rx, timeout), CanReadStatus::timeout);
    const auto took = Clock::now() - start;
    EXPECT_GE(took, timeout);
    EXPECT_LT(took, timeout + 200ms);  // generous: the host may be busy
  }
  EXPECT_EQ(client_.counters().io_errors, 0u);
}

TEST_F(LocalCanBusTest, AZeroTimeoutOnlyLooks) {
  open_pair();
  CanRxFrame rx;
  const auto start = Clock::now();
  EXPECT_EQ(server_.read(rx, 0ns), CanReadStatus::timeout);
  EXPECT_LT(Clock::now() - start, 50ms);
  ASSERT_EQ(client_.write(make_frame(0x100, 1)), CanWriteStatus::ok);
  EXPECT_EQ(server_.read(rx, 0ns), CanReadStatus::frame);  // already queued: returned at once
  EXPECT_EQ(server_.read(rx, 0ns), CanReadStatus::timeout);
}

TEST_F(LocalCanBusTest, AServerWithoutAPeerCannotWrite) {
  ASSERT_TRUE(server_.open_server(path_).ok());
  EXPECT_EQ(server_.write(make_frame(0x100, 1)), CanWriteStatus::io_error);
  EXPECT_EQ(server_.last_errno(), ENOTCONN);
  EXPECT_EQ(server_.counters().tx_errors, 1u);
  EXPECT_EQ(server_.counters().frames_sent, 0u);
}

TEST_F(LocalCanBusTest, APeerThatIsGoneIsAnIoError) {
  open_pair();
  introduce_client();
  // The client goes: the server's answer has nowhere to go.
  client_.close();
  EXPECT_EQ(server_.write(make_frame(0x100, 1)), CanWriteStatus::io_error);
  EXPECT_EQ(server_.last_errno(), ECONNREFUSED);
  EXPECT_EQ(server_.counters().tx_errors, 1u);
  EXPECT_FALSE(server_.has_peer());
  EXPECT_EQ(server_.write(make_frame(0x100, 1)), CanWriteStatus::io_error);  // and stays so
  EXPECT_EQ(server_.last_errno(), ENOTCONN);

  // The server goes: the client's request has nowhere to go (and nobody to reconnect to).
  LocalCanBus client;
  ASSERT_TRUE(client.open_client(path_).ok());
  server_.close();
  EXPECT_FALSE(fs::exists(path_)) << "the server unlinks its socket";
  EXPECT_EQ(client.write(make_frame(0x100, 1)), CanWriteStatus::io_error);
  EXPECT_EQ(client.last_errno(), ENOENT) << std::strerror(client.last_errno());  // reconnect's
  EXPECT_EQ(client.write(make_frame(0x100, 1)), CanWriteStatus::io_error);
  EXPECT_EQ(client.counters().tx_errors, 2u);
  EXPECT_EQ(client.counters().frames_sent, 0u);
}

TEST_F(LocalCanBusTest, AClientFindsARestartedServer) {
  open_pair();
  introduce_client();
  server_.close();
  LocalCanBus restarted;
  ASSERT_TRUE(restarted.open_server(path_).ok());
  ASSERT_EQ(client_.write(make_frame(0x101, 1)), CanWriteStatus::ok);  // reconnects, resends
  CanRxFrame rx;
  ASSERT_EQ(restarted.read(rx, 1s), CanReadStatus::frame);
  EXPECT_EQ(rx.frame, make_frame(0x101, 1));
  ASSERT_EQ(restarted.write(make_frame(0x102, 1)), CanWriteStatus::ok);
  ASSERT_EQ(client_.read(rx, 1s), CanReadStatus::frame);
  EXPECT_EQ(rx.frame, make_frame(0x102, 1));
  EXPECT_EQ(client_.counters().tx_errors, 0u);
}

TEST_F(LocalCanBusTest, OpenFailuresAreReportedAsStatus) {
  LocalCanBus bus;
  EXPECT_EQ(bus.open_server("").status, CanOpenStatus::bad_argument);
  EXPECT_EQ(bus.open_client(std::string(LocalCanBus::kMaxPathBytes + 1, 'x')).status,
            CanOpenStatus::bad_argument);
  EXPECT_EQ(bus.open_server(std::string("/tmp/a\0b", 8)).status, CanOpenStatus::bad_argument);
  CanSocketConfig many;
  many.filter_count = kMaxCanFilters + 1;
  EXPECT_EQ(bus.open_server(path_, many).status, CanOpenStatus::bad_argument);

  const CanOpenResult nobody = bus.open_client(path_);
  EXPECT_EQ(nobody.status, CanOpenStatus::connect_failed);
  EXPECT_EQ(nobody.error_number, ENOENT);
  EXPECT_STREQ(can_open_status_name(nobody.status), "connect_failed");
  EXPECT_FALSE(bus.is_open());

  ASSERT_TRUE(server_.open_server(path_).ok());
  const CanOpenResult taken = bus.open_server(path_);
  EXPECT_EQ(taken.status, CanOpenStatus::bind_failed);
  EXPECT_EQ(taken.error_number, EADDRINUSE);
  EXPECT_TRUE(fs::is_socket(path_)) << "a failed open leaves the other server's socket alone";

  CanRxFrame rx;
  EXPECT_EQ(bus.read(rx, 0ns), CanReadStatus::not_open);
  EXPECT_EQ(bus.write(proto::CanFrame{}), CanWriteStatus::not_open);
}

TEST_F(LocalCanBusTest, CloseUnlinksOnlyTheSocketTheServerBound) {
  ASSERT_TRUE(server_.open_server(path_).ok());
  server_.close();
  EXPECT_FALSE(fs::exists(path_));

  ASSERT_TRUE(server_.open_server(path_).ok());
  fs::remove(path_);
  { std::ofstream(path_) << "someone else's file\n"; }
  server_.close();
  EXPECT_TRUE(fs::is_regular_file(path_));
}

TEST_F(LocalCanBusTest, ReadAndWriteDoNotAllocate) {
  open_pair();
  introduce_client();
  CanRxFrame rx;
  const std::size_t before = zerog::test::allocation_count();
  for (int i = 0; i < 500; ++i) {
    ASSERT_EQ(client_.write(make_frame(0x100, 8)), CanWriteStatus::ok);
    ASSERT_EQ(server_.read(rx, 1s), CanReadStatus::frame);
    ASSERT_EQ(server_.write(make_frame(proto::kCanErrorFlag | 0x010u, 8)), CanWriteStatus::ok);
    ASSERT_EQ(client_.read(rx, 1s), CanReadStatus::error_frame);
    ASSERT_EQ(client_.read(rx, 0ns), CanReadStatus::timeout);
  }
  EXPECT_EQ(zerog::test::allocation_count(), before);
}

// The sensor of zerog-rt on a client, the emulated board of zerog-emu serving in a thread.
TEST_F(LocalCanBusTest, NetcanoemSensorReadsTheCalibrationAndTheWrenchFromAnAtiBoard) {
  emu::AtiBoardConfig board_config;
  board_config.base_id = 0x21;
  board_config.counts_per_force = 50'000;  // a range for a few hundred N
  board_config.counts_per_torque = 50'000;
  emu::AtiBoard board(board_config);
  ASSERT_TRUE(server_.open_server(path_).ok());
  ASSERT_TRUE(
      client_.open_client(path_, NetcanoemSensor::socket_config(board_config.base_id)).ok());
  std::atomic<bool> stop{false};
  std::thread serving([&] { board.serve(server_, stop); });

  NetcanoemConfig config;
  config.base_id = board_config.base_id;
  config.calibration_index = 3;
  config.sample_timeout = 200ms;  // a busy host must not fail the test; the bound is not tested
  NetcanoemSensor sensor(client_, config);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  const proto::netcanoem::Calibration& cal = sensor.calibration();
  EXPECT_EQ(cal.active_calibration, 3);
  EXPECT_STREQ(cal.serial_number.data(), "FT42007A");
  EXPECT_EQ(cal.firmware.build, board_config.firmware.build);
  EXPECT_EQ(cal.counts_per_force, 50'000u);
  for (int r = 0; r < 6; ++r)
    for (int col = 0; col < 6; ++col)
      EXPECT_EQ(cal.matrix[r][col], board_config.matrix[r][col]);  // exact in float32

  const std::array<std::array<double, 6>, 3> wrenches{{
      {12.0, -7.5, -480.0, 1.25, -0.5, 0.05},
      {-30.0, 40.0, 100.0, -2.0, 3.0, -1.0},
      {0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
  }};
  const std::array<double, 6> count = board.count_resolution_si();
  FtSample s;
  for (const std::array<double, 6>& wrench : wrenches) {
    board.set_wrench(wrench);
    ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
    EXPECT_TRUE(s.valid);
    EXPECT_EQ(s.status, FtSampleStatus::ok);
    EXPECT_GT(s.arrived_ns, 0);  // the kernel's receive time of the completing frame
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(s.wrench_si[i], wrench[i], count[i]) << i;
  }
  stop.store(true);
  serving.join();
  const FtCounters counters = sensor.counters();
  EXPECT_EQ(counters.samples, 3u);
  EXPECT_EQ(counters.timeouts, 0u);
  EXPECT_EQ(board.counters().samples_sent, 3u);
  EXPECT_EQ(board.counters().tx_failed, 0u);
  EXPECT_EQ(client_.counters().bad_length, 0u);
}

}  // namespace
}  // namespace zerog::rtio
