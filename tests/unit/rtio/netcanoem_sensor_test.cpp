// NetcanoemSensor on a FakeCanBus with the emulated board (zerog::emu::AtiBoard): start-up,
// conversion to SI, status classification and every counted drop. The same device on real
// SocketCAN: tests/vm/.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "netcanoem_board.hpp"
#include "zerog/emu/ati_board.hpp"
#include "zerog/rtio/can_socket.hpp"
#include "zerog/rtio/fake_can_bus.hpp"
#include "zerog/rtio/fake_ft_sensor.hpp"
#include "zerog/rtio/netcanoem_sensor.hpp"

namespace zerog::rtio {
namespace {

namespace netcanoem = proto::netcanoem;

constexpr double kNewtonPerLbf = 4.4482216152605;
constexpr double kNewtonMetrePerLbfIn = 4.4482216152605 * 0.0254;
/// The gauges the board reports unless a test sets others.
constexpr std::array<std::int16_t, 6> kGauges{1200, -800, 2500, 640, -1800, 90};

class NetcanoemSensorTest : public ::testing::Test {
 protected:
  /// The board, made from board_config_ on first use (change board_config_ before that). Its
  /// answers are queued on bus_ with receive times 1000, 1001, … per answer.
  emu::AtiBoard& board() {
    if (!board_) {
      board_ = std::make_unique<emu::AtiBoard>(board_config_);
      board_->set_gauges(kGauges);
      responder_ = std::make_unique<emu::AtiBoardResponder>(*board_, 1000);
      bus_.set_responder(responder_.get());
    }
    return *board_;
  }
  void set_quirks(const emu::AtiBoardQuirks& quirks) { board().set_quirks(quirks); }

  NetcanoemConfig config() {
    board();
    NetcanoemConfig c;
    c.base_id = board_config_.base_id;
    return c;
  }
  // The thermistor read with every poll, −50 °C at 0 counts and 10 mK per count (the scripted
  // interleavings' conversion).
  NetcanoemConfig thermistor_every_poll() {
    NetcanoemConfig c = config();
    c.thermistor_every_polls = 1;
    c.thermistor = netcanoem::ThermistorConversion{-50.0, 0.01};
    return c;
  }

  static void expect_wrench(const std::array<double, 6>& got, const std::array<double, 6>& want) {
    for (int i = 0; i < 6; ++i) EXPECT_NEAR(got[i], want[i], 1e-9 * (1 + std::abs(want[i]))) << i;
  }

  // How many frames with `opcode` the sensor has written.
  std::size_t written_with(netcanoem::Opcode opcode) const {
    std::size_t n = 0;
    for (std::uint64_t i = 0; i < bus_.written_count(); ++i) {
      if (netcanoem::opcode_of(bus_.written(i).id) == static_cast<std::uint8_t>(opcode)) ++n;
    }
    return n;
  }

  FakeCanBus bus_;
  emu::AtiBoardConfig board_config_;
  std::unique_ptr<emu::AtiBoard> board_;
  std::unique_ptr<emu::AtiBoardResponder> responder_;
};

TEST_F(NetcanoemSensorTest, StartUpReadsTheCalibration) {
  NetcanoemConfig c = config();
  c.calibration_index = 2;
  NetcanoemSensor sensor(bus_, c);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  const netcanoem::Calibration& cal = sensor.calibration();
  EXPECT_EQ(cal.active_calibration, 2);
  EXPECT_EQ(cal.firmware.major, 3);
  EXPECT_EQ(cal.firmware.minor, 8);
  EXPECT_EQ(cal.firmware.build, 1201);
  EXPECT_STREQ(cal.serial_number.data(), "FT42007A");
  for (int r = 0; r < 6; ++r)
    for (int col = 0; col < 6; ++col) EXPECT_EQ(cal.matrix[r][col], board_config_.matrix[r][col]);
  EXPECT_TRUE(cal.counts_from_device);
  EXPECT_EQ(cal.counts_per_force, 1'000'000u);
  EXPECT_EQ(cal.force_unit, 2);
  EXPECT_EQ(cal.torque_unit, 3);
  EXPECT_EQ(written_with(netcanoem::Opcode::matrix_sg01), 6u);
  EXPECT_EQ(written_with(netcanoem::Opcode::counts), 1u);
  EXPECT_TRUE(sensor.started());
}

TEST_F(NetcanoemSensorTest, FirmwareBefore37UsesTheDefaultCounts) {
  board_config_.firmware = {3, 6, 7};
  board_config_.counts_per_force = 123;  // must not be used (and is never asked for)
  NetcanoemSensor sensor(bus_, config());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  EXPECT_FALSE(sensor.calibration().counts_from_device);
  EXPECT_EQ(sensor.calibration().counts_per_force, netcanoem::kDefaultCounts);
  EXPECT_EQ(sensor.calibration().counts_per_torque, netcanoem::kDefaultCounts);
  EXPECT_EQ(written_with(netcanoem::Opcode::counts), 0u);
}

TEST_F(NetcanoemSensorTest, SampleBecomesAnSiWrench) {
  board_config_.counts_per_force = 1'000'000;
  board_config_.counts_per_torque = 1000;
  board_config_.force_unit = 1;   // lbf
  board_config_.torque_unit = 1;  // lbf·in
  NetcanoemConfig c = config();
  c.bias_gauges = {10.0, -4.0, 0.5, 0.0, 20.0, -7.25};
  NetcanoemSensor sensor(bus_, c);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);

  FtSample s;
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_TRUE(s.valid);
  EXPECT_EQ(s.status, FtSampleStatus::ok);
  EXPECT_EQ(s.gauges, kGauges);
  EXPECT_EQ(s.sequence, 1u);
  EXPECT_EQ(s.arrived_ns, 1001);  // of the second (completing) frame
  expect_wrench(s.wrench_si, test::expected_wrench_si(board_config_, kGauges, c.bias_gauges,
                                                      kNewtonPerLbf, kNewtonMetrePerLbfIn));

  const std::array<std::int16_t, 6> gauges{-30000, 15000, 0, 1, -1, 32000};
  board().set_gauges(gauges);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.sequence, 2u);
  EXPECT_EQ(s.gauges, gauges);
  expect_wrench(s.wrench_si, test::expected_wrench_si(board_config_, gauges, c.bias_gauges,
                                                      kNewtonPerLbf, kNewtonMetrePerLbfIn));
  const FtCounters counters = sensor.counters();
  EXPECT_EQ(counters.requests, 2u);
  EXPECT_EQ(counters.samples, 2u);
  EXPECT_EQ(counters.timeouts, 0u);
}

TEST_F(NetcanoemSensorTest, StatusClassification) {
  NetcanoemSensor sensor(bus_, config());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  FtSample s;

  const std::uint16_t bus_error = netcanoem::kStatusCanBusError | netcanoem::kStatusAnyError;
  board().set_status_word(bus_error);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.status, FtSampleStatus::warning);  // bus error: warn, keep using it
  EXPECT_TRUE(s.valid);
  EXPECT_EQ(s.status_word, bus_error);

  board().set_status_word((1u << 3) | netcanoem::kStatusAnyError);  // a critical bit
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.status, FtSampleStatus::critical);
  EXPECT_FALSE(s.valid);

  board().set_status_word(0);
  std::array<std::int16_t, 6> railed = kGauges;
  railed[4] = -32768;  // rail
  board().set_gauges(railed);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.status, FtSampleStatus::saturated);
  EXPECT_EQ(s.saturated_mask, 1u << 4);
  EXPECT_FALSE(s.valid);

  const FtCounters c = sensor.counters();
  EXPECT_EQ(c.samples, 3u);
  EXPECT_EQ(c.samples_warning, 1u);
  EXPECT_EQ(c.samples_critical, 1u);
  EXPECT_EQ(c.samples_saturated, 1u);
}

TEST_F(NetcanoemSensorTest, StrayWrongLengthAndErrorFramesAreCountedAndWaitedPast) {
  NetcanoemSensor sensor(bus_, config());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  const std::uint8_t base = board_config_.base_id;

  proto::CanFrame stray;  // another opcode of the board
  stray.id = netcanoem::can_id(base, netcanoem::Opcode::serial_number);
  stray.len = 8;
  proto::CanFrame short_a;  // a 0x0 response cut to 5 bytes
  short_a.id = netcanoem::can_id(base, netcanoem::Opcode::sample_a);
  short_a.len = 5;
  proto::CanFrame error;  // bus error frame: no ACK + bus error
  error.id = proto::kCanErrorFlag | 0x020u | 0x080u;
  error.len = 8;
  emu::AtiBoardQuirks quirks;
  quirks.before_sample = {stray, short_a, error, stray};
  quirks.before_sample_count = 4;
  set_quirks(quirks);

  FtSample s;
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_TRUE(s.valid);
  const FtCounters c = sensor.counters();
  EXPECT_EQ(c.stray_frames, 2u);
  EXPECT_EQ(c.wrong_length, 1u);
  EXPECT_EQ(c.error_frames, 1u);
  EXPECT_EQ(bus_.counters().error_classes[static_cast<int>(CanErrorClass::no_ack)], 1u);
  EXPECT_EQ(bus_.counters().error_classes[static_cast<int>(CanErrorClass::bus_error)], 1u);
  EXPECT_EQ(bus_.counters().error_classes[static_cast<int>(CanErrorClass::bus_off)], 0u);
}

TEST_F(NetcanoemSensorTest, SilentSensorTimesOutAndIsCounted) {
  NetcanoemSensor sensor(bus_, config());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  board().set_fault(emu::FtFault::silent);
  FtSample s;
  s.sequence = 77;
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::timeout);
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::timeout);
  EXPECT_EQ(s.sequence, 77u);  // untouched
  EXPECT_EQ(sensor.counters().timeouts, 2u);
  EXPECT_EQ(sensor.counters().requests, 2u);
  board().set_fault(emu::FtFault::none);
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::sample);
}

TEST_F(NetcanoemSensorTest, HalfResponseTimesOutAndLateFramesAreDrainedAsStale) {
  NetcanoemSensor sensor(bus_, config());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  // Only the first half arrives: the sample is incomplete when the wait ends.
  const auto frames = netcanoem::encode_sample(board_config_.base_id, kGauges, 0).value();
  emu::AtiBoardQuirks quirks;
  quirks.before_sample[0] = frames[0];
  quirks.before_sample_count = 1;
  quirks.no_sample_response = true;
  set_quirks(quirks);
  FtSample s;
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::timeout);
  // Its second half comes late, with a whole old pair: drained before the next request.
  bus_.inject(frames[1]);
  bus_.inject(frames[0]);
  bus_.inject(frames[1]);
  set_quirks({});
  const std::array<std::int16_t, 6> fresh{1, 2, 3, 4, 5, 6};
  board().set_gauges(fresh);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.gauges, fresh);  // the fresh answer, not the stale pair
  EXPECT_EQ(sensor.counters().stale_frames, 3u);
  EXPECT_EQ(sensor.counters().timeouts, 1u);
}

// Answers each sample request with scripted frames (A = 0x0, B = 0x1 of a poll) in a given
// order, after start-up went through the emulated board.
class ScriptedBoard final : public CanResponder {
 public:
  explicit ScriptedBoard(std::uint8_t base_id) : base_id_(base_id) {}
  /// Gauges of poll p, distinct in every gauge, so a mixed pair cannot pass for either poll.
  static std::array<std::int16_t, 6> gauges(int p) {
    std::array<std::int16_t, 6> g{};
    for (int i = 0; i < 6; ++i) g[i] = static_cast<std::int16_t>(100 * p + 10 * i + p * i);
    return g;
  }
  /// The frames to queue for the next requests, e.g. {"A2", "B1", "B2"}; "T123" is a thermistor
  /// answer (0x9) of 123 counts. Only sample requests take a script line (a thermistor request
  /// gets its answer wherever the script puts it).
  void then(std::vector<std::string> frames) { script_.push_back(std::move(frames)); }
  void on_write(const proto::CanFrame& request, FakeCanBus& bus) override {
    if (request.len != 0 || next_ >= script_.size()) return;
    for (const std::string& f : script_[next_]) {
      if (f[0] == 'T') {
        const auto counts = static_cast<std::uint16_t>(std::stoi(f.substr(1)));
        bus.inject(CanRxFrame{*netcanoem::encode_diagnostic_adc(base_id_, counts), 0});
        continue;
      }
      const auto pair = netcanoem::encode_sample(base_id_, gauges(std::stoi(f.substr(1))), 0);
      bus.inject(CanRxFrame{(*pair)[f[0] == 'A' ? 0 : 1], 0});
    }
    ++next_;
  }

 private:
  std::uint8_t base_id_;
  std::vector<std::vector<std::string>> script_;
  std::size_t next_ = 0;
};

// Issue 15: a re-poll after a timeout while the first poll's 0x1 is still on its way. The late
// 0x1 completes its own 0x0 (dropped as late, counted), the new poll pairs its own frames.
TEST_F(NetcanoemSensorTest, RepollWhileASecondHalfIsOnItsWayPairsEachPollWithItsOwnFrames) {
  NetcanoemSensor sensor(bus_, config());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  ScriptedBoard script(board_config_.base_id);
  bus_.set_responder(&script);
  script.then({"A1"});              // B1 waits on the bus: timeout
  script.then({"A2", "B1", "B2"});  // re-poll: A2 overtakes B1
  script.then({"A3", "A4", "B3"});  // A4: not ours (e.g. a second host); B4 comes next poll
  script.then({"B4", "A5", "B5"});
  FtSample s;
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::timeout);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.gauges, ScriptedBoard::gauges(2));
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.gauges, ScriptedBoard::gauges(3));
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.gauges, ScriptedBoard::gauges(5));
  const FtCounters c = sensor.counters();
  EXPECT_EQ(c.late_samples, 2u);  // B1 with A1, B4 with A4
  EXPECT_EQ(c.timeouts, 1u);
  EXPECT_EQ(c.dropped_incomplete, 0u);
  EXPECT_EQ(c.overtaken, 2u);  // B1 (A2 queued behind A1), B3 (A4 queued behind A3)
  EXPECT_EQ(c.samples, 3u);
  bus_.set_responder(nullptr);
}

// A 0x1 lost for good (the board reset between its frames): the next poll's 0x1 completes the
// old half and is dropped as late; that poll times out and, as its pairing cannot be trusted,
// its own half is dropped too (counted). The poll after is exact again: no sample mixes polls.
TEST_F(NetcanoemSensorTest, ALostSecondHalfCostsTwoPollsAndMixesNothing) {
  NetcanoemSensor sensor(bus_, config());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  ScriptedBoard script(board_config_.base_id);
  bus_.set_responder(&script);
  script.then({"A1"});  // B1 lost
  script.then({"A2", "B2"});
  script.then({"A3", "B3"});
  script.then({"A4", "B4"});
  FtSample s;
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::timeout);
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::timeout);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.gauges, ScriptedBoard::gauges(3));
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.gauges, ScriptedBoard::gauges(4));
  const FtCounters c = sensor.counters();
  EXPECT_EQ(c.late_samples, 1u);
  EXPECT_EQ(c.dropped_incomplete, 1u);
  EXPECT_EQ(c.timeouts, 2u);
  bus_.set_responder(nullptr);
}

// --- The thermistor (opcode 0x9, diagnostic index 2), read between the gauge polls ----------

// With the emulated board: read with the first poll and then every N-th, its answer (queued
// behind that poll's sample pair) taken in the next poll and converted with the configured
// conversion; not counted stale, no sample lost.
TEST_F(NetcanoemSensorTest, ThermistorIsReadEveryNthPollAndReachesTheSample) {
  board_config_.temperature_C = 31.5;
  NetcanoemConfig c = config();
  c.thermistor_every_polls = 3;
  c.thermistor = board_config_.thermistor;
  NetcanoemSensor sensor(bus_, c);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  FtSample s;
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);  // poll 1: reads it, answer behind
  EXPECT_FALSE(s.thermistor_valid);
  EXPECT_FALSE(s.temperature_valid);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);  // poll 2: the answer of poll 1
  EXPECT_EQ(s.gauges, kGauges);
  ASSERT_TRUE(s.temperature_valid);
  EXPECT_TRUE(s.thermistor_valid);
  EXPECT_EQ(s.thermistor_counts, board().thermistor_counts());
  EXPECT_NEAR(s.temperature_C, 31.5, 0.5 * board_config_.thermistor.celsius_per_count);
  EXPECT_GE(s.temperature_age_s, 0.0);
  board().set_temperature(40.0);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);  // poll 3: no read
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);  // poll 4: reads it again
  EXPECT_NEAR(s.temperature_C, 31.5, 0.5 * board_config_.thermistor.celsius_per_count);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);  // poll 5: the new temperature
  EXPECT_NEAR(s.temperature_C, 40.0, 0.5 * board_config_.thermistor.celsius_per_count);
  EXPECT_EQ(written_with(netcanoem::Opcode::diagnostic_adc), 2u);  // polls 1 and 4
  const FtCounters counters = sensor.counters();
  EXPECT_EQ(counters.thermistor_requests, 2u);
  EXPECT_EQ(counters.thermistor_readings, 2u);
  EXPECT_EQ(counters.thermistor_lost, 0u);
  EXPECT_EQ(counters.stale_frames, 0u);
  EXPECT_EQ(counters.stray_frames, 0u);
  EXPECT_EQ(counters.samples, 5u);
  EXPECT_EQ(board().counters().thermistor_reads, 2u);
}

// Safety: a 0x9 answer arriving between a poll's 0x0 and 0x1 halves, and after a re-poll behind
// a late 0x1, is never paired as gauge data: each sample carries exactly its own poll's gauges.
// (The kept mutant, ctest netcanoem_mutant_diagnostic_as_gauge, takes the 0x9 payload as a second
// half: this test fails on it.)
TEST_F(NetcanoemSensorTest, ThermistorAnswerBetweenGaugeHalvesIsNeverPairedAsGaugeData) {
  NetcanoemSensor sensor(bus_, thermistor_every_poll());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  ScriptedBoard script(board_config_.base_id);
  bus_.set_responder(&script);
  script.then({"A1", "T7500", "B1"});        // between the halves
  script.then({"A2"});                       // B2 and the thermistor answer late: timeout
  script.then({"A3", "B2", "T8000", "B3"});  // re-poll: late B2, then the answer, then B3
  script.then({"T8100", "A4", "B4"});        // before the first half
  FtSample s;
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.gauges, ScriptedBoard::gauges(1));
  EXPECT_EQ(s.thermistor_counts, 7500u);
  EXPECT_NEAR(s.temperature_C, 25.0, 1e-9);
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::timeout);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.gauges, ScriptedBoard::gauges(3));
  EXPECT_EQ(s.thermistor_counts, 8000u);
  EXPECT_NEAR(s.temperature_C, 30.0, 1e-9);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.gauges, ScriptedBoard::gauges(4));
  EXPECT_EQ(s.thermistor_counts, 8100u);
  const FtCounters counters = sensor.counters();
  EXPECT_EQ(counters.samples, 3u);
  EXPECT_EQ(counters.late_samples, 1u);  // B2 with A2
  EXPECT_EQ(counters.out_of_order, 0u);
  EXPECT_EQ(counters.wrong_length, 0u);
  EXPECT_EQ(counters.thermistor_readings, 3u);
  EXPECT_EQ(counters.thermistor_lost, 1u);  // poll 2's read, unanswered when poll 3's was due
  bus_.set_responder(nullptr);
}

// A thermistor read that gets no answer is counted when the next one is due; the samples go on
// and no temperature is made up.
TEST_F(NetcanoemSensorTest, LostThermistorAnswersAreCountedNotFatal) {
  NetcanoemSensor sensor(bus_, thermistor_every_poll());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  ScriptedBoard script(board_config_.base_id);
  bus_.set_responder(&script);
  for (int p = 1; p <= 3; ++p) script.then({"A" + std::to_string(p), "B" + std::to_string(p)});
  FtSample s;
  for (int p = 1; p <= 3; ++p) {
    ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample) << p;
    EXPECT_EQ(s.gauges, ScriptedBoard::gauges(p));
    EXPECT_TRUE(s.valid);
    EXPECT_FALSE(s.thermistor_valid);
    EXPECT_FALSE(s.temperature_valid);
  }
  EXPECT_EQ(sensor.counters().thermistor_requests, 3u);
  EXPECT_EQ(sensor.counters().thermistor_lost, 2u);  // the third is still open
  bus_.set_responder(nullptr);
}

// A board that stops answering the thermistor reads (the samples go on): the held reading is
// used up to thermistor_max_age_polls sample requests after its read, then it is stale: no
// temperature any more (temperature_valid false, temperature_stale), counted once; the next
// answer makes it fresh again. Read every 2nd poll, at most 5 polls old.
TEST_F(NetcanoemSensorTest, ThermistorReadingExpiresWhenTheBoardStopsAnsweringAndRecovers) {
  board_config_.temperature_C = 31.5;
  NetcanoemConfig c = config();
  c.thermistor_every_polls = 2;
  c.thermistor_max_age_polls = 5;
  c.thermistor = board_config_.thermistor;
  NetcanoemSensor sensor(bus_, c);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  const double count = board_config_.thermistor.celsius_per_count;
  FtSample s;
  for (int p = 1; p <= 4; ++p) ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample) << p;
  ASSERT_TRUE(s.temperature_valid);  // the read of poll 3, taken in poll 4
  EXPECT_FALSE(s.temperature_stale);
  emu::AtiBoardQuirks quiet;
  quiet.no_diagnostic_response = true;
  set_quirks(quiet);
  // Polls 5–8: the reading of poll 3 is at most 5 polls old: still used.
  for (int p = 5; p <= 8; ++p) {
    ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample) << p;
    EXPECT_TRUE(s.temperature_valid) << p;
    EXPECT_FALSE(s.temperature_stale) << p;
    EXPECT_NEAR(s.temperature_C, 31.5, 0.5 * count) << p;
  }
  EXPECT_EQ(sensor.counters().thermistor_expired, 0u);
  // Poll 9: 6 polls old, stale; the samples themselves are fine.
  board().set_temperature(40.0);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_TRUE(s.valid);
  EXPECT_FALSE(s.temperature_valid);
  EXPECT_TRUE(s.temperature_stale);
  EXPECT_TRUE(s.thermistor_valid);  // the raw counts of the old reading stay for diagnosis
  EXPECT_EQ(sensor.counters().thermistor_expired, 1u);
  set_quirks({});
  // Polls 10, 11: still stale (counted once); poll 11 reads it, answered again.
  for (int p = 10; p <= 11; ++p) {
    ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample) << p;
    EXPECT_TRUE(s.temperature_stale) << p;
    EXPECT_FALSE(s.temperature_valid) << p;
  }
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);  // poll 12: poll 11's answer, fresh
  EXPECT_TRUE(s.temperature_valid);
  EXPECT_FALSE(s.temperature_stale);
  EXPECT_NEAR(s.temperature_C, 40.0, 0.5 * count);
  const FtCounters counters = sensor.counters();
  EXPECT_EQ(counters.thermistor_expired, 1u);
  EXPECT_EQ(counters.thermistor_lost, 3u);  // polls 5, 7, 9: unanswered when the next was due
  EXPECT_EQ(counters.samples, 12u);
  EXPECT_EQ(counters.timeouts, 0u);
}

// A board that never answers them: no reading this many polls after start() is stale too (the
// configured conversion says a temperature is expected). A maximum age not above the read
// period would expire every reading: refused.
TEST_F(NetcanoemSensorTest, ThermistorNeverAnsweredIsStaleAfterTheMaximumAge) {
  NetcanoemConfig c = config();
  c.thermistor_every_polls = 2;
  c.thermistor_max_age_polls = 5;
  c.thermistor = board_config_.thermistor;
  emu::AtiBoardQuirks quiet;
  quiet.no_diagnostic_response = true;
  set_quirks(quiet);
  NetcanoemSensor sensor(bus_, c);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  FtSample s;
  for (int p = 1; p <= 5; ++p) {
    ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample) << p;
    EXPECT_FALSE(s.temperature_valid) << p;
    EXPECT_FALSE(s.temperature_stale) << p;
  }
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_TRUE(s.temperature_stale);
  EXPECT_EQ(sensor.counters().thermistor_expired, 1u);
  // Without a conversion there is no temperature to expire.
  NetcanoemConfig raw = c;
  raw.thermistor.reset();
  NetcanoemSensor counts_only(bus_, raw);
  ASSERT_EQ(counts_only.start(), FtStartStatus::ok);
  for (int p = 1; p <= 8; ++p) ASSERT_EQ(counts_only.read_sample(s), FtReadStatus::sample) << p;
  EXPECT_FALSE(s.temperature_stale);
  EXPECT_EQ(counts_only.counters().thermistor_expired, 0u);
  c.thermistor_max_age_polls = 2;
  EXPECT_EQ(NetcanoemSensor(bus_, c).start(), FtStartStatus::bad_config);
}

// Without a conversion the reading stays raw counts; an answer nobody asked for (reads off, or
// someone else's read of another channel) and a 0x9 frame of a wrong length are counted and
// ignored.
TEST_F(NetcanoemSensorTest, ThermistorWithoutConversionUnrequestedAndWrongLength) {
  NetcanoemConfig c = config();
  c.thermistor_every_polls = 2;
  NetcanoemSensor sensor(bus_, c);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  FtSample s;
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_TRUE(s.thermistor_valid);
  EXPECT_EQ(s.thermistor_counts, board().thermistor_counts());
  EXPECT_FALSE(s.temperature_valid);
  bus_.inject(*netcanoem::encode_diagnostic_adc(board_config_.base_id, 1));  // unrequested
  proto::CanFrame odd = *netcanoem::encode_diagnostic_adc(board_config_.base_id, 2);
  odd.len = 3;
  bus_.inject(odd);
  ASSERT_EQ(sensor.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.thermistor_counts, board().thermistor_counts());  // not 1
  const FtCounters counters = sensor.counters();
  EXPECT_EQ(counters.thermistor_unrequested, 1u);
  EXPECT_EQ(counters.thermistor_wrong_length, 1u);
  EXPECT_EQ(counters.stray_frames, 0u);  // 0x9 frames never reach the gauge assembler
}

TEST_F(NetcanoemSensorTest, FullTxQueueIsCounted) {
  NetcanoemSensor sensor(bus_, config());
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  bus_.fail_writes(CanWriteStatus::would_block);
  FtSample s;
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::tx_failed);
  EXPECT_EQ(sensor.counters().tx_would_block, 1u);
  EXPECT_EQ(bus_.counters().tx_would_block, 1u);
  bus_.fail_writes(CanWriteStatus::io_error);
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::io_error);
  EXPECT_EQ(sensor.counters().io_errors, 1u);
}

TEST_F(NetcanoemSensorTest, NotStartedBeforeStart) {
  NetcanoemSensor sensor(bus_, config());
  FtSample s;
  EXPECT_EQ(sensor.read_sample(s), FtReadStatus::not_started);
  EXPECT_EQ(bus_.written_count(), 0u);
}

TEST_F(NetcanoemSensorTest, StartUpRetriesEachRequest) {
  emu::AtiBoardQuirks quirks;
  quirks.ignore_requests = 2;
  set_quirks(quirks);
  NetcanoemConfig c = config();
  c.startup_attempts = 3;
  NetcanoemSensor sensor(bus_, c);
  ASSERT_EQ(sensor.start(), FtStartStatus::ok);
  EXPECT_EQ(sensor.startup_retries(), 2u);
}

TEST_F(NetcanoemSensorTest, SilentSensorFailsStartUpAfterTheAttempts) {
  board().set_fault(emu::FtFault::silent);
  NetcanoemConfig c = config();
  c.startup_attempts = 3;
  NetcanoemSensor sensor(bus_, c);
  EXPECT_EQ(sensor.start(), FtStartStatus::no_response);
  EXPECT_EQ(bus_.written_count(), 3u);  // the set-calibration request, three times
  EXPECT_FALSE(sensor.started());
}

TEST_F(NetcanoemSensorTest, EchoMismatchFailsStartUp) {
  emu::AtiBoardQuirks quirks;
  quirks.wrong_echo = true;
  set_quirks(quirks);
  NetcanoemSensor sensor(bus_, config());
  EXPECT_EQ(sensor.start(), FtStartStatus::readout_failed);
  EXPECT_EQ(sensor.readout_error(), netcanoem::ReadoutError::echo_mismatch);
}

TEST_F(NetcanoemSensorTest, UnknownUnitsFailStartUp) {
  board_config_.torque_unit = 42;
  NetcanoemSensor sensor(bus_, config());
  EXPECT_EQ(sensor.start(), FtStartStatus::unknown_units);
}

TEST_F(NetcanoemSensorTest, BadThermistorConfigIsRefused) {
  NetcanoemConfig c = config();
  c.thermistor = netcanoem::ThermistorConversion{20.0, 0.0};  // every count the same °C
  EXPECT_EQ(NetcanoemSensor(bus_, c).start(), FtStartStatus::bad_config);
  c.thermistor.reset();
  c.thermistor_every_polls = -1;
  EXPECT_EQ(NetcanoemSensor(bus_, c).start(), FtStartStatus::bad_config);
}

TEST_F(NetcanoemSensorTest, BadConfig) {
  NetcanoemConfig c = config();
  c.calibration_index = 16;
  NetcanoemSensor sensor(bus_, c);
  EXPECT_EQ(sensor.start(), FtStartStatus::bad_config);
}

TEST(NetcanoemSocketConfig, FiltersTheBoardsIdsAndAllErrors) {
  const CanSocketConfig c = NetcanoemSensor::socket_config(0x21, 128);
  ASSERT_EQ(c.filter_count, 1u);
  proto::CanFrame f;
  f.id = 0x215;
  EXPECT_TRUE(c.filters[0].matches(f));
  f.id = 0x225;
  EXPECT_FALSE(c.filters[0].matches(f));
  f.id = 0x215 | proto::kCanExtendedFlag;
  EXPECT_FALSE(c.filters[0].matches(f));
  EXPECT_EQ(c.error_mask, kCanAllErrors);
  EXPECT_EQ(c.receive_buffer_bytes, 128 * 1024);
  EXPECT_TRUE(c.timestamps);
}

TEST(FakeFtSensor, ReturnsTheScriptAndCounts) {
  FakeFtSensor fake;
  FtSample s;
  EXPECT_EQ(fake.read_sample(s), FtReadStatus::not_started);
  ASSERT_EQ(fake.start(), FtStartStatus::ok);
  FtSample critical;
  critical.status = FtSampleStatus::critical;
  fake.push(FtReadStatus::sample, critical);
  fake.push(FtReadStatus::timeout);
  EXPECT_EQ(fake.read_sample(s), FtReadStatus::sample);
  EXPECT_EQ(s.status, FtSampleStatus::critical);
  EXPECT_EQ(s.sequence, 1u);
  EXPECT_EQ(fake.read_sample(s), FtReadStatus::timeout);
  EXPECT_EQ(fake.read_sample(s), FtReadStatus::timeout);  // script empty
  EXPECT_EQ(fake.counters().samples_critical, 1u);
  EXPECT_EQ(fake.counters().timeouts, 2u);
}

// Natively this kernel has no CAN: opening fails cleanly with a status, never an exception.
TEST(CanSocket, OpenFailuresAreReportedAsStatus) {
  CanSocket socket;
  EXPECT_EQ(socket.open("").status, CanOpenStatus::bad_argument);
  EXPECT_EQ(socket.open("a_name_far_too_long_for_ifnamsiz").status, CanOpenStatus::bad_argument);
  const CanOpenResult r = socket.open("zgnoif0");
  EXPECT_TRUE(r.status == CanOpenStatus::socket_failed ||
              r.status == CanOpenStatus::no_such_interface)
      << can_open_status_name(r.status);
  EXPECT_FALSE(socket.is_open());
  CanRxFrame rx;
  EXPECT_EQ(socket.read(rx, std::chrono::nanoseconds(0)), CanReadStatus::not_open);
  EXPECT_EQ(socket.write(proto::CanFrame{}), CanWriteStatus::not_open);
}

}  // namespace
}  // namespace zerog::rtio
