// candump -L log parser: the frame forms, the filter, and every error with its column.
#include "zerog/proto/candump.hpp"

#include <gtest/gtest.h>

#include <sstream>

#include "zerog/proto/netcanoem.hpp"

namespace zerog::proto {
namespace {

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
  expect_error(" (1.0) can0 123#00", 1, "leading whitespace");
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
  expect_error("(1.0) can0 123", 15, "'#'");
  expect_error("(1.0) can0 123##1DEAD", 16, "CAN FD");
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

// Found by tests/fuzz (candump_fuzz): 12 digits of seconds overflowed the timestamp in ns
// (signed overflow, undefined behaviour). The largest that fits: 9223372035 s (year 2262).
TEST(Candump, TimestampBeyondInt64NanosecondsIsAnError) {
  expect_error("(170000000000.125000) can0 202#00", 2, "too large");
  expect_error("(9223372036.000000) can0 123#00", 2, "too large");
  EXPECT_EQ(parse_ok("(9223372035.999999999) can0 123#00").timestamp_ns, 9'223'372'035'999'999'999);
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
}  // namespace zerog::proto
