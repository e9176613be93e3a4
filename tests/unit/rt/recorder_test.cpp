// The recorder's files (a log that formats::read_log reads back, cycles.csv with every record
// field,
// `.partial` until finish(), black-box dumps) and the latency histogram's quantiles.
#include "zerog/rt/recorder.hpp"

#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "rt_fixtures.hpp"
#include "zerog/formats/cycles_csv.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/rt/latency.hpp"

namespace zerog::rt {
namespace {

namespace fs = std::filesystem;

std::vector<std::string> split(const std::string& text, char sep) {
  std::vector<std::string> out;
  std::string cell;
  for (char c : text) {
    if (c == sep) {
      out.push_back(cell);
      cell.clear();
    } else {
      cell += c;
    }
  }
  out.push_back(cell);
  return out;
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines = split(text, '\n');
  if (!lines.empty() && lines.back().empty()) lines.pop_back();
  return lines;
}

loop::CycleRecord record(std::uint64_t cycle, double t_s) {
  loop::CycleRecord r;
  r.cycle = cycle;
  r.ipoc = 1000 + 12 * cycle;
  r.t_s = t_s;
  r.state = loop::State::zero_g;
  r.joints_rad = {0.1, -1.2, 1.5, 0.2, 0.7, -0.3};
  r.p_base_sensor_m = {1.5, 0.2, 1.2};
  r.q_base_sensor = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()));
  r.wrench_measured = {10.0 + static_cast<double>(cycle), -5.0, 981.0, 1.0, 2.0, 0.5};
  r.specific_force_imu = {0.1, 0.2, 9.8};
  r.rate_imu = {0.01, -0.02, 0.03};
  r.ft_samples = 4;
  r.imu_samples = 24;
  r.contact = {1.25, 0, 0, 0, 0, 0};
  r.compute_ns = 1234;
  return r;
}

TEST(LatencyHistogram, QuantilesAreWithinTheBucketResolution) {
  LatencyHistogram h;
  EXPECT_EQ(h.quantile(0.5), 0u);
  std::mt19937_64 rng(7);
  std::lognormal_distribution<double> d(std::log(20000.0), 0.6);
  std::vector<std::int64_t> values;
  for (int i = 0; i < 100000; ++i) values.push_back(static_cast<std::int64_t>(d(rng)));
  for (std::int64_t v : values) h.add(v);
  std::sort(values.begin(), values.end());
  for (double q : {0.5, 0.9, 0.99, 0.999}) {
    const auto exact = static_cast<double>(
        values[static_cast<std::size_t>(q * static_cast<double>(values.size() - 1))]);
    EXPECT_LE(static_cast<double>(h.quantile(q)), exact) << q;
    EXPECT_GE(static_cast<double>(h.quantile(q)), exact * (1.0 - 1.0 / 64.0)) << q;
  }
  EXPECT_EQ(h.max(), static_cast<std::uint64_t>(values.back()));
  EXPECT_EQ(h.count(), values.size());
  for (std::uint64_t v : {0ull, 127ull, 128ull, 1000ull, 123456789ull, 1ull << 40}) {
    EXPECT_LE(LatencyHistogram::lower_edge(LatencyHistogram::bucket(v)), v);
    EXPECT_GT(LatencyHistogram::lower_edge(LatencyHistogram::bucket(v)) + v / 64 + 1, v);
  }
}

TEST(RecordCsv, EveryRowHasTheHeadersColumns) {
  std::string text;
  formats::append_record_header(text);
  formats::append_record_row(record(7, 0.084), text);
  const std::vector<std::string> lines = lines_of(text);
  ASSERT_EQ(lines.size(), 2u);
  const auto header = split(lines[0], ',');
  const auto row = split(lines[1], ',');
  EXPECT_EQ(static_cast<int>(header.size()), formats::record_column_count());
  ASSERT_EQ(row.size(), header.size());
  auto cell = [&](const std::string& name) {
    const auto it = std::find(header.begin(), header.end(), name);
    return it == header.end() ? std::string("?")
                              : row[static_cast<std::size_t>(it - header.begin())];
  };
  EXPECT_EQ(cell("cycle"), "7");
  EXPECT_EQ(cell("t_s"), "0.084");
  EXPECT_EQ(cell("state"), "zero_g");
  EXPECT_EQ(cell("fault"), "none");
  EXPECT_EQ(cell("Fx_N"), "17");
  EXPECT_EQ(cell("contact_Fx_N"), "1.25");
  EXPECT_EQ(cell("compute_ns"), "1234");
}

// The reader beside the writer (zerog/formats/cycles_csv.hpp): what the recorder writes reads
// back field for field (numbers are written as the shortest text that reads back exactly).
TEST(RecordCsv, ReadsBackWhatItWrites) {
  test::TempDir dir;
  std::string text;
  formats::append_record_header(text);
  const loop::CycleRecord a = record(7, 0.084), b = record(8, 0.096);
  formats::append_record_row(a, text);
  formats::append_record_row(b, text);
  const fs::path file = dir.path() / "cycles.csv";
  formats::write_file_atomic(file, text);
  const std::vector<loop::CycleRecord> back = formats::read_cycles_csv(file);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[1].cycle, 8u);
  EXPECT_EQ(back[1].ipoc, b.ipoc);
  EXPECT_EQ(back[1].t_s, b.t_s);
  EXPECT_EQ(back[1].state, loop::State::zero_g);
  EXPECT_EQ(back[1].joints_rad, b.joints_rad);
  EXPECT_EQ(back[1].wrench_measured, b.wrench_measured);
  EXPECT_EQ(back[1].contact, b.contact);
  EXPECT_EQ(back[1].q_base_sensor.coeffs(), b.q_base_sensor.coeffs());
  EXPECT_EQ(back[1].compute_ns, 1234);
  std::string again;
  formats::append_record_header(again);
  for (const loop::CycleRecord& r : back) formats::append_record_row(r, again);
  EXPECT_EQ(again, text);
  EXPECT_THROW(formats::read_cycles_csv(dir.path() / "missing.csv"), std::runtime_error);
}

// The temperature the model was fed (temp_C, °C) and whether it was the F/T sensor's reading
// (temp_measured) read back; an unknown temperature (NaN: a record read from an older file) is
// an empty cell and reads back as NaN.
TEST(RecordCsv, TemperatureColumnsReadBack) {
  test::TempDir dir;
  loop::CycleRecord measured = record(7, 0.084), configured = record(8, 0.096),
                    unknown = record(9, 0.108);
  measured.temperature_C = 31.25;
  measured.temperature_measured = true;
  measured.temperature_age_s = 0.375;
  configured.temperature_C = 25.0;  // the configured one (e.g. the reading went stale)
  configured.flags = loop::kTemperatureStale;
  unknown.temperature_C = std::numeric_limits<double>::quiet_NaN();
  std::string text;
  formats::append_record_header(text);
  for (const loop::CycleRecord& r : {measured, configured, unknown})
    formats::append_record_row(r, text);
  const std::vector<std::string> lines = lines_of(text);
  ASSERT_EQ(lines.size(), 4u);
  const auto cell = [&](std::size_t row, const std::string& name) {
    const std::vector<std::string> header = split(lines[0], ',');
    const std::vector<std::string> cells = split(lines[row], ',');
    const auto at = std::find(header.begin(), header.end(), name);
    EXPECT_NE(at, header.end()) << name;
    return at == header.end() ? std::string("?") : cells.at(at - header.begin());
  };
  EXPECT_EQ(cell(1, "temp_C"), "31.25");
  EXPECT_EQ(cell(1, "temp_measured"), "1");
  EXPECT_EQ(cell(2, "temp_C"), "25");
  EXPECT_EQ(cell(2, "temp_measured"), "0");
  EXPECT_EQ(cell(3, "temp_C"), "");
  const fs::path file = dir.path() / "cycles.csv";
  formats::write_file_atomic(file, text);
  const std::vector<loop::CycleRecord> back = formats::read_cycles_csv(file);
  ASSERT_EQ(back.size(), 3u);
  EXPECT_EQ(back[0].temperature_C, 31.25);
  EXPECT_TRUE(back[0].temperature_measured);
  EXPECT_EQ(back[1].temperature_C, 25.0);
  EXPECT_FALSE(back[1].temperature_measured);
  EXPECT_EQ(back[1].flags, static_cast<std::uint32_t>(loop::kTemperatureStale));
  EXPECT_TRUE(std::isnan(back[2].temperature_C));
  EXPECT_FALSE(back[2].temperature_measured);
}

// cycles.csv files written before the temperature columns (real recordings exist) still read:
// the temperature is unknown (NaN), not measured; everything else as before.
TEST(RecordCsv, ReadsOlderFilesWithoutTheTemperatureColumns) {
  test::TempDir dir;
  std::string text;
  formats::append_record_header(text);
  formats::append_record_row(record(7, 0.084), text);
  // Drop the two columns from header and row, as an older writer wrote them.
  std::vector<std::vector<std::string>> rows;
  for (const std::string& line : lines_of(text)) rows.push_back(split(line, ','));
  const auto at = std::find(rows[0].begin(), rows[0].end(), "temp_C") - rows[0].begin();
  ASSERT_LT(static_cast<std::size_t>(at), rows[0].size());
  std::string old;
  for (std::vector<std::string>& r : rows) {
    r.erase(r.begin() + at, r.begin() + at + 2);
    for (std::size_t i = 0; i < r.size(); ++i) old += (i ? "," : "") + r[i];
    old += '\n';
  }
  ASSERT_EQ(old.find("temp_"), std::string::npos);
  const fs::path file = dir.path() / "old_cycles.csv";
  formats::write_file_atomic(file, old);
  const std::vector<loop::CycleRecord> back = formats::read_cycles_csv(file);
  ASSERT_EQ(back.size(), 1u);
  EXPECT_EQ(back[0].cycle, 7u);
  EXPECT_EQ(back[0].contact, record(7, 0.084).contact);
  EXPECT_EQ(back[0].compute_ns, 1234);
  EXPECT_TRUE(std::isnan(back[0].temperature_C));
  EXPECT_FALSE(back[0].temperature_measured);
}

TEST(Recorder, WritesALogThatReadsBackAndCyclesCsvAndRenamesOnlyAtTheEnd) {
  test::TempDir dir;
  RecorderOptions o;
  o.dir = dir.path() / "run1";
  o.rig = test::test_rig();
  {
    Recorder rec(o);
    loop::CycleRecord first = record(1, 0.0);
    first.ft_samples = 0;  // no F/T sample yet: no log row
    rec.add(first);
    for (std::uint64_t c = 2; c <= 50; ++c) rec.add(record(c, 0.012 * static_cast<double>(c - 1)));
    loop::CycleRecord stale = record(51, 0.012);  // a duplicate IPOC: no log row
    stale.flags = loop::kIpocStale;
    rec.add(stale);
    EXPECT_TRUE(fs::exists(dir.path() / "run1" / "run.csv.partial"));
    EXPECT_FALSE(fs::exists(dir.path() / "run1" / "run.csv"));
    EXPECT_FALSE(fs::exists(dir.path() / "run1" / "cycles.csv"));
    rec.finish();
    EXPECT_EQ(rec.counters().records, 51u);
    EXPECT_EQ(rec.counters().log_rows, 49u);
    EXPECT_EQ(rec.counters().skipped_no_samples, 1u);
    EXPECT_EQ(rec.counters().skipped_stale, 1u);
  }
  EXPECT_FALSE(fs::exists(dir.path() / "run1" / "run.csv.partial"));
  const formats::Log log = formats::read_log(dir.path() / "run1" / "run.csv");
  ASSERT_EQ(log.samples.size(), 49u);
  EXPECT_TRUE(log.columns.joints);
  EXPECT_TRUE(log.columns.full_imu());
  EXPECT_EQ(log.rig.name, test::test_rig().name);
  EXPECT_DOUBLE_EQ(log.samples[0].t_s, 0.012);
  EXPECT_NEAR(log.samples[0].force_sensor_N.x(), 12.0, 1e-9);
  EXPECT_NEAR(log.samples[10].joints_rad[1], -1.2, 1e-9);
  EXPECT_NEAR(log.samples[10].q_base_sensor.angularDistance(
                  Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()))),
              0.0, 1e-8);
  const std::vector<std::string> cycles =
      lines_of(test::read_text(dir.path() / "run1" / "cycles.csv"));
  EXPECT_EQ(cycles.size(), 52u);  // header + every record

  // Never over a recording.
  EXPECT_THROW(Recorder{o}, std::runtime_error);
}

// With the F/T sensor's temperature ([ft] thermistor conversion): the log gets temp_C in °C;
// rows before the first reading are skipped (the configured temperature is not a reading).
TEST(Recorder, WritesTheSensorsTemperatureAsTempC) {
  test::TempDir dir;
  RecorderOptions o;
  o.dir = dir.path() / "warm";
  o.rig = test::test_rig();
  o.temperature = true;
  {
    Recorder rec(o);
    for (std::uint64_t c = 1; c <= 20; ++c) {
      loop::CycleRecord r = record(c, 0.012 * static_cast<double>(c - 1));
      r.temperature_measured = c > 5;
      r.temperature_C = c > 5 ? 31.5 + 0.01 * static_cast<double>(c) : 25.0;
      rec.add(r);
    }
    rec.finish();
    EXPECT_EQ(rec.counters().skipped_no_temperature, 5u);
    EXPECT_EQ(rec.counters().log_rows, 15u);
  }
  const formats::Log log = formats::read_log(dir.path() / "warm" / "run.csv");
  EXPECT_TRUE(log.columns.temperature);
  ASSERT_EQ(log.samples.size(), 15u);
  EXPECT_NEAR(log.samples[0].temperature_C, 31.56, 1e-9);
  EXPECT_NEAR(log.samples[14].temperature_C, 31.70, 1e-9);
}

TEST(Recorder, DumpsTheFrozenBlackBoxOldestFirstWithTheFaultCycleLast) {
  test::TempDir dir;
  RecorderOptions o;
  o.blackbox_dir = dir.path();
  Recorder rec(o);  // not recording: the dump goes to blackbox_dir
  loop::Cycle::Box box;
  for (std::uint64_t c = 1; c <= 300; ++c) {
    loop::CycleRecord r = record(c, 0.012 * static_cast<double>(c));
    if (c == 300) {
      r.state = loop::State::fault;
      r.fault = loop::Fault::ft_stale;
    }
    box.push(r);
  }
  box.freeze();
  const fs::path path = rec.dump_black_box(box);
  EXPECT_EQ(path, dir.path() / "blackbox-300.csv");
  const std::vector<std::string> lines = lines_of(test::read_text(path));
  ASSERT_EQ(lines.size(), 2u + loop::Cycle::kBlackBoxCycles);  // comment, header, records
  EXPECT_NE(lines[0].find("fault ft_stale at cycle 300"), std::string::npos) << lines[0];
  EXPECT_EQ(split(lines[2], ',')[0], std::to_string(300 - loop::Cycle::kBlackBoxCycles + 1));
  EXPECT_EQ(split(lines.back(), ',')[0], "300");
  EXPECT_EQ(split(lines.back(), ',')[5], "ft_stale");
  EXPECT_EQ(rec.counters().black_boxes, 1u);
}

// Restrictive whatever the umask: with umask 0 (what a careless start-up script leaves) the
// recording, its rig, the black box and the summary are still 0640, the folder 0750.
TEST(Recorder, FilesAre0640AndTheFolder0750WhateverTheUmask) {
  const mode_t old_umask = ::umask(0);
  test::TempDir dir;
  RecorderOptions o;
  o.dir = dir.path() / "run1";
  o.rig = test::test_rig();
  fs::path box_path;
  {
    Recorder rec(o);
    for (std::uint64_t c = 1; c <= 20; ++c) rec.add(record(c, 0.012 * static_cast<double>(c)));
    EXPECT_EQ(fs::status(dir.path() / "run1" / "run.csv.partial").permissions(),
              static_cast<fs::perms>(kRecordFileMode));
    loop::Cycle::Box box;
    box.push(record(21, 0.252));
    box.freeze();
    box_path = rec.dump_black_box(box);
    rec.finish();
  }
  formats::write_file_atomic(dir.path() / "summary.json", "{}\n", {}, kRecordFileMode);
  ::umask(old_umask);
  for (const fs::path& p : {dir.path() / "run1" / "run.csv", dir.path() / "run1" / "cycles.csv",
                            formats::rig_path_for(dir.path() / "run1" / "run.csv"), box_path,
                            dir.path() / "summary.json"}) {
    EXPECT_EQ(fs::status(p).permissions(), static_cast<fs::perms>(0640)) << p;
  }
  EXPECT_EQ(fs::status(dir.path() / "run1").permissions(), static_cast<fs::perms>(0750));
}

}  // namespace
}  // namespace zerog::rt
