// The Modbus server over real TCP on 127.0.0.1, against a real loop::Cycle stepped by a test
// thread: libmodbus's client API and mbpoll (Debian's, an independent client) read the state,
// write the virtual mass while idle, are refused during zero-g with nothing changed; the
// allowlist, the client limit, a stalled half request, timeouts and configuration errors.
#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <modbus/modbus.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <thread>

#include "modbus_fixtures.hpp"
#include "zerog/modbus/server.hpp"

namespace zerog::modbus {
namespace {

using test::CycleTarget;

ServerConfig local_config() {
  ServerConfig c;
  c.bind_address = "127.0.0.1";
  c.port = 0;
  // The tests check what is decided, not how fast: under a sanitizer on a loaded 2-core machine
  // the stepping thread can miss the default 0.25 s (the no-cycle test sets its own).
  c.proposal_timeout_s = 3.0;
  return c;
}

/// A libmodbus client, connected (or not: connected() false).
class Client {
 public:
  explicit Client(int port, const char* address = "127.0.0.1") {
    ctx_ = modbus_new_tcp(address, port);
    modbus_set_response_timeout(ctx_, 5, 0);
    connected_ = modbus_connect(ctx_) == 0;
  }
  ~Client() {
    modbus_close(ctx_);
    modbus_free(ctx_);
  }
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;
  bool connected() const { return connected_; }
  modbus_t* ctx() { return ctx_; }

  /// An input or holding register value (raw), or −1 with errno set.
  std::int64_t read_input(int address, ValueType type) {
    std::uint16_t w[2] = {};
    if (modbus_read_input_registers(ctx_, address, word_count(type), w) != word_count(type))
      return -1;
    return get_words(type, w);
  }
  std::int64_t read_holding_int32(int address) {
    std::uint16_t w[2] = {};
    if (modbus_read_registers(ctx_, address, 2, w) != 2) return -1;
    return get_words(ValueType::int32, w);
  }
  /// Writes int32 values from `address` on; the rc of modbus_write_registers (errno on −1).
  int write_int32(int address, std::initializer_list<std::int64_t> raws) {
    std::vector<std::uint16_t> words;
    for (std::int64_t raw : raws) {
      std::uint16_t w[2];
      put_words(ValueType::int32, raw, w);
      words.push_back(w[0]);
      words.push_back(w[1]);
    }
    return modbus_write_registers(ctx_, address, static_cast<int>(words.size()), words.data());
  }

 private:
  modbus_t* ctx_ = nullptr;
  bool connected_ = false;
};

/// Waits (up to 5 s) until `pred()` holds.
template <typename Pred>
bool wait_until(Pred pred) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (std::chrono::steady_clock::now() < deadline) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return false;
}

struct ShellRun {
  int status = -1;
  std::string output;
};
/// Runs a command line (stdout and stderr together).
ShellRun shell(const std::string& command) {
  ShellRun r;
  FILE* p = ::popen((command + " 2>&1").c_str(), "r");
  if (p == nullptr) return r;
  std::array<char, 512> buf;
  while (std::fgets(buf.data(), buf.size(), p) != nullptr) r.output += buf.data();
  const int rc = ::pclose(p);
  r.status = WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
  return r;
}

std::string mbpoll(int port, const std::string& args) {
  return std::string(ZEROG_MBPOLL) + " -m tcp -p " + std::to_string(port) + " -1 -o 5 " + args;
}

constexpr int kMass = 0;            // holding: mass_kg, int32, 1 raw = 0.001 kg
constexpr int kInertiaXy = 8;       // holding: inertia_xy_kgm2
constexpr int kStateRegister = 1;   // input: state
constexpr int kProposalStatus = 4;  // input: proposal_status

class ModbusServerTest : public ::testing::Test {
 protected:
  void start(ServerConfig config = local_config()) {
    target_.start();
    ASSERT_TRUE(target_.wait_for([](const SupervisorSnapshot& s) { return s.ready; }));
    server_ = std::make_unique<ModbusServer>(config, target_);
    ASSERT_EQ(server_->start().text(), "");
    ASSERT_GT(server_->port(), 0);
  }
  void enable_zero_g(Client& c) {
    ASSERT_EQ(modbus_write_bit(c.ctx(), 0, 1), 1) << modbus_strerror(errno);
    ASSERT_EQ(target_.snapshot().state, loop::State::zero_g);
  }
  void TearDown() override {
    if (server_) server_->stop();
    target_.stop();
  }

  CycleTarget target_;
  std::unique_ptr<ModbusServer> server_;
};

TEST_F(ModbusServerTest, LibmodbusReadsTheStateAndWritesTheMassWhileIdle) {
  start();
  Client c(server_->port());
  ASSERT_TRUE(c.connected());
  EXPECT_EQ(c.read_input(0, ValueType::uint16), kRegisterMapVersion);
  EXPECT_EQ(c.read_input(kStateRegister, ValueType::uint16), 0);  // idle
  EXPECT_EQ(c.read_input(40, ValueType::uint32), 0xC0FFEE42);     // model_crc32
  EXPECT_EQ(c.read_holding_int32(kMass), 100'000);                // 100 kg

  ASSERT_EQ(c.write_int32(kMass, {80'250}), 2) << modbus_strerror(errno);
  EXPECT_EQ(c.read_holding_int32(kMass), 80'250);
  EXPECT_EQ(c.read_input(kProposalStatus, ValueType::uint16),
            static_cast<int>(loop::ProposalStatus::accepted));
  target_.stop();
  EXPECT_EQ(target_.cycle().tunables().body.mass_kg, 80.25);  // the running value
  const ServerCounters n = server_->counters();
  EXPECT_EQ(n.writes_accepted, 1u);
  EXPECT_EQ(n.exceptions_total(), 0u);
}

// A PLC reads the state right after the coil write's reply: it must see the command applied,
// even when the snapshot is published well after the step that decided it (CI once read idle).
TEST_F(ModbusServerTest, AReadRightAfterACommandReplyShowsTheNewState) {
  target_.set_publish_delay(std::chrono::milliseconds(30));
  start();
  Client c(server_->port());
  ASSERT_TRUE(c.connected());
  for (int round = 0; round < 3; ++round) {
    ASSERT_EQ(modbus_write_bit(c.ctx(), 0, 1), 1) << modbus_strerror(errno);
    EXPECT_EQ(c.read_input(kStateRegister, ValueType::uint16),
              static_cast<int>(loop::State::zero_g));
    ASSERT_EQ(modbus_write_bit(c.ctx(), 0, 0), 1) << modbus_strerror(errno);
    EXPECT_EQ(c.read_input(kStateRegister, ValueType::uint16), static_cast<int>(loop::State::idle));
  }
}

TEST_F(ModbusServerTest, TheSameWriteDuringZeroGIsRefusedAndChangesNothing) {
  start();
  Client c(server_->port());
  ASSERT_TRUE(c.connected());
  enable_zero_g(c);
  EXPECT_EQ(c.read_input(kStateRegister, ValueType::uint16), 2);  // zero_g
  std::uint8_t coil = 0;
  ASSERT_EQ(modbus_read_bits(c.ctx(), 0, 1, &coil), 1);
  EXPECT_EQ(coil, 1);

  EXPECT_EQ(c.write_int32(kMass, {80'250}), -1);
  EXPECT_EQ(errno, EMBXSBUSY) << modbus_strerror(errno);
  EXPECT_EQ(c.read_holding_int32(kMass), 100'000);
  EXPECT_EQ(c.read_input(kProposalStatus, ValueType::uint16),
            static_cast<int>(loop::ProposalStatus::refused_state));

  // Stop: idle again, and then the write goes through.
  ASSERT_EQ(modbus_write_bit(c.ctx(), 0, 0), 1) << modbus_strerror(errno);
  EXPECT_EQ(target_.snapshot().state, loop::State::idle);
  target_.stop();
  EXPECT_EQ(target_.cycle().tunables().body.mass_kg, 100.0);
  const ServerCounters n = server_->counters();
  EXPECT_EQ(n.exceptions[6], 1u);
  EXPECT_EQ(n.writes_refused, 1u);
  EXPECT_EQ(n.commands_accepted, 2u);
}

TEST_F(ModbusServerTest, InconsistentAndOutOfRangeWritesChangeNothing) {
  start();
  Client c(server_->port());
  ASSERT_TRUE(c.connected());
  // In range per register, but the inertia is not positive definite: the cycle refuses (03).
  EXPECT_EQ(c.write_int32(kInertiaXy, {90'000}), -1);  // Ixy = 9 kg·m² with Ixx 4, Iyy 5
  EXPECT_EQ(errno, EMBXILVAL);
  EXPECT_EQ(c.read_input(kProposalStatus, ValueType::uint16),
            static_cast<int>(loop::ProposalStatus::refused_invalid));
  // Mass fine, Ixx fine, Iyy out of range: the whole write is refused before the cycle.
  EXPECT_EQ(c.write_int32(kMass, {90'000, 70'000, 0}), -1);
  EXPECT_EQ(errno, EMBXILVAL);
  // Half of the 32-bit mass: illegal address.
  const std::uint16_t one = 1;
  EXPECT_EQ(modbus_write_register(c.ctx(), kMass, one), -1);
  EXPECT_EQ(errno, EMBXILADD);
  EXPECT_EQ(c.read_holding_int32(kMass), 100'000);
  target_.stop();
  const loop::Tunables t = target_.cycle().tunables();
  EXPECT_EQ(t.body.mass_kg, 100.0);
  EXPECT_EQ(t.body.inertia_body_kgm2, loop::test::test_cycle_config().body.inertia_body_kgm2);
  EXPECT_EQ(server_->counters().writes_refused, 3u);
}

TEST_F(ModbusServerTest, CommandsTheStateMachineRefusesAreServerDeviceFailure) {
  start();
  Client c(server_->port());
  ASSERT_TRUE(c.connected());
  // start_collection without a collection path: the cycle refuses it.
  EXPECT_EQ(modbus_write_bit(c.ctx(), 1, 1), -1);
  EXPECT_EQ(errno, EMBXSFAIL) << modbus_strerror(errno);
  EXPECT_EQ(target_.snapshot().state, loop::State::idle);
  // Reset while not in fault: nothing to do, answered normally.
  EXPECT_EQ(modbus_write_bit(c.ctx(), 2, 1), 1);
}

TEST_F(ModbusServerTest, MbpollReadsTheStateWritesTheMassAndIsRefusedDuringZeroG) {
  ASSERT_STRNE(ZEROG_MBPOLL, "ZEROG_MBPOLL-NOTFOUND") << "mbpoll is not installed";
  start();
  const int port = server_->port();
  // State: input register 1 (0-based with -0).
  ShellRun r = shell(mbpoll(port, "-0 -t 3 -r 1 -c 1 127.0.0.1"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("[1]: \t0"), std::string::npos) << r.output;
  // Write 80.25 kg (int32, high word first: -B), read it back.
  r = shell(mbpoll(port, "-0 -t 4:int -B -r 0 127.0.0.1 80250"));
  ASSERT_EQ(r.status, 0) << r.output;
  r = shell(mbpoll(port, "-0 -t 4:int -B -r 0 -c 1 127.0.0.1"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("80250"), std::string::npos) << r.output;
  // Enable zero-g through the coil (1-based numbering: coil 1 = address 0).
  r = shell(mbpoll(port, "-t 0 -r 1 127.0.0.1 1"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(target_.snapshot().state, loop::State::zero_g);
  // The same mass write during zero-g: an exception, nothing changed.
  r = shell(mbpoll(port, "-0 -t 4:int -B -r 0 127.0.0.1 60000"));
  EXPECT_NE(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("busy"), std::string::npos) << r.output;
  target_.stop();
  EXPECT_EQ(target_.cycle().tunables().body.mass_kg, 80.25);
}

TEST_F(ModbusServerTest, TheAllowlistClosesOtherClients) {
  ServerConfig config = local_config();
  config.allow = {"127.0.0.2"};
  start(config);
  {
    Client c(server_->port());  // connects from 127.0.0.1: accepted by TCP, closed at once
    std::uint16_t w = 0;
    EXPECT_EQ(modbus_read_input_registers(c.ctx(), 1, 1, &w), -1);
  }
  EXPECT_TRUE(wait_until([&] { return server_->counters().clients_refused_allowlist >= 1; }));
  EXPECT_EQ(server_->counters().clients_accepted, 0u);
  EXPECT_EQ(server_->counters().requests, 0u);
}

TEST_F(ModbusServerTest, TheAllowlistAdmitsItsNetwork) {
  ServerConfig config = local_config();
  config.allow = {"10.1.2.0/24", "127.0.0.0/8"};
  start(config);
  Client c(server_->port());
  EXPECT_EQ(c.read_input(kStateRegister, ValueType::uint16), 0);
  EXPECT_EQ(server_->counters().clients_refused_allowlist, 0u);
}

TEST_F(ModbusServerTest, ClientsBeyondTheLimitAreClosed) {
  ServerConfig config = local_config();
  config.max_clients = 2;
  start(config);
  Client a(server_->port()), b(server_->port());
  EXPECT_EQ(a.read_input(kStateRegister, ValueType::uint16), 0);
  EXPECT_EQ(b.read_input(kStateRegister, ValueType::uint16), 0);
  {
    Client extra(server_->port());
    EXPECT_EQ(extra.read_input(kStateRegister, ValueType::uint16), -1);
  }
  EXPECT_TRUE(wait_until([&] { return server_->counters().clients_refused_limit == 1; }));
  EXPECT_EQ(server_->clients_connected(), 2);
  EXPECT_EQ(a.read_input(kStateRegister, ValueType::uint16), 0);  // still served
  EXPECT_EQ(a.read_input(5, ValueType::uint16), 2);               // modbus_clients
}

/// A raw TCP connection that sends part of a request and then nothing.
int stalled_connection(int port, std::size_t bytes) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_port = htons(static_cast<std::uint16_t>(port));
  inet_pton(AF_INET, "127.0.0.1", &a.sin_addr);
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&a), sizeof a) != 0) return -1;
  const std::uint8_t half[] = {0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0x01, 0x04, 0x00, 0x01};
  if (::send(fd, half, std::min(bytes, sizeof half), 0) < 0) return -1;
  return fd;
}

TEST_F(ModbusServerTest, AStalledHalfRequestDoesNotStopOthersBeingServed) {
  ServerConfig config = local_config();
  config.request_timeout_s = 10.0;  // longer than the other client's 5 s response timeout
  start(config);
  const int fd = stalled_connection(server_->port(), 9);
  ASSERT_GE(fd, 0);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  Client c(server_->port());
  for (int i = 0; i < 20; ++i) {
    ASSERT_EQ(c.read_input(kStateRegister, ValueType::uint16), 0) << i;
  }
  ASSERT_EQ(c.write_int32(kMass, {95'000}), 2);
  EXPECT_EQ(server_->clients_connected(), 2);
  EXPECT_EQ(server_->counters().request_timeouts, 0u);
  ::close(fd);
}

TEST_F(ModbusServerTest, AHalfRequestIsClosedAfterTheRequestTimeout) {
  ServerConfig config = local_config();
  config.request_timeout_s = 0.1;
  start(config);
  const int fd = stalled_connection(server_->port(), 5);
  ASSERT_GE(fd, 0);
  EXPECT_TRUE(wait_until([&] { return server_->counters().request_timeouts == 1; }));
  std::uint8_t byte = 0;
  EXPECT_EQ(::recv(fd, &byte, 1, 0), 0);  // closed by the server
  ::close(fd);
  // The count drops just after the close the peer sees (same server pass): wait for it.
  EXPECT_TRUE(wait_until([&] { return server_->clients_connected() == 0; }));
}

TEST_F(ModbusServerTest, GarbageThatIsNotModbusTcpClosesTheConnection) {
  start();
  const int fd = stalled_connection(server_->port(), 0);
  ASSERT_GE(fd, 0);
  const char http[] = "GET / HTTP/1.0\r\n\r\n";
  ASSERT_GT(::send(fd, http, sizeof http - 1, 0), 0);
  std::uint8_t byte = 0;
  EXPECT_EQ(::recv(fd, &byte, 1, 0), 0);
  ::close(fd);
  EXPECT_EQ(server_->counters().framing_errors, 1u);
}

TEST_F(ModbusServerTest, PipelinedRequestsAreAllAnsweredEvenAfterTheClientClosesItsSide) {
  start();
  const int fd = stalled_connection(server_->port(), 0);
  ASSERT_GE(fd, 0);
  // Two reads of the state (transactions 7 and 8) in one segment, then end of input.
  const std::uint8_t two[] = {0x00, 0x07, 0x00, 0x00, 0x00, 0x06, 0x01, 0x04,
                              0x00, 0x01, 0x00, 0x01, 0x00, 0x08, 0x00, 0x00,
                              0x00, 0x06, 0x01, 0x04, 0x00, 0x01, 0x00, 0x01};
  ASSERT_EQ(::send(fd, two, sizeof two, 0), static_cast<ssize_t>(sizeof two));
  ::shutdown(fd, SHUT_WR);
  std::vector<std::uint8_t> got;
  std::uint8_t buf[64];
  for (ssize_t n; (n = ::recv(fd, buf, sizeof buf, 0)) > 0;) got.insert(got.end(), buf, buf + n);
  ::close(fd);
  // Each reply: MBAP (7) + function 04 + byte count 2 + the state (0 = idle).
  const std::vector<std::uint8_t> expected = {0x00, 0x07, 0x00, 0x00, 0x00, 0x05, 0x01, 0x04,
                                              0x02, 0x00, 0x00, 0x00, 0x08, 0x00, 0x00, 0x00,
                                              0x05, 0x01, 0x04, 0x02, 0x00, 0x00};
  EXPECT_EQ(got, expected);
  EXPECT_EQ(server_->counters().requests, 2u);
}

TEST(ModbusServerNoCycle, AWriteTheCycleNeverTakesIsWithdrawnAndAnsweredWithFailure) {
  CycleTarget target;  // never stepped: like zerog-rt with its cycle thread stuck
  ServerConfig config = local_config();
  config.proposal_timeout_s = 0.05;
  ModbusServer server(config, target);
  ASSERT_EQ(server.start().text(), "");
  Client c(server.port());
  EXPECT_EQ(c.write_int32(kMass, {70'000}), -1);
  EXPECT_EQ(errno, EMBXSFAIL);
  EXPECT_EQ(target.proposal_status(), loop::ProposalStatus::none);  // withdrawn
  target.step_once();
  EXPECT_EQ(target.cycle().tunables().body.mass_kg, 100.0);
  // A command is queued, not refused: ACKNOWLEDGE.
  EXPECT_EQ(modbus_write_bit(c.ctx(), 0, 1), -1);
  EXPECT_EQ(errno, EMBXACK);
}

TEST(ModbusServerConfig, ErrorsNameTheSetting) {
  // The setting comes as a field of the status, the reason as its message (zerog-rt's
  // configuration names the key from the field, never from the text).
  const auto expect_setting = [](const Status& st, const std::string& setting,
                                 const std::string& why) {
    EXPECT_EQ(st.code(), StatusCode::invalid_setting) << st.text();
    EXPECT_EQ(st.setting(), setting) << st.text();
    EXPECT_NE(st.message().find(why), std::string::npos) << st.text();
    EXPECT_EQ(st.message().find(setting + ":"), std::string::npos) << st.text();
  };
  ServerConfig c;
  expect_setting(check_server_config(c), "bind_address", "required");
  EXPECT_NE(check_server_config(c).text().find("bind_address: required"), std::string::npos);
  c.bind_address = "localhost";
  expect_setting(check_server_config(c), "bind_address", "'localhost' is not an IPv4");
  c.bind_address = "127.0.0.1";
  EXPECT_TRUE(check_server_config(c).ok());
  EXPECT_EQ(check_server_config(c).code(), StatusCode::ok);
  EXPECT_EQ(check_server_config(c).text(), "");
  c.allow = {"10.0.0.0/8", "10.0.0.5/24"};
  EXPECT_EQ(check_server_config(c).text(),
            "allow[1]: '10.0.0.5/24' has host bits set (did you mean 10.0.0.0/24?)");
  expect_setting(check_server_config(c), "allow[1]", "has host bits set");
  c.allow = {"10.0.0.0/33"};
  expect_setting(check_server_config(c), "allow[0]", "prefix length");
  c.allow = {"10.0.0.0/8", "ten"};
  expect_setting(check_server_config(c), "allow[1]", "is not an IPv4 address or network");
  c.allow.clear();
  c.max_clients = 0;
  expect_setting(check_server_config(c), "max_clients", "1..64");
  c.max_clients = 4;
  c.request_timeout_s = 0.0;
  expect_setting(check_server_config(c), "request_timeout_s", "(0, 10]");
  c.request_timeout_s = 0.5;
  c.idle_timeout_s = -1.0;
  expect_setting(check_server_config(c), "idle_timeout_s", "86400");
  c.idle_timeout_s = 60.0;
  c.proposal_timeout_s = 6.0;
  expect_setting(check_server_config(c), "proposal_timeout_s", "(0, 5]");
  c.proposal_timeout_s = 0.25;
  c.port = 70000;
  expect_setting(check_server_config(c), "port", "0..65535");

  Allowlist a;
  ASSERT_EQ(a.parse({"192.168.1.0/24", "10.0.0.7"}).text(), "");
  EXPECT_TRUE(a.permits(0xC0A801FE));   // 192.168.1.254
  EXPECT_FALSE(a.permits(0xC0A802FE));  // 192.168.2.254
  EXPECT_TRUE(a.permits(0x0A000007));
  EXPECT_FALSE(a.permits(0x0A000008));
}

TEST(ModbusServerConfig, StartRefusesABadConfigurationAndASecondStart) {
  CycleTarget target;
  ServerConfig bad = local_config();
  bad.max_clients = 0;
  ModbusServer refused(bad, target);
  const Status st = refused.start();
  EXPECT_EQ(st.code(), StatusCode::invalid_setting);
  EXPECT_EQ(st.setting(), "max_clients");
  EXPECT_EQ(refused.port(), 0);

  ModbusServer server(local_config(), target);
  ASSERT_EQ(server.start().text(), "");
  EXPECT_EQ(server.start().code(), StatusCode::already_started);
}

TEST(ModbusServerConfig, ABindFailureSaysWhereAndWhy) {
  CycleTarget target;
  ModbusServer first(local_config(), target);
  ASSERT_EQ(first.start().text(), "");
  ServerConfig taken = local_config();
  taken.port = first.port();
  ModbusServer second(taken, target);
  const Status st = second.start();
  EXPECT_EQ(st.code(), StatusCode::system_error);
  const std::string why = st.text();
  EXPECT_NE(why.find("cannot bind 127.0.0.1:" + std::to_string(first.port())), std::string::npos)
      << why;
  EXPECT_NE(why.find("in use"), std::string::npos) << why;
}

}  // namespace
}  // namespace zerog::modbus
