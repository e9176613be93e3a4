// zerog decode-can on a recorded candump log reproduces wrenches computed independently here
// (calibration matrix times gauges over counts, with Eigen), ignores other bus traffic and
// counts what it drops.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include <unistd.h>

#include "zerog/formats/log.hpp"
#include "zerog/io/can_decode.hpp"
#include "zerog/io/candump.hpp"

namespace zerog::io {

using formats::InputError;
namespace {

namespace nc = proto::netcanoem;
namespace fs = std::filesystem;
constexpr std::uint8_t kBase = 0x20;

struct Recording {
  std::string text;
  std::vector<io::CandumpRecord> records;
  double t = 1700000000.0;
  void add(const proto::CanFrame& f, const char* iface = "can0") {
    io::CandumpRecord r;
    r.timestamp_ns = std::llround(t * 1e6) * 1000;  // candump's stamps are whole microseconds
    r.interface = iface;
    r.frame = f;
    text += io::format_candump_line(r) + "\n";
    records.push_back(r);
    t += 0.0005;
  }
  // The same frames as candump prints them in its default output with timestamps `clock`.
  std::string columns(io::CandumpClock clock) const {
    std::string out;
    std::int64_t previous = records.front().timestamp_ns;
    for (io::CandumpRecord r : records) {
      const std::int64_t absolute = r.timestamp_ns;
      if (clock == io::CandumpClock::zero) r.timestamp_ns = absolute - records[0].timestamp_ns;
      if (clock == io::CandumpClock::delta) r.timestamp_ns = absolute - previous;
      previous = absolute;
      out += io::format_candump_columns(r, clock) + "\n";
    }
    return out;
  }
};

struct Fixture {
  Eigen::Matrix<double, 6, 6> C;
  std::uint32_t cpf = 1000000, cpt = 1000;  // counts per N, per N·m
  std::vector<std::array<std::int16_t, 6>> gauges;
  Recording rec;
};

// The calibration and, if `with_startup`, its read-out as zerog-rt records it at start-up.
Fixture make_calibrated(bool with_startup, std::mt19937& rng) {
  Fixture fx;
  std::uniform_real_distribution<float> coef(-2000.0f, 2000.0f);  // float32-exact on the wire
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) fx.C(r, c) = coef(rng);
  if (with_startup) {
    fx.rec.add(*nc::request_set_active_calibration(kBase, 0));
    fx.rec.add(*nc::encode_active_calibration(kBase, 0));
    for (int r = 0; r < 6; ++r) {
      fx.rec.add(*nc::request_matrix_row(kBase, static_cast<std::uint8_t>(r)));
      std::array<double, 6> row;
      for (int c = 0; c < 6; ++c) row[c] = fx.C(r, c);
      const auto frames = nc::encode_matrix_row(kBase, row).value();
      for (const auto& f : frames) fx.rec.add(f);
    }
    fx.rec.add(*nc::request_counts(kBase));
    fx.rec.add(*nc::encode_counts(kBase, fx.cpf, fx.cpt));
    fx.rec.add(*nc::request_units(kBase));
    fx.rec.add(*nc::encode_units(kBase, static_cast<std::uint8_t>(nc::ForceUnit::N),
                                 static_cast<std::uint8_t>(nc::TorqueUnit::N_m)));
  }
  return fx;
}

// The wrench of gauges `sg` (no bias), computed here from the fixture's calibration.
Eigen::Matrix<double, 6, 1> expected_wrench(const Fixture& fx,
                                            const std::array<std::int16_t, 6>& g) {
  Eigen::Matrix<double, 6, 1> sg;
  for (int i = 0; i < 6; ++i) sg[i] = g[i];
  Eigen::Matrix<double, 6, 1> w = fx.C * sg;
  w.head<3>() /= fx.cpf;
  w.tail<3>() /= fx.cpt;
  return w;
}

Fixture make(bool with_startup) {
  std::mt19937 rng(3);
  Fixture fx = make_calibrated(with_startup, rng);
  std::uniform_int_distribution<int> g(-20000, 20000);
  for (int k = 0; k < 40; ++k) {
    std::array<std::int16_t, 6> s;
    for (auto& v : s) v = static_cast<std::int16_t>(g(rng));
    fx.gauges.push_back(s);
    fx.rec.add(*nc::request_sample(kBase));
    const auto frames = *nc::encode_sample(kBase, s, 0);
    fx.rec.add(frames[0]);
    proto::CanFrame other{};  // other traffic on the bus, between the two halves
    other.id = 0x123;
    other.len = 2;
    fx.rec.add(other, "can0");
    fx.rec.add(frames[1]);
  }
  // One critical sample (status bit 2) and one with a saturated gauge: both dropped, counted.
  fx.rec.add(*nc::request_sample(kBase));
  const auto critical = nc::encode_sample(kBase, fx.gauges[0], 1u << 2).value();
  for (const auto& f : critical) fx.rec.add(f);
  auto sat = fx.gauges[0];
  sat[3] = 32767;
  const auto saturated = nc::encode_sample(kBase, sat, 0).value();
  for (const auto& f : saturated) fx.rec.add(f);
  return fx;
}

fs::path write_temp(const std::string& name, const std::string& text) {
  const fs::path p =
      fs::temp_directory_path() / ("zerog_can_" + std::to_string(::getpid()) + "_" + name);
  std::ofstream(p) << text;
  return p;
}

TEST(DecodeCan, ReproducesIndependentlyComputedWrenches) {
  const Fixture fx = make(true);
  const fs::path log = write_temp("ok.log", fx.rec.text);
  const CanDecodeResult r = decode_netcanoem_log(log, {});
  EXPECT_TRUE(r.calibration_from_log);
  ASSERT_EQ(r.samples.size(), fx.gauges.size());
  for (std::size_t k = 0; k < fx.gauges.size(); ++k) {
    Eigen::Matrix<double, 6, 1> sg;
    for (int i = 0; i < 6; ++i) sg[i] = fx.gauges[k][i];
    Eigen::Matrix<double, 6, 1> w = fx.C * sg;
    w.head<3>() /= fx.cpf;
    w.tail<3>() /= fx.cpt;
    for (int i = 0; i < 6; ++i)
      EXPECT_NEAR(r.samples[k].wrench[i], w[i], 1e-9 * (1 + std::abs(w[i]))) << k;
  }
  EXPECT_EQ(r.other_traffic, fx.gauges.size());
  EXPECT_EQ(r.unusable, 2u);
  EXPECT_EQ(r.counters.critical, 1u);
  EXPECT_EQ(r.counters.saturated, 1u);
  // The F/T recording round-trips through a file.
  const fs::path out = log.string() + ".csv";
  write_ft_recording(r, out, {log});
  std::ifstream in(out);
  std::string first, header;
  std::getline(in, first);
  std::getline(in, header);
  EXPECT_THAT(first, ::testing::HasSubstr("zerog-ft 1"));
  EXPECT_EQ(header, "t_s,Fx_N,Fy_N,Fz_N,Mx_Nm,My_Nm,Mz_Nm,status");
  EXPECT_THROW(write_ft_recording(r, log, {log}), std::runtime_error);  // never over the input
  fs::remove(log);
  fs::remove(out);
}

// Issue 15 acceptance: a candump log with overtaken 0x1 frames decodes every poll, each from its
// own two frames. Written from the real bus log's patterns (CANopen traffic beside the board, a
// host polling without waiting; the board's 0x1 overtaken by the next poll's 0x0 23 times in
// 808 polls): A1 A2 B1 B2, and twice in a row A1 A2 B1 A3 B2 B3 (A = 0x0, B = 0x1, digit = poll).
// Thermistor reads (0x9, index 2) interleaved with the polls as zerog-rt sends them, one inside
// a poll's two halves, plus a read of another channel, an unknown index, an unanswered request,
// an answer nobody asked for and a wrong-length frame: the samples stay exact, each gets the
// latest reading at or before it in temp_C (the first reading before any), the rest is counted.
TEST(DecodeCan, ThermistorReadsBecomeTempCAndNeverGaugeData) {
  std::mt19937 rng(21);
  Fixture fx = make_calibrated(true, rng);
  std::uniform_int_distribution<int> g(-20000, 20000);
  const auto thermistor = *nc::request_diagnostic_adc(kBase, nc::DiagnosticIndex::thermistor);
  const auto power = *nc::request_diagnostic_adc(kBase, nc::DiagnosticIndex::power);
  std::vector<std::uint16_t> counts_of_poll;  // the reading each sample should carry
  std::uint16_t latest = 0;
  for (int k = 0; k < 12; ++k) {
    std::array<std::int16_t, 6> s;
    for (auto& v : s) v = static_cast<std::int16_t>(g(rng));
    fx.gauges.push_back(s);
    const auto frames = *nc::encode_sample(kBase, s, 0);
    fx.rec.add(*nc::request_sample(kBase));
    const bool read = k % 4 == 1;
    const auto counts = static_cast<std::uint16_t>(7500 + 10 * k);
    if (read) fx.rec.add(thermistor);
    fx.rec.add(frames[0]);
    if (read && k == 5) fx.rec.add(*nc::encode_diagnostic_adc(kBase, counts));  // between halves
    fx.rec.add(frames[1]);
    if (read && k != 5) fx.rec.add(*nc::encode_diagnostic_adc(kBase, counts));  // after the pair
    if (read && k == 5) latest = counts;  // its answer came before its 0x1: the new one
    counts_of_poll.push_back(latest);
    if (read && k != 5) latest = counts;  // from the next poll on
  }
  counts_of_poll[0] = counts_of_poll[1] = 7510;  // before the first reading: the first reading
  fx.rec.add(power);                             // another channel: ignored
  fx.rec.add(*nc::encode_diagnostic_adc(kBase, 1));
  proto::CanFrame unknown = thermistor;  // an index the manual does not list
  unknown.data[0] = 9;
  fx.rec.add(unknown);
  fx.rec.add(*nc::encode_diagnostic_adc(kBase, 2));
  fx.rec.add(thermistor);                            // never answered …
  fx.rec.add(thermistor);                            // … before this one, also never answered
  fx.rec.add(*nc::encode_diagnostic_adc(kBase, 3));  // answers the last
  fx.rec.add(*nc::encode_diagnostic_adc(kBase, 4));  // nobody asked
  proto::CanFrame odd = *nc::encode_diagnostic_adc(kBase, 5);
  odd.len = 6;  // as long as a gauge half
  fx.rec.add(odd);

  const fs::path log = write_temp("thermistor.log", fx.rec.text);
  CanDecodeOptions o;
  o.thermistor = nc::ThermistorConversion{-50.0, 0.01};
  const CanDecodeResult r = decode_netcanoem_log(log, o);
  ASSERT_EQ(r.samples.size(), fx.gauges.size());
  for (std::size_t k = 0; k < fx.gauges.size(); ++k) {
    const Eigen::Matrix<double, 6, 1> w = expected_wrench(fx, fx.gauges[k]);
    for (int i = 0; i < 6; ++i)
      ASSERT_NEAR(r.samples[k].wrench[i], w[i], 1e-9 * (1 + std::abs(w[i]))) << "poll " << k;
    ASSERT_TRUE(r.samples[k].thermistor_counts.has_value()) << k;
    EXPECT_EQ(*r.samples[k].thermistor_counts, counts_of_poll[k]) << "poll " << k;
    EXPECT_NEAR(*r.samples[k].temperature_C, -50.0 + 0.01 * counts_of_poll[k], 1e-9) << k;
  }
  EXPECT_EQ(r.thermistor.size(), 4u);  // polls 1, 5, 9 and the late answer at the end
  const DiagnosticCounters& d = r.diagnostic;
  EXPECT_EQ(d.requests, 7u);
  EXPECT_EQ(d.thermistor_readings, 4u);
  EXPECT_EQ(d.other_channel, 1u);
  EXPECT_EQ(d.unknown_index, 1u);
  EXPECT_EQ(d.unanswered, 1u);
  EXPECT_EQ(d.unrequested, 1u);
  EXPECT_EQ(d.wrong_length, 1u);
  std::size_t startup_frames = 0;  // the read-out's frames: the assembler's only strays
  for (const auto& f : fx.rec.records) {
    const std::uint8_t op = nc::opcode_of(f.frame.id);
    if (op != 0x0 && op != 0x1 && op != 0x9) ++startup_frames;
  }
  EXPECT_EQ(r.counters.stray, startup_frames);  // 0x9 frames never reach the gauge assembler
  EXPECT_EQ(r.counters.out_of_order, 0u);
  EXPECT_TRUE(r.temperature_converted);

  // The recording: temp_C in °C (the log format's unit), and thermistor_counts.
  const fs::path out = write_temp("thermistor.csv", "");
  fs::remove(out);
  write_ft_recording(r, out, {log});
  std::ifstream in(out);
  std::string comment, header, first;
  std::getline(in, comment);
  std::getline(in, header);
  std::getline(in, first);
  EXPECT_EQ(header, "t_s,Fx_N,Fy_N,Fz_N,Mx_Nm,My_Nm,Mz_Nm,status,thermistor_counts,temp_C");
  EXPECT_THAT(first, ::testing::EndsWith(",0,7510,25.1000"));

  // Without a conversion: raw counts only, no temp_C.
  const CanDecodeResult raw = decode_netcanoem_log(log, {});
  EXPECT_FALSE(raw.temperature_converted);
  EXPECT_FALSE(raw.samples[0].temperature_C.has_value());
  fs::remove(out);
  write_ft_recording(raw, out, {log});
  std::ifstream in_raw(out);
  std::getline(in_raw, comment);
  std::getline(in_raw, comment);  // the note that temp_C needs a conversion
  std::getline(in_raw, header);
  EXPECT_THAT(comment, ::testing::HasSubstr("no temp_C without a conversion"));
  EXPECT_EQ(header, "t_s,Fx_N,Fy_N,Fz_N,Mx_Nm,My_Nm,Mz_Nm,status,thermistor_counts");
  o.thermistor = nc::ThermistorConversion{25.0, 0.0};
  EXPECT_THROW(decode_netcanoem_log(log, o), std::runtime_error);
  fs::remove(out);
  fs::remove(log);
}

TEST(DecodeCan, OvertakenSecondHalvesDecodeEveryPollFromItsOwnFrames) {
  std::mt19937 rng(11);
  Fixture fx = make_calibrated(true, rng);
  std::uniform_int_distribution<int> g(-20000, 20000);
  constexpr int kPolls = 808;
  for (int k = 0; k < kPolls; ++k) {
    std::array<std::int16_t, 6> s;
    for (auto& v : s) v = static_cast<std::int16_t>(g(rng));
    fx.gauges.push_back(s);
  }
  // Polls whose 0x1 is overtaken: 15 single (A B' B) and 4 double (A A' B A'' B' B''), 23 in all.
  std::vector<int> single, twice;
  for (int i = 0; i < 15; ++i) single.push_back(20 + 50 * i);
  for (int i = 0; i < 4; ++i) twice.push_back(45 + 200 * i);
  std::vector<std::pair<int, int>> order;  // (poll, 0 = 0x0 / 1 = 0x1) in bus order
  for (int k = 0; k < kPolls;) {
    if (std::find(single.begin(), single.end(), k) != single.end()) {
      order.insert(order.end(), {{k, 0}, {k + 1, 0}, {k, 1}, {k + 1, 1}});  // A1 A2 B1 B2
      k += 2;
    } else if (std::find(twice.begin(), twice.end(), k) != twice.end()) {
      order.insert(order.end(), {{k, 0}, {k + 1, 0}, {k, 1}, {k + 2, 0}, {k + 1, 1}, {k + 2, 1}});
      k += 3;
    } else {
      order.insert(order.end(), {{k, 0}, {k, 1}});
      k += 1;
    }
  }
  std::vector<double> t_own_b(kPolls);  // time of each poll's own 0x1 frame
  proto::CanFrame canopen{};            // lower ids win arbitration: SYNC and a PDO
  canopen.len = 8;
  for (std::size_t i = 0; i < order.size(); ++i) {
    const auto [poll, half] = order[i];
    if (half == 0) fx.rec.add(*nc::request_sample(kBase));
    const auto frames = *nc::encode_sample(kBase, fx.gauges[poll], 0);
    if (half == 1) t_own_b[poll] = static_cast<double>(std::llround(fx.rec.t * 1e6)) * 1e-6;
    fx.rec.add(frames[half]);
    canopen.id = i % 2 == 0 ? 0x080 : 0x181;
    fx.rec.add(canopen);
  }
  const fs::path log = write_temp("overtaken.log", fx.rec.text);
  const CanDecodeResult r = decode_netcanoem_log(log, {});
  fs::remove(log);
  ASSERT_EQ(r.samples.size(), static_cast<std::size_t>(kPolls));
  for (int k = 0; k < kPolls; ++k) {
    const Eigen::Matrix<double, 6, 1> w = expected_wrench(fx, fx.gauges[k]);
    for (int i = 0; i < 6; ++i)
      ASSERT_NEAR(r.samples[k].wrench[i], w[i], 1e-9 * (1 + std::abs(w[i]))) << "poll " << k;
    EXPECT_NEAR(r.samples[k].t_s, t_own_b[k], 1e-6) << "poll " << k;
  }
  EXPECT_EQ(r.counters.overtaken, 23u);
  EXPECT_EQ(r.counters.dropped_incomplete, 0u);
  EXPECT_EQ(r.counters.out_of_order, 0u);
  EXPECT_EQ(r.unconfirmed, 0u);
  EXPECT_EQ(r.unusable, 0u);
}

// A 0x1 that never comes (the board reset between its two frames): in-order pairing would shift
// every later pair by one poll. The run that never empties the queue is dropped, counted, and
// pairing starts afresh: no sample written mixes two polls.
TEST(DecodeCan, ALostSecondHalfDropsTheUnconfirmedRunNotMixedSamples) {
  std::mt19937 rng(12);
  Fixture fx = make_calibrated(true, rng);
  std::uniform_int_distribution<int> g(-20000, 20000);
  constexpr int kPolls = 100, kLost = 10;
  for (int k = 0; k < kPolls; ++k) {
    std::array<std::int16_t, 6> s;
    for (auto& v : s) v = static_cast<std::int16_t>(g(rng));
    fx.gauges.push_back(s);
    const auto frames = *nc::encode_sample(kBase, s, 0);
    fx.rec.add(frames[0]);
    if (k != kLost) fx.rec.add(frames[1]);
  }
  const fs::path log = write_temp("lost.log", fx.rec.text);
  const CanDecodeResult r = decode_netcanoem_log(log, {});
  fs::remove(log);
  ASSERT_EQ(r.unconfirmed, kMaxUnconfirmedRun + 1);
  // Polls 0–9 and, after the dropped run (and the half waiting with it), polls 44–99.
  ASSERT_EQ(r.samples.size(), kPolls - r.unconfirmed - 1);
  EXPECT_EQ(r.counters.dropped_incomplete, 1u);
  for (const DecodedWrench& s : r.samples) {
    bool own = false;  // equal to exactly one poll's wrench
    for (int k = 0; k < kPolls && !own; ++k) {
      const Eigen::Matrix<double, 6, 1> w = expected_wrench(fx, fx.gauges[k]);
      own = std::abs(s.wrench[0] - w[0]) <= 1e-9 * (1 + std::abs(w[0])) &&
            std::abs(s.wrench[5] - w[5]) <= 1e-9 * (1 + std::abs(w[5]));
    }
    EXPECT_TRUE(own) << "a sample mixes two polls at t = " << s.t_s;
  }
}

TEST(DecodeCan, WithoutTheStartUpItAsksForACalibration) {
  const Fixture fx = make(false);
  const fs::path log = write_temp("nocal.log", fx.rec.text);
  try {
    decode_netcanoem_log(log, {});
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("no complete calibration"));
  }
  fs::remove(log);
}

// The same bus traffic in every form candump writes decodes to the same samples: the same
// wrenches, and the same times on each form's clock (-L, -ta, -tA since 1970; -tz, -td since
// the first frame; no timestamps: k / --assume-rate).
TEST(DecodeCan, EveryCandumpFormDecodesToTheSameSamples) {
  const Fixture fx = make(true);
  const fs::path reference_log = write_temp("ref.log", fx.rec.text);
  const CanDecodeResult reference = decode_netcanoem_log(reference_log, {});
  ASSERT_EQ(reference.samples.size(), fx.gauges.size());
  EXPECT_EQ(reference.log.form, io::CandumpForm::log);
  EXPECT_EQ(reference.log.clock, io::CandumpClock::absolute);
  const double t_first_frame = static_cast<double>(fx.rec.records.front().timestamp_ns) * 1e-9;
  struct Form {
    const char* name;
    io::CandumpClock clock;
    double t_offset_s;  // what the form's clock subtracts from the time since 1970
  };
  for (const Form& f :
       {Form{"ta", io::CandumpClock::absolute, 0.0}, Form{"tA", io::CandumpClock::date, 0.0},
        Form{"tz", io::CandumpClock::zero, t_first_frame},
        Form{"td", io::CandumpClock::delta, t_first_frame},
        Form{"none", io::CandumpClock::none, 0.0}}) {
    SCOPED_TRACE(f.name);
    const fs::path log = write_temp(std::string(f.name) + ".log", fx.rec.columns(f.clock));
    CanDecodeOptions o;
    if (f.clock == io::CandumpClock::none) {
      // Without timestamps the wrenches would have no time: refused unless a rate is given.
      try {
        decode_netcanoem_log(log, o);
        FAIL() << "no error";
      } catch (const std::runtime_error& e) {
        EXPECT_THAT(e.what(), ::testing::HasSubstr("no timestamps"));
        EXPECT_THAT(e.what(), ::testing::HasSubstr("--assume-rate"));
      }
      o.assume_rate_hz = 500.0;
    }
    const CanDecodeResult r = decode_netcanoem_log(log, o);
    EXPECT_EQ(r.log.form, io::CandumpForm::columns);
    EXPECT_EQ(r.log.clock, f.clock) << r.log.clock_reason;  // detected, not given
    EXPECT_EQ(r.time_assumed, f.clock == io::CandumpClock::none);
    ASSERT_EQ(r.samples.size(), reference.samples.size());
    EXPECT_EQ(r.other_traffic, reference.other_traffic);
    EXPECT_EQ(r.unusable, reference.unusable);
    for (std::size_t k = 0; k < r.samples.size(); ++k) {
      EXPECT_EQ(r.samples[k].wrench, reference.samples[k].wrench) << k;
      EXPECT_EQ(r.samples[k].status, reference.samples[k].status) << k;
      const double t = f.clock == io::CandumpClock::none ? static_cast<double>(k) / 500.0
                                                         : reference.samples[k].t_s - f.t_offset_s;
      EXPECT_NEAR(r.samples[k].t_s, t, 2e-6) << k;
    }
    fs::remove(log);
  }
  // A rate for a log that has times is refused too.
  CanDecodeOptions o;
  o.assume_rate_hz = 500.0;
  EXPECT_THROW(decode_netcanoem_log(reference_log, o), std::runtime_error);
  fs::remove(reference_log);
}

TEST(DecodeCan, ALineInAnotherFormIsNamedWithFileLineAndColumn) {
  const fs::path log = write_temp(
      "mixed.log", "  can0  201   [2]  01 02\n\n (1700000000.000000)  can0  201   [2]  01 02\n");
  try {
    decode_netcanoem_log(log, {});
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 3);
    EXPECT_EQ(e.column(), 1);
    EXPECT_THAT(e.what(), ::testing::HasSubstr(log.string()));
    EXPECT_THAT(e.what(), ::testing::HasSubstr("one form"));
  }
  fs::remove(log);
}

TEST(DecodeCan, AMalformedLineIsNamedWithLineAndColumn) {
  const fs::path log =
      write_temp("bad.log", "(1700000000.000000) can0 201#0102\n(1700000000.1) can0 2G1#00\n");
  try {
    decode_netcanoem_log(log, {});
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 2);
    EXPECT_GT(e.column(), 0);
  }
  fs::remove(log);
}

}  // namespace
}  // namespace zerog::io
