// candump text parser: the -L log form and the default columns (with every timestamp form), the
// filter, the clock of a whole log, and every error with its column.
#include "zerog/io/candump.hpp"

#include <gtest/gtest.h>

#include <sstream>

#include "zerog/proto/netcanoem.hpp"

namespace zerog::io {
namespace {

using proto::CanFilter;
using proto::CanFrame;
namespace netcanoem = proto::netcanoem;

CandumpRecord parse_ok(std::string_view line) {
  CandumpRecord r;
  CandumpError e;
  EXPECT_EQ(parse_candump_line(line, 1, r, e), CandumpLineKind::record) << e.message();
  return r;
}

void expect_error(std::string_view line, int column, std::string_view reason_part) {
  CandumpRecord r;
  CandumpError e;
  ASSERT_EQ(parse_candump_line(line, 7, r, e), CandumpLineKind::error) << line;
  EXPECT_EQ(e.line, 7);
  EXPECT_EQ(e.column, column) << line << ": " << e.reason;
  EXPECT_NE(e.reason.find(reason_part), std::string::npos) << e.reason;
}

TEST(Candump, StandardFrame) {
  const CandumpRecord r = parse_ok("(1700000000.123456) can0 123#DEADBEEF");
  EXPECT_EQ(r.timestamp_ns, 1700000000123456000);
  EXPECT_EQ(r.interface, "can0");
  EXPECT_EQ(r.frame.id, 0x123u);
  EXPECT_FALSE(r.frame.extended());
  EXPECT_EQ(r.frame.len, 4);
  EXPECT_EQ(r.frame.data[0], 0xDE);
  EXPECT_EQ(r.frame.data[3], 0xEF);
  EXPECT_EQ(r.direction, '\0');
}

TEST(Candump, EmptyDataLowerCaseDotsAndLineEnd) {
  EXPECT_EQ(parse_ok("(1.5) vcan0 7ff#").frame.len, 0);
  EXPECT_EQ(parse_ok("(1.5) vcan0 7ff#").timestamp_ns, 1'500'000'000);
  const CandumpRecord r = parse_ok("(0.000001) can1 0a1#de.ad.be.ef.01.02.03.04\r\n");
  EXPECT_EQ(r.frame.id, 0x0A1u);
  EXPECT_EQ(r.frame.len, 8);
  EXPECT_EQ(r.frame.data[7], 0x04);
  EXPECT_EQ(r.timestamp_ns, 1000);
}

TEST(Candump, RemoteFrames) {
  CandumpRecord r = parse_ok("(1.000000) can0 123#R");
  EXPECT_TRUE(r.frame.remote());
  EXPECT_EQ(r.frame.len, 0);
  EXPECT_EQ(r.frame.raw_id(), 0x123u);
  r = parse_ok("(1.000000) can0 12345678#R8");
  EXPECT_TRUE(r.frame.remote());
  EXPECT_TRUE(r.frame.extended());
  EXPECT_EQ(r.frame.len, 8);
}

TEST(Candump, ExtendedAndErrorFrames) {
  CandumpRecord r = parse_ok("(1.000000) can0 12345678#0102");
  EXPECT_TRUE(r.frame.extended());
  EXPECT_EQ(r.frame.raw_id(), 0x12345678u);
  EXPECT_EQ(r.frame.len, 2);
  r = parse_ok("(1.000000) can0 00000200#0102");  // extended id 0x200, not the ATI board
  EXPECT_TRUE(r.frame.extended());
  EXPECT_FALSE(netcanoem::filter_for(0x20).matches(r.frame));
  r = parse_ok("(1.000000) can0 20000004#0004000000000000");
  EXPECT_TRUE(r.frame.error());
  EXPECT_FALSE(r.frame.extended());
}

TEST(Candump, LeadingBlanksAndCanFdInTheLogForm) {
  EXPECT_EQ(parse_ok(" (1.0) can0 123#00").frame.len, 1);
  const CandumpRecord r = parse_ok("(1.0) can0 123##1DE.AD");
  EXPECT_TRUE(r.fd);
  EXPECT_EQ(r.fd_length, 2);
  EXPECT_EQ(r.frame.len, 0);  // the payload is checked, not kept
  EXPECT_EQ(r.frame.raw_id(), 0x123u);
}

TEST(Candump, DirectionFlag) {
  EXPECT_EQ(parse_ok("(1.000000) can0 200# T").direction, 'T');
  EXPECT_EQ(parse_ok("(1.000000) can0 200#00 R").direction, 'R');
}

TEST(Candump, FormatRoundTrip) {
  for (const char* line : {"(1700000000.123456) can0 123#DEADBEEF", "(1.000000) can0 12345678#R8",
                           "(2.000000) vcan3 7FF#", "(3.000001) can0 20000004#0004000000000000",
                           "(4.123456789) can0 00000001#01 T", "(5.000000) can0 200#R"}) {
    EXPECT_EQ(format_candump_line(parse_ok(line)), line);
  }
}

TEST(Candump, Errors) {
  expect_error("1.0 can0 123#00", 1, "'('");
  expect_error("(x.0) can0 123#00", 2, "seconds");
  expect_error("(1) can0 123#00", 3, "'.'");
  expect_error("(1.) can0 123#00", 4, "fraction");
  expect_error("(1.0123456789) can0 123#00", 13, "more than 9");
  expect_error("(1.0 can0 123#00", 5, "')'");
  expect_error("(1.0)can0 123#00", 6, "space after the timestamp");
  expect_error("(1.0) can0", 11, "frame");
  expect_error("(1.0) averyveryverylongname 123#00", 7, "longer than 15");
  expect_error("(1.0) can0 12#00", 12, "3 (standard) or 8 (extended)");
  expect_error("(1.0) can0 1234#00", 12, "3 (standard) or 8 (extended)");
  expect_error("(1.0) can0 123456789#00", 12, "3 (standard) or 8 (extended)");
  expect_error("(1.0) can0 12G#00", 14, "hex digit");
  expect_error("(1.0) can0 800#00", 12, "above 0x7FF");
  expect_error("(1.0) can0 7FFFFFFF#00", 12, "error frame id");
  expect_error("(1.0) can0 4FFFFFFF#00", 12, "above 0x1FFFFFFF");
  expect_error("(1.0) can0 123", 15, "length");
  expect_error("(1.0) can0 123##", 17, "flags");
  expect_error("(1.0) can0 123##1DEADBEEF0011223344", 12, "CAN FD data length 9");
  expect_error("(1.0) can0 123#ABC", 19, "odd number");
  expect_error("(1.0) can0 123#AX", 17, "odd number");
  expect_error("(1.0) can0 123#.AB", 16, "'.' before");
  expect_error("(1.0) can0 123#AB.", 19, "hex digit");
  expect_error("(1.0) can0 123#000102030405060708", 32, "more than 8");
  expect_error("(1.0) can0 123#R9", 17, "above 8");
  expect_error("(1.0) can0 123#0011223344556677_E", 32, "len8_dlc");
  expect_error("(1.0) can0 123#00 X", 19, "direction");
  expect_error("(1.0) can0 123#00 T junk", 21, "unexpected characters");
  expect_error("(1.0) can0 123#R5x", 18, "unexpected characters");
}

// candump's default screen output, each form as can-utils' candump.c/lib.c print it.
TEST(Candump, DefaultOutputWithoutTimestamps) {
  CandumpRecord r = parse_ok("  can1  7F6   [1]  00");
  EXPECT_EQ(r.form, CandumpForm::columns);
  EXPECT_EQ(r.stamp, CandumpStamp::none);
  EXPECT_EQ(r.timestamp_ns, 0);
  EXPECT_EQ(r.interface, "can1");
  EXPECT_EQ(r.frame.id, 0x7F6u);
  EXPECT_EQ(r.frame.len, 1);
  EXPECT_EQ(r.frame.data[0], 0x00);
  r = parse_ok("  can0  201   [8]  00 00 00 64 00 00 FF 38");
  EXPECT_EQ(r.frame.len, 8);
  EXPECT_EQ(r.frame.data[3], 0x64);
  EXPECT_EQ(r.frame.data[7], 0x38);
  r = parse_ok(" vcan0  12345678   [2]  01 02");  // extended; names right-aligned
  EXPECT_TRUE(r.frame.extended());
  EXPECT_EQ(r.frame.raw_id(), 0x12345678u);
  EXPECT_EQ(r.interface, "vcan0");
  r = parse_ok("  can0       201   [2]  01 02");  // standard id indented once an EFF id was seen
  EXPECT_EQ(r.frame.id, 0x201u);
  r = parse_ok("  can0  123   [0]  remote request");
  EXPECT_TRUE(r.frame.remote());
  EXPECT_EQ(r.frame.len, 0);
  r = parse_ok("  can0  20000004   [8]  00 04 00 00 00 00 00 00   ERRORFRAME");
  EXPECT_TRUE(r.frame.error());
  EXPECT_EQ(r.frame.data[1], 0x04);
  r = parse_ok("  can0  123   [4]  41 42 43 44         'ABCD'");  // -a
  EXPECT_EQ(r.frame.data[3], 0x44);
  r = parse_ok("  can0  RX - -  201   [1]  7F");  // -x
  EXPECT_EQ(r.direction, 'R');
  EXPECT_EQ(r.frame.data[0], 0x7F);
  EXPECT_EQ(parse_ok("  can0  TX B E  201   [0] ").direction, 'T');
  r = parse_ok("  can0  123  [12]  00 11 22 33 44 55 66 77 88 99 AA BB");  // CAN FD
  EXPECT_TRUE(r.fd);
  EXPECT_EQ(r.fd_length, 12);
  r = parse_ok(
      "  can0  123  [64]  00 01 02 03 04 05 06 07 08 09 0A 0B 0C 0D 0E 0F 10 11 12 13 14 15 16 "
      "17 18 19 1A 1B 1C 1D 1E 1F 20 21 22 23 24 25 26 27 28 29 2A 2B 2C 2D 2E 2F 30 31 32 33 34 "
      "35 36 37 38 39 3A 3B 3C 3D 3E 3F");
  EXPECT_EQ(r.fd_length, 64);
  EXPECT_EQ(parse_ok("  can0  123  [08]  00 11 22 33 44 55 66 77").fd_length, 8);
}

TEST(Candump, DefaultOutputWithTimestamps) {
  CandumpRecord r = parse_ok(" (1700000000.123456)  can0  201   [2]  AB CD");  // -ta
  EXPECT_EQ(r.stamp, CandumpStamp::seconds);
  EXPECT_EQ(r.timestamp_ns, 1700000000123456000);
  EXPECT_EQ(r.frame.data[1], 0xCD);
  r = parse_ok(" (000.000500)  can0  201   [2]  AB CD");  // -tz, -td
  EXPECT_EQ(r.timestamp_ns, 500'000);
  r = parse_ok(" (2023-11-14 22:13:20.123456)  can0  201   [2]  AB CD");  // -tA
  EXPECT_EQ(r.stamp, CandumpStamp::date);
  EXPECT_EQ(r.timestamp_ns, 1700000000123456000);  // read as UTC
  r = parse_ok(" (2021-05-10 15:02:46.143287)  can0  RX - -  3DE  [08]  EE EE EE EE EE EE EE EE");
  EXPECT_TRUE(r.fd);
  EXPECT_EQ(r.direction, 'R');
}

TEST(Candump, DefaultOutputErrors) {
  expect_error("  can0  7F6   [9]  00", 16, "above 8");
  expect_error("  can0  7F6   [1]", 18, "line ends before all 1");
  expect_error("  can0  7F6   [2]  00", 22, "line ends before all 2");
  expect_error("  can0  7F6   [1]  0", 20, "two hex digits");
  expect_error("  can0  7F6   [1]  00000000", 20, "binary");
  expect_error("  can0  7F6   [2]  00`11", 22, "candump -S");
  expect_error("  can0  7F6   {9}  00", 15, "candump -8");
  expect_error("  can0  7F6  [13]  00", 15, "CAN FD data length 13");
  expect_error("  can0  7F6   1]  00", 15, "'['");
  expect_error("  can0  7F6   [1)  00", 17, "']'");
  expect_error("  can0  7F6   [1]  00 11", 23, "unexpected characters after the data");
  expect_error("  can0  7F6   [1]  00   ERRORFRAME", 25, "unexpected characters");
  expect_error("  can0  7F60   [1]  00", 9, "3 (standard) or 8 (extended)");
  expect_error("  can0  12G   [1]  00", 11, "hex digit");
  expect_error("  can0  RX X -  7F6   [1]  00", 12, "'-' or 'B'");
  expect_error("  can0  123   [0]  remote requst", 27, "remote request");
  expect_error(" (2023-13-14 22:13:20.1)  can0  201   [0]", 3, "out of range");
  expect_error(" (2023-11-14T22:13:20.1)  can0  201   [0]", 13, "' ' between date and time");
  expect_error("(2023-11-14 22:13:20.1) can0 201#00", 1, "date timestamp");
}

TEST(Candump, AWholeLogIsOneFormAndItsClockIsDetected) {
  std::vector<CandumpRecord> records;
  CandumpError e;
  CandumpLogInfo info;
  // -tz: starts at 0 and never goes down.
  ASSERT_TRUE(
      parse_candump(" (000.000000)  can0  201   [0] \n (000.000700)  can0  201   [0] \n"
                    " (001.250000)  can0  201   [0] \n",
                    CanFilter{}, records, e, &info))
      << e.message();
  EXPECT_EQ(info.clock, CandumpClock::zero);
  EXPECT_EQ(info.form, CandumpForm::columns);
  EXPECT_EQ(records[2].timestamp_ns, 1'250'000'000);
  // -td: the same first lines, then a smaller step; times are summed.
  records.clear();
  ASSERT_TRUE(
      parse_candump(" (000.000000)  can0  201   [0] \n (000.000700)  can0  201   [0] \n"
                    " (000.000300)  can0  201   [0] \n",
                    CanFilter{}, records, e, &info))
      << e.message();
  EXPECT_EQ(info.clock, CandumpClock::delta);
  EXPECT_NE(info.clock_reason.find("line 3 goes below line 2"), std::string::npos);
  EXPECT_EQ(records[1].timestamp_ns, 700'000);
  EXPECT_EQ(records[2].timestamp_ns, 1'000'000);
  // A steady -td stream repeats its delta: that is -td too.
  records.clear();
  ASSERT_TRUE(
      parse_candump(" (000.000000)  can0  201   [0] \n (000.000500)  can0  201   [0] \n"
                    " (000.000500)  can0  201   [0] \n",
                    CanFilter{}, records, e, &info));
  EXPECT_EQ(info.clock, CandumpClock::delta);
  EXPECT_NE(info.clock_reason.find("line 3 repeats line 2"), std::string::npos);
  EXPECT_EQ(records[2].timestamp_ns, 1'000'000);
  // Given as delta, a growing log is summed too.
  records.clear();
  ASSERT_TRUE(parse_candump(" (000.000000)  can0  201   [0] \n (000.000700)  can0  201   [0] \n",
                            CanFilter{}, records, e, &info, CandumpClock::delta));
  EXPECT_EQ(info.clock, CandumpClock::delta);
  // -ta: not starting at 0.
  records.clear();
  ASSERT_TRUE(
      parse_candump(" (1700000000.000000)  can0  201   [0] \n", CanFilter{}, records, e, &info));
  EXPECT_EQ(info.clock, CandumpClock::absolute);
  // No timestamps.
  records.clear();
  ASSERT_TRUE(
      parse_candump("  can0  201   [0] \n\n  can0  201   [0] \n", CanFilter{}, records, e, &info));
  EXPECT_EQ(info.clock, CandumpClock::none);
  EXPECT_EQ(info.frames, 2u);
  // Mixed forms are refused at the first line in another form.
  records.clear();
  EXPECT_FALSE(
      parse_candump("  can0  201   [0] \n(1.000000) can0 201#\n", CanFilter{}, records, e));
  EXPECT_EQ(e.line, 2);
  EXPECT_EQ(e.column, 1);
  EXPECT_NE(e.reason.find("one form"), std::string::npos) << e.reason;
  // A clock that does not fit the log is refused.
  EXPECT_FALSE(parse_candump("  can0  201   [0] \n", CanFilter{}, records, e, nullptr,
                             CandumpClock::absolute));
  EXPECT_NE(e.reason.find("no timestamps"), std::string::npos);
  EXPECT_FALSE(parse_candump("(1.000000) can0 201#\n", CanFilter{}, records, e, nullptr,
                             CandumpClock::delta));
}

TEST(Candump, ColumnsFormatterWritesWhatTheParserReads) {
  CandumpRecord r;
  r.timestamp_ns = 1700000000123456000;
  r.interface = "can0";
  r.frame.id = 0x201;
  r.frame.len = 2;
  r.frame.data = {0xAB, 0xCD};
  EXPECT_EQ(format_candump_columns(r, CandumpClock::none), "  can0  201   [2]  AB CD");
  EXPECT_EQ(format_candump_columns(r, CandumpClock::absolute),
            " (1700000000.123456)  can0  201   [2]  AB CD");
  EXPECT_EQ(format_candump_columns(r, CandumpClock::date),
            " (2023-11-14 22:13:20.123456)  can0  201   [2]  AB CD");
  r.timestamp_ns = 1'500'000;
  EXPECT_EQ(format_candump_columns(r, CandumpClock::zero), " (000.001500)  can0  201   [2]  AB CD");
  r.frame.id = 0x20000004;
  r.frame.len = 8;
  EXPECT_EQ(format_candump_columns(r, CandumpClock::none),
            "  can0  20000004   [8]  AB CD 00 00 00 00 00 00   ERRORFRAME");
  EXPECT_TRUE(parse_ok(format_candump_columns(r, CandumpClock::none)).frame.error());
}

// Found by tests/fuzz (candump_fuzz): 12 digits of seconds overflowed the timestamp in ns
// (signed overflow, undefined behaviour). The largest that fits: 9223372035 s (year 2262).
TEST(Candump, TimestampBeyondInt64NanosecondsIsAnError) {
  expect_error("(170000000000.125000) can0 202#00", 2, "too large");
  expect_error("(9223372036.000000) can0 123#00", 2, "too large");
  EXPECT_EQ(parse_ok("(9223372035.999999999) can0 123#00").timestamp_ns, 9'223'372'035'999'999'999);
}

// Found by tests/fuzz (candump_fuzz): a -tA date after 2262 overflowed the same way.
TEST(Candump, DateBeyondInt64NanosecondsIsAnError) {
  expect_error(" (4046-11-14 22:13:20.123456)  can0  201   [4]  41 42 43 44", 3, "2262");
  EXPECT_GT(parse_ok(" (2262-01-01 00:00:00.000000)  can0  201   [1]  41").timestamp_ns, 0);
}

TEST(Candump, ErrorMessageNamesLineAndColumn) {
  CandumpError e{3, 14, "why"};
  EXPECT_EQ(e.message(), "line 3, column 14: why");
}

TEST(Candump, WholeLogWithFilterAndBlankLines) {
  const std::string log =
      "(1700000000.000100) can0 200#0000000100020003\n"
      "(1700000000.000150) can0 123#DEADBEEF\n"
      "\n"
      "(1700000000.000200) can0 201#000400050006\n"
      "(1700000000.000300) can0 12345201#00\n"  // extended id, other traffic
      "(1700000000.000400) can0 210#00\n";      // another board
  std::vector<CandumpRecord> records;
  CandumpError e;
  ASSERT_TRUE(parse_candump(log, netcanoem::filter_for(0x20), records, e)) << e.message();
  ASSERT_EQ(records.size(), 2u);
  netcanoem::SampleAssembler a(0x20);
  netcanoem::GaugeSample s;
  EXPECT_EQ(a.feed(records[0].frame, s), netcanoem::FeedResult::pending);
  ASSERT_EQ(a.feed(records[1].frame, s), netcanoem::FeedResult::sample);
  EXPECT_EQ(s.gauges, (std::array<std::int16_t, 6>{1, 4, 2, 5, 3, 6}));

  std::istringstream in(log);
  records.clear();
  ASSERT_TRUE(parse_candump(in, CanFilter{}, records, e));
  EXPECT_EQ(records.size(), 5u);
}

TEST(Candump, WholeLogStopsAtTheFirstError) {
  const std::string log =
      "(1.000000) can0 200#00\n"
      "(2.000000) can0 200#0\n"
      "(3.000000) can0 200#00\n";
  std::vector<CandumpRecord> records;
  CandumpError e;
  EXPECT_FALSE(parse_candump(log, CanFilter{}, records, e));
  EXPECT_EQ(records.size(), 1u);
  EXPECT_EQ(e.line, 2);
  EXPECT_EQ(e.column, 22);
}

}  // namespace
}  // namespace zerog::io
