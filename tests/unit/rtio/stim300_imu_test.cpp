// Stim300Imu on a real pty (no VM needed): the test writes datagrams made by the codec's encoder,
// garbage and a corrupted CRC into the master side; the device reads the slave side like any tty.
#include <gtest/gtest.h>

#include <termios.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <vector>

#include "pty.hpp"
#include "zerog/proto/stim300.hpp"
#include "zerog/rtio/fake_imu.hpp"
#include "zerog/rtio/serial_port.hpp"
#include "zerog/rtio/stim300_imu.hpp"

namespace zerog::rtio {
namespace {

namespace stim300 = proto::stim300;
using namespace std::chrono_literals;

struct Motion {
  std::array<double, 3> rate_rad_s{};
  std::array<double, 3> accel_m_s2{};
  std::array<double, 3> incl_m_s2{};
};

Motion motion(int k) {
  const double t = 0.1 * k;
  return {{0.1 + t, -0.2, 0.3 * std::sin(t)}, {0.5, -9.80665 + t, 1.25}, {0.4, -9.7, 0.05 * k}};
}

std::vector<std::uint8_t> datagram(std::uint8_t counter, const Motion& m,
                                   std::uint8_t accel_status = 0) {
  stim300::RawDatagram raw;
  raw.identifier = 0x93;
  const stim300::Scale scale;
  for (int i = 0; i < 3; ++i) {
    raw.rate.counts[i] = stim300::rate_counts(m.rate_rad_s[i]);
    raw.accel.counts[i] = stim300::accel_counts(m.accel_m_s2[i], scale);
    raw.incl.counts[i] = stim300::incl_counts(m.incl_m_s2[i]);
  }
  raw.accel.status = accel_status;
  raw.counter = counter;
  raw.latency_us = 250;
  std::array<std::uint8_t, stim300::kMaxDatagramLength + 2> buffer{};
  const stim300::EncodeResult r = stim300::encode_datagram(raw, true, buffer);
  EXPECT_EQ(r.status, stim300::EncodeStatus::ok);
  return {buffer.begin(), buffer.begin() + static_cast<std::ptrdiff_t>(r.size)};
}

void append(std::vector<std::uint8_t>& to, const std::vector<std::uint8_t>& bytes) {
  to.insert(to.end(), bytes.begin(), bytes.end());
}

// Independent check: within one LSB of what was encoded (rate 2^-14 °/s, acc 2^-19 g, incl 2^-22
// g).
void expect_motion(const ImuSample& s, const Motion& m) {
  const double rate_lsb = 3.14159265358979323846 / 180.0 / 16384.0;
  const double accel_lsb = 9.80665 / 524288.0;
  const double incl_lsb = 9.80665 / 4194304.0;
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(s.rate_rad_s[i], m.rate_rad_s[i], rate_lsb) << i;
    EXPECT_NEAR(s.accel_m_s2[i], m.accel_m_s2[i], accel_lsb) << i;
    EXPECT_NEAR(s.incl_m_s2[i], m.incl_m_s2[i], incl_lsb) << i;
  }
}

class Stim300ImuTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(pty_.ok()) << "posix_openpt failed"; }
  Stim300Config config(std::chrono::nanoseconds timeout = 200ms) const {
    Stim300Config c;
    c.path = pty_.slave_path();
    c.serial.baud = 921600;
    c.read_timeout = timeout;
    return c;
  }
  test::Pty pty_;
};

TEST_F(Stim300ImuTest, DecodesDatagramsPastGarbageBadCrcAndCounterGaps) {
  Stim300Imu imu(config());
  ASSERT_EQ(imu.start(), ImuStartStatus::ok);

  std::vector<std::uint8_t> stream;
  append(stream, datagram(10, motion(0)));
  append(stream, {0x00, 0x11, 0x22, 0x33, 0x44, 0x55, 0x66});  // line noise
  append(stream, datagram(11, motion(1)));
  std::vector<std::uint8_t> corrupted = datagram(12, motion(2));
  corrupted[20] ^= 0x40;  // a bit flip: the CRC no longer matches
  append(stream, corrupted);
  append(stream, datagram(13, motion(3)));
  append(stream, datagram(15, motion(5)));  // 14 lost
  append(stream, datagram(16, motion(6), /*accel_status=*/0x01));
  ASSERT_TRUE(pty_.write(stream));

  const std::array<int, 5> expected_k{0, 1, 3, 5, 6};
  const std::array<int, 5> expected_missed{0, 0, 1, 1, 0};
  for (std::size_t i = 0; i < expected_k.size(); ++i) {
    ImuSample s;
    ASSERT_EQ(imu.read_sample(s), ImuReadStatus::sample) << i;
    expect_motion(s, motion(expected_k[i]));
    EXPECT_EQ(s.counter, 10 + expected_k[i]);
    EXPECT_EQ(s.missed_before, expected_missed[i]) << i;
    EXPECT_EQ(s.sequence, i + 1);
    EXPECT_NEAR(s.latency_s, 250e-6, 1e-12);
    EXPECT_TRUE(s.rate_valid);
    EXPECT_TRUE(s.incl_valid);
    EXPECT_EQ(s.accel_valid, i != 4) << i;  // the last one has an accelerometer status bit
    EXPECT_GT(s.arrived_ns, 0);
  }
  ImuSample s;
  const auto before = std::chrono::steady_clock::now();
  EXPECT_EQ(imu.read_sample(s), ImuReadStatus::timeout);
  EXPECT_GE(std::chrono::steady_clock::now() - before, 150ms);

  const ImuCounters c = imu.counters();
  EXPECT_EQ(c.samples, 5u);
  EXPECT_EQ(c.invalid_samples, 1u);
  EXPECT_EQ(c.bytes_read, stream.size());
  EXPECT_EQ(c.crc_failures, 1u);
  EXPECT_EQ(c.counter_gaps, 2u);  // 12 (bad CRC) and 14 (never sent)
  EXPECT_EQ(c.datagrams_missed, 2u);
  EXPECT_EQ(c.sync_losses, 2u);  // the garbage and the bad datagram
  EXPECT_GE(c.bytes_skipped, 7u + corrupted.size());
  EXPECT_EQ(c.timeouts, 1u);
}

// Lockstep's read (proto/lockstep.md): up to a byte count, never past it, `drained` at once when
// the bytes up to it complete no further datagram (garbage), without waiting for the timeout.
TEST_F(Stim300ImuTest, ReadUpToAByteCountStopsThereAndSaysDrained) {
  Stim300Imu imu(config(200ms));
  ASSERT_EQ(imu.start(), ImuStartStatus::ok);
  std::vector<std::uint8_t> first;
  append(first, datagram(1, motion(1)));
  append(first, {0x00, 0x11, 0x22, 0x33});  // garbage after it
  const std::vector<std::uint8_t> second = datagram(2, motion(2));
  std::vector<std::uint8_t> stream = first;
  append(stream, second);
  ASSERT_TRUE(pty_.write(stream));

  ImuSample s;
  ASSERT_EQ(imu.read_sample_upto(s, first.size(), 5s), ImuReadStatus::sample);
  expect_motion(s, motion(1));
  const auto before = std::chrono::steady_clock::now();
  EXPECT_EQ(imu.read_sample_upto(s, first.size(), 5s), ImuReadStatus::drained);
  EXPECT_LT(std::chrono::steady_clock::now() - before, 1s);  // not the 5 s wait
  EXPECT_EQ(imu.counters().bytes_read, first.size());        // nothing of the second read
  EXPECT_EQ(imu.counters().timeouts, 0u);
  ASSERT_EQ(imu.read_sample_upto(s, stream.size(), 5s), ImuReadStatus::sample);
  expect_motion(s, motion(2));
  EXPECT_EQ(imu.read_sample_upto(s, stream.size(), 5s), ImuReadStatus::drained);
  EXPECT_FALSE(imu.pop_buffered(s));
}

TEST_F(Stim300ImuTest, DatagramSplitAcrossReads) {
  Stim300Imu imu(config(50ms));
  ASSERT_EQ(imu.start(), ImuStartStatus::ok);
  const std::vector<std::uint8_t> d = datagram(200, motion(2));
  ASSERT_TRUE(pty_.write(std::span(d).first(17)));
  ImuSample s;
  EXPECT_EQ(imu.read_sample(s), ImuReadStatus::timeout);  // half a datagram is not a sample
  ASSERT_TRUE(pty_.write(std::span(d).subspan(17)));
  ASSERT_EQ(imu.read_sample(s), ImuReadStatus::sample);
  expect_motion(s, motion(2));
  EXPECT_EQ(s.counter, 200);
}

TEST_F(Stim300ImuTest, UnpluggedTtyIsDetected) {
  Stim300Imu imu(config());
  ASSERT_EQ(imu.start(), ImuStartStatus::ok);
  ASSERT_TRUE(pty_.write(datagram(1, motion(1))));
  ImuSample s;
  ASSERT_EQ(imu.read_sample(s), ImuReadStatus::sample);

  pty_.close_master();  // the cable is pulled
  EXPECT_EQ(imu.read_sample(s), ImuReadStatus::disconnected);
  EXPECT_EQ(imu.read_sample(s), ImuReadStatus::disconnected);  // stays reported, no spinning
  EXPECT_EQ(imu.counters().disconnects, 1u);
  EXPECT_EQ(imu.start(), ImuStartStatus::open_failed);  // the pty is gone
}

TEST_F(Stim300ImuTest, OpenFailuresAreStatuses) {
  Stim300Config c = config();
  c.path = "/nonexistent/ttyZEROG";
  EXPECT_EQ(Stim300Imu(c).start(), ImuStartStatus::open_failed);
  c.path = "/dev/null";  // not a tty
  EXPECT_EQ(Stim300Imu(c).start(), ImuStartStatus::bad_config);
  c = config();
  c.serial.baud = 12345;
  EXPECT_EQ(Stim300Imu(c).start(), ImuStartStatus::bad_config);
  ImuSample s;
  EXPECT_EQ(Stim300Imu(c).read_sample(s), ImuReadStatus::not_started);
}

TEST_F(Stim300ImuTest, SerialPortIsRawAtTheConfiguredBaud) {
  SerialPort port;
  ASSERT_TRUE(port.open(pty_.slave_path(), SerialConfig{921600, true, true}).ok());
  termios tio{};
  ASSERT_EQ(::tcgetattr(port.fd(), &tio), 0);
  EXPECT_EQ(::cfgetispeed(&tio), static_cast<speed_t>(B921600));
  EXPECT_EQ(::cfgetospeed(&tio), static_cast<speed_t>(B921600));
  EXPECT_EQ(tio.c_lflag & (ICANON | ECHO | ISIG | IEXTEN), 0u);
  EXPECT_EQ(tio.c_iflag & (ICRNL | IXON | ISTRIP), 0u);
  EXPECT_EQ(tio.c_oflag & OPOST, 0u);
  EXPECT_EQ(tio.c_cflag & CSIZE, static_cast<tcflag_t>(CS8));
  EXPECT_EQ(baud_to_speed(115200), static_cast<unsigned>(B115200));
  EXPECT_EQ(baud_to_speed(1234), 0u);

  // Bytes that a cooked tty would translate (CR, ^C, ^S, DEL) arrive unchanged.
  const std::array<std::uint8_t, 6> bytes{'\r', 0x03, 0x13, 0x7F, '\n', 0x00};
  ASSERT_TRUE(pty_.write(bytes));
  std::array<std::uint8_t, 16> got{};
  std::size_t total = 0;
  while (total < bytes.size()) {
    const SerialReadResult r = port.read(std::span(got).subspan(total), 200ms);
    ASSERT_EQ(r.status, SerialReadStatus::data);
    total += r.size;
  }
  EXPECT_TRUE(std::equal(bytes.begin(), bytes.end(), got.begin()));
  EXPECT_EQ(port.read(got, 10ms).status, SerialReadStatus::timeout);
}

TEST(FakeImu, ReturnsTheScriptAndCounts) {
  FakeImu fake;
  ImuSample s;
  EXPECT_EQ(fake.read_sample(s), ImuReadStatus::not_started);
  ASSERT_EQ(fake.start(), ImuStartStatus::ok);
  ImuSample gap;
  gap.rate_valid = gap.accel_valid = gap.incl_valid = true;
  gap.missed_before = 3;
  fake.push(ImuReadStatus::sample, gap);
  fake.push(ImuReadStatus::disconnected);
  EXPECT_EQ(fake.read_sample(s), ImuReadStatus::sample);
  EXPECT_EQ(s.sequence, 1u);
  EXPECT_EQ(fake.read_sample(s), ImuReadStatus::disconnected);
  EXPECT_EQ(fake.read_sample(s), ImuReadStatus::not_started);
  EXPECT_EQ(fake.counters().datagrams_missed, 3u);
  EXPECT_EQ(fake.counters().disconnects, 1u);
}

}  // namespace
}  // namespace zerog::rtio
