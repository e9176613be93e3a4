// ATI NETCANOEM (proto/netcanoem.md): request encoders, the sample assembler and its error
// paths, status classification, the calibration readout, the wrench conversion against a hand
// computation, and the DBC file against the decoder.
#include "zerog/proto/netcanoem.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace zerog::proto::netcanoem {
namespace {

constexpr std::uint8_t kBase = 0x20;

CanFrame frame(std::uint32_t id, std::initializer_list<std::uint8_t> bytes) {
  CanFrame f;
  f.id = id;
  f.len = static_cast<std::uint8_t>(bytes.size());
  std::copy(bytes.begin(), bytes.end(), f.data.begin());
  return f;
}

TEST(NetcanoemIds, IdIsBaseShiftedPlusOpcode) {
  EXPECT_EQ(can_id(0x20, Opcode::sample_a), 0x200u);
  EXPECT_EQ(can_id(0x20, Opcode::firmware_version), 0x20Fu);
  EXPECT_EQ(can_id(0x7F, Opcode::sample_b), 0x7F1u);
  EXPECT_EQ(base_id_of(0x5A3), 0x5A);
  EXPECT_EQ(opcode_of(0x5A3), 0x3);
  const CanFilter f = filter_for(kBase);
  EXPECT_TRUE(f.matches(frame(0x200, {})));
  EXPECT_TRUE(f.matches(frame(0x20F, {})));
  EXPECT_FALSE(f.matches(frame(0x210, {})));
  EXPECT_FALSE(f.matches(frame(0x200 | kCanExtendedFlag, {})));
  EXPECT_FALSE(f.matches(frame(0x200 | kCanRemoteFlag, {})));
}

TEST(NetcanoemRequests, EncodeIdLengthAndData) {
  EXPECT_EQ(*request_sample(kBase), frame(0x200, {}));
  EXPECT_EQ(*request_matrix_row(kBase, 5), frame(0x202, {5}));
  EXPECT_EQ(*request_serial_number(kBase), frame(0x205, {}));
  EXPECT_EQ(*request_set_active_calibration(kBase, 15), frame(0x206, {15}));
  EXPECT_EQ(*request_counts(kBase), frame(0x207, {}));
  EXPECT_EQ(*request_units(kBase), frame(0x208, {}));
  EXPECT_EQ(*request_firmware_version(kBase), frame(0x20F, {}));
}

TEST(NetcanoemRequests, OutOfRangeArgumentsGiveNoFrame) {
  EXPECT_FALSE(request_sample(0x80));
  EXPECT_FALSE(request_matrix_row(kBase, 6));
  EXPECT_FALSE(request_set_active_calibration(kBase, 16));
  EXPECT_FALSE(request_firmware_version(0xFF));
  EXPECT_FALSE(encode_active_calibration(kBase, 16));
}

TEST(NetcanoemStatus, EachCriticalBitIsCritical) {
  for (int bit : {1, 2, 3, 4, 5, 6, 7, 11, 12}) {
    const auto status = static_cast<std::uint16_t>(1u << bit | kStatusAnyError);
    EXPECT_EQ(classify_status(status), StatusClass::critical) << "bit " << bit;
  }
  for (int bit : {0, 8, 9, 10, 13, 14, 15}) {
    EXPECT_EQ(classify_status(static_cast<std::uint16_t>(1u << bit)), StatusClass::warning)
        << "bit " << bit;
  }
  EXPECT_EQ(classify_status(0), StatusClass::ok);
  EXPECT_EQ(classify_status(kStatusCanBusError | kStatusAnyError), StatusClass::warning);
}

TEST(NetcanoemAssembler, KnownFramesReorderGauges) {
  SampleAssembler a(kBase);
  GaugeSample s;
  // 0x0: status 0x0000, SG0 = 1, SG2 = -2 (0xFFFE), SG4 = 0x1234; 0x1: SG1 = 256, SG3 = -1, SG5 = 7
  EXPECT_EQ(a.feed(frame(0x200, {0x00, 0x00, 0x00, 0x01, 0xFF, 0xFE, 0x12, 0x34}), s),
            FeedResult::pending);
  EXPECT_TRUE(a.pending());
  ASSERT_EQ(a.feed(frame(0x201, {0x01, 0x00, 0xFF, 0xFF, 0x00, 0x07}), s), FeedResult::sample);
  EXPECT_EQ(s.gauges, (std::array<std::int16_t, 6>{1, 256, -2, -1, 0x1234, 7}));
  EXPECT_EQ(s.status, 0);
  EXPECT_EQ(s.status_class, StatusClass::ok);
  EXPECT_EQ(s.saturated_mask, 0);
  EXPECT_TRUE(s.usable());
  EXPECT_EQ(a.counters().samples, 1u);
}

TEST(NetcanoemAssembler, EncoderRoundTrip) {
  const std::array<std::int16_t, 6> gauges{-12345, 0, 32766, -32767, 42, -1};
  const auto frames = encode_sample(kBase, gauges, 0x4000);
  ASSERT_TRUE(frames);
  SampleAssembler a(kBase);
  GaugeSample s;
  EXPECT_EQ(a.feed((*frames)[0], s), FeedResult::pending);
  ASSERT_EQ(a.feed((*frames)[1], s), FeedResult::sample);
  EXPECT_EQ(s.gauges, gauges);
  EXPECT_EQ(s.status, 0x4000);
  EXPECT_EQ(s.status_class, StatusClass::warning);  // CAN bus error: keep going
  EXPECT_TRUE(s.usable());
  EXPECT_EQ(a.counters().warning, 1u);
}

TEST(NetcanoemAssembler, StrayFramesAreCountedAndIgnored) {
  SampleAssembler a(kBase);
  GaugeSample s;
  const std::array<CanFrame, 6> strays{
      frame(0x210, {0, 0, 0, 0, 0, 0, 0, 0}),                     // other board
      frame(0x123, {1, 2}),                                       // other traffic
      frame(0x200 | kCanExtendedFlag, {0, 0, 0, 0, 0, 0, 0, 0}),  // extended id 0x200
      frame(0x200 | kCanRemoteFlag, {}),                          // remote frame
      frame(0x202, {0, 0, 0, 0, 0, 0, 0, 0}),                     // our matrix response
      frame(0x20F, {3, 7, 0, 1}),                                 // our firmware response
  };
  for (const CanFrame& f : strays) EXPECT_EQ(a.feed(f, s), FeedResult::stray);
  EXPECT_EQ(a.counters().stray, strays.size());
  EXPECT_FALSE(a.pending());
}

TEST(NetcanoemAssembler, WrongLengthIsCountedAndLeavesStateAlone) {
  SampleAssembler a(kBase);
  GaugeSample s;
  EXPECT_EQ(a.feed(frame(0x200, {0, 0, 0, 1, 0, 3, 0}), s), FeedResult::wrong_length);  // 7
  EXPECT_FALSE(a.pending());
  EXPECT_EQ(a.feed(frame(0x200, {0, 0, 0, 1, 0, 3, 0, 5}), s), FeedResult::pending);
  EXPECT_EQ(a.feed(frame(0x201, {0, 2, 0, 4, 0, 6, 0, 0}), s), FeedResult::wrong_length);  // 8
  EXPECT_TRUE(a.pending());
  EXPECT_EQ(a.feed(frame(0x201, {0, 2, 0, 4, 0}), s), FeedResult::wrong_length);  // 5
  ASSERT_EQ(a.feed(frame(0x201, {0, 2, 0, 4, 0, 6}), s), FeedResult::sample);
  EXPECT_EQ(s.gauges, (std::array<std::int16_t, 6>{1, 2, 3, 4, 5, 6}));
  EXPECT_EQ(a.counters().wrong_length, 3u);
}

TEST(NetcanoemAssembler, ZeroLengthSampleFrameIsARequest) {
  SampleAssembler a(kBase);
  GaugeSample s;
  EXPECT_EQ(a.feed(*request_sample(kBase), s), FeedResult::request);
  EXPECT_EQ(a.counters().requests, 1u);
  EXPECT_EQ(a.counters().wrong_length, 0u);
}

TEST(NetcanoemAssembler, SecondHalfFirstIsOutOfOrder) {
  SampleAssembler a(kBase);
  GaugeSample s;
  EXPECT_EQ(a.feed(frame(0x201, {0, 2, 0, 4, 0, 6}), s), FeedResult::out_of_order);
  EXPECT_EQ(a.counters().out_of_order, 1u);
  // A full pair afterwards still works, and a second 0x1 is out of order again.
  const auto frames = *encode_sample(kBase, {1, 2, 3, 4, 5, 6}, 0);
  EXPECT_EQ(a.feed(frames[0], s), FeedResult::pending);
  EXPECT_EQ(a.feed(frames[1], s), FeedResult::sample);
  EXPECT_EQ(a.feed(frames[1], s), FeedResult::out_of_order);
  EXPECT_EQ(a.counters().out_of_order, 2u);
}

// Gauges of poll p (1, 2, …): distinct in every gauge and every poll, so a pair that mixes two
// polls' halves cannot pass for either.
std::array<std::int16_t, 6> poll_gauges(int p) {
  std::array<std::int16_t, 6> g{};
  for (int i = 0; i < 6; ++i) g[i] = static_cast<std::int16_t>(1000 * p + 100 * i + 7 * p * i);
  return g;
}

// Feeds frames written as "A<p>" (0x0 response of poll p) and "B<p>" (its 0x1) in that order;
// returns, per complete sample, the poll its tag names and checks that its gauges are exactly
// that poll's (the 0x0 half tagged with its poll).
std::vector<int> feed_pattern(SampleAssembler& a, const std::vector<std::string>& pattern) {
  std::vector<int> polls;
  for (const std::string& f : pattern) {
    const int p = std::stoi(f.substr(1));
    const auto frames = *encode_sample(kBase, poll_gauges(p), static_cast<std::uint16_t>(0));
    GaugeSample s;
    const FeedResult r = a.feed(frames[f[0] == 'A' ? 0 : 1], s, static_cast<std::uint64_t>(p));
    if (r != FeedResult::sample) continue;
    polls.push_back(static_cast<int>(s.tag));
    EXPECT_EQ(s.gauges, poll_gauges(static_cast<int>(s.tag))) << f << ": mixes two polls";
  }
  return polls;
}

// Issue 15: on a bus with CANopen traffic and a host polling without waiting, the board's 0x1
// was overtaken by the next poll's 0x0 (23 of 808 polls) as A1 A2 B1 B2, and twice in a row.
// In-order pairing decodes every poll from its own two frames.
TEST(NetcanoemAssembler, OvertakenSecondHalvesPairInOrder) {
  SampleAssembler a(kBase);
  const std::vector<int> polls =
      feed_pattern(a, {"A1",  "B1",                          // undisturbed
                       "A2",  "A3", "B2", "B3",              // B2 overtaken by A3
                       "A4",  "A5", "B4", "A6", "B5", "B6",  // B4 by A5, B5 by A6
                       "A7",  "A8", "A9", "B7", "B8", "B9",  // B7 by A8 and A9
                       "A10", "B10"});
  EXPECT_EQ(polls, (std::vector<int>{1, 2, 3, 4, 5, 6, 7, 8, 9, 10}));
  EXPECT_EQ(a.counters().samples, 10u);
  EXPECT_EQ(a.counters().overtaken, 5u);  // B2, B4, B5, B7, B8 had a later half queued
  EXPECT_EQ(a.counters().dropped_incomplete, 0u);
  EXPECT_EQ(a.counters().out_of_order, 0u);
  EXPECT_FALSE(a.pending());
}

// The second pattern of issue 15 as written, A1 A2 B1 A3 B3 B2, has poll 3's 0x1 ahead of poll
// 2's: both are the same id with no poll number in them, so no id-based pairing can tell them
// apart. In-order pairing gives A2+B3 and A3+B2 here: this test pins that limit down (and so
// fails if someone believes it solved). See proto/netcanoem.md.
TEST(NetcanoemAssembler, SecondHalvesSwappedAmongThemselvesCannotBeTold) {
  SampleAssembler a(kBase);
  std::vector<int> tags;
  std::vector<bool> exact;
  for (const std::string f : {"A1", "A2", "B1", "A3", "B3", "B2"}) {
    const int p = f[1] - '0';
    const auto frames = *encode_sample(kBase, poll_gauges(p), 0);
    GaugeSample s;
    if (a.feed(frames[f[0] == 'A' ? 0 : 1], s, static_cast<std::uint64_t>(p)) ==
        FeedResult::sample) {
      tags.push_back(static_cast<int>(s.tag));
      exact.push_back(s.gauges == poll_gauges(p) && s.tag == static_cast<std::uint64_t>(p));
    }
  }
  EXPECT_EQ(tags, (std::vector<int>{1, 2, 3}));
  EXPECT_EQ(exact, (std::vector<bool>{true, false, false}));
}

TEST(NetcanoemAssembler, FullQueueDropsTheOldestHalf) {
  SampleAssembler a(kBase);
  std::vector<std::string> pattern;
  for (int p = 1; p <= 5; ++p) pattern.push_back("A" + std::to_string(p));  // B1 never comes
  pattern.insert(pattern.end(), {"B2", "B3", "B4", "B5"});
  EXPECT_EQ(feed_pattern(a, pattern), (std::vector<int>{2, 3, 4, 5}));
  EXPECT_EQ(a.counters().dropped_incomplete, 1u);
  static_assert(SampleAssembler::kPendingCapacity == 4);
}

TEST(NetcanoemAssembler, DropPendingBeforeAndReset) {
  SampleAssembler a(kBase);
  feed_pattern(a, {"A1", "A2", "A3"});
  EXPECT_EQ(a.pending_count(), 3u);
  EXPECT_EQ(a.drop_pending_before(3), 2u);  // halves of polls 1 and 2
  EXPECT_EQ(a.counters().dropped_incomplete, 2u);
  EXPECT_EQ(feed_pattern(a, {"B3"}), (std::vector<int>{3}));
  // reset() forgets waiting halves without counting them.
  feed_pattern(a, {"A4"});
  a.reset();
  GaugeSample s;
  EXPECT_EQ(a.feed((*encode_sample(kBase, poll_gauges(4), 0))[1], s), FeedResult::out_of_order);
  EXPECT_EQ(a.counters().dropped_incomplete, 2u);
}

TEST(NetcanoemAssembler, SaturatedGaugeMakesSampleUnusable) {
  for (int gauge = 0; gauge < 6; ++gauge) {
    for (std::int16_t rail : {std::int16_t{32767}, std::int16_t{-32768}}) {
      std::array<std::int16_t, 6> g{10, 20, 30, 40, 50, 60};
      g[gauge] = rail;
      const auto frames = *encode_sample(kBase, g, 0);
      SampleAssembler a(kBase);
      GaugeSample s;
      a.feed(frames[0], s);
      ASSERT_EQ(a.feed(frames[1], s), FeedResult::sample);
      EXPECT_EQ(s.saturated_mask, 1u << gauge);
      EXPECT_FALSE(s.usable());
      EXPECT_EQ(a.counters().saturated, 1u);
    }
  }
  EXPECT_EQ(saturated_gauges({32767, -32768, 0, 32766, -32767, 1}), 0b11);
}

TEST(NetcanoemAssembler, EachCriticalStatusBitMakesSampleUnusable) {
  for (int bit : {1, 2, 3, 4, 5, 6, 7, 11, 12}) {
    const auto status = static_cast<std::uint16_t>(1u << bit | kStatusAnyError);
    const auto frames = *encode_sample(kBase, {1, 2, 3, 4, 5, 6}, status);
    SampleAssembler a(kBase);
    GaugeSample s;
    a.feed(frames[0], s);
    ASSERT_EQ(a.feed(frames[1], s), FeedResult::sample);
    EXPECT_EQ(s.status, status);
    EXPECT_EQ(s.status_class, StatusClass::critical) << "bit " << bit;
    EXPECT_FALSE(s.usable()) << "bit " << bit;
    EXPECT_EQ(a.counters().critical, 1u);
  }
}

// --- Calibration readout ----------------------------------------------------------------------

// A board emulator answering requests the way NETCANOEM does.
struct FakeBoard {
  std::uint8_t base = kBase;
  FirmwareVersion firmware{3, 7, 12};
  std::array<char, 8> serial{'F', 'T', '1', '2', '3', '4', '5', '\0'};
  std::array<std::array<double, 6>, 6> matrix{};
  std::uint32_t cpf = 1'000'000, cpt = 1'000;
  std::uint8_t force_unit = 2, torque_unit = 3;
  std::uint8_t active = 0;
  int requests = 0;

  FakeBoard() {
    for (int r = 0; r < 6; ++r) {
      for (int c = 0; c < 6; ++c) matrix[r][c] = (r + 1) * 0.5 - c * 0.25;  // exact in float32
    }
  }

  std::vector<CanFrame> answer(const CanFrame& request) {
    ++requests;
    std::vector<CanFrame> out;
    switch (static_cast<Opcode>(opcode_of(request.id))) {
      case Opcode::active_calibration:
        active = request.data[0];
        out.push_back(*encode_active_calibration(base, active));
        break;
      case Opcode::firmware_version:
        out.push_back(*encode_firmware_version(base, firmware));
        break;
      case Opcode::serial_number:
        out.push_back(*encode_serial_number(base, serial));
        break;
      case Opcode::matrix_sg01: {
        const std::array<CanFrame, 3> frames = *encode_matrix_row(base, matrix[request.data[0]]);
        out.insert(out.end(), frames.begin(), frames.end());
        break;
      }
      case Opcode::counts:
        if (firmware.has_counts()) out.push_back(*encode_counts(base, cpf, cpt));
        break;
      case Opcode::units:
        out.push_back(*encode_units(base, force_unit, torque_unit));
        break;
      default:
        break;
    }
    return out;
  }
};

// Runs a readout against the board; `tamper` may edit each response list.
template <typename Tamper>
ReadoutState run_readout(CalibrationReadout& readout, FakeBoard& board, Tamper&& tamper) {
  for (int guard = 0; guard < 100; ++guard) {
    if (readout.state() == ReadoutState::done || readout.state() == ReadoutState::failed) break;
    const CanFrame request = readout.take_request();
    std::vector<CanFrame> responses = board.answer(request);
    tamper(request, responses);
    for (const CanFrame& f : responses) readout.feed(f);
    if (readout.state() == ReadoutState::awaiting_response) readout.retry();  // "timeout"
  }
  return readout.state();
}
ReadoutState run_readout(CalibrationReadout& readout, FakeBoard& board) {
  return run_readout(readout, board, [](const CanFrame&, std::vector<CanFrame>&) {});
}

TEST(NetcanoemReadout, ReadsEverythingFromFirmware37) {
  FakeBoard board;
  CalibrationReadout readout(kBase, 3);
  ASSERT_EQ(run_readout(readout, board), ReadoutState::done);
  const Calibration& c = readout.calibration();
  EXPECT_EQ(board.active, 3);
  EXPECT_EQ(c.active_calibration, 3);
  EXPECT_EQ(c.firmware.major, 3);
  EXPECT_EQ(c.firmware.minor, 7);
  EXPECT_EQ(c.firmware.build, 12);
  EXPECT_STREQ(c.serial_number.data(), "FT12345");
  EXPECT_EQ(c.matrix, board.matrix);
  EXPECT_TRUE(c.counts_from_device);
  EXPECT_EQ(c.counts_per_force, 1'000'000u);
  EXPECT_EQ(c.counts_per_torque, 1'000u);
  EXPECT_EQ(c.force_unit, 2);
  EXPECT_EQ(c.torque_unit, 3);
  EXPECT_EQ(board.requests, 1 + 1 + 1 + 6 + 1 + 1);
  EXPECT_EQ(readout.error(), ReadoutError::none);
}

TEST(NetcanoemReadout, FirmwareBefore37UsesDefaultCounts) {
  FakeBoard board;
  board.firmware = {3, 6, 99};
  board.cpf = board.cpt = 42;
  CalibrationReadout readout(kBase, 0);
  ASSERT_EQ(run_readout(readout, board), ReadoutState::done);
  EXPECT_FALSE(readout.calibration().counts_from_device);
  EXPECT_EQ(readout.calibration().counts_per_force, kDefaultCounts);
  EXPECT_EQ(readout.calibration().counts_per_torque, kDefaultCounts);
  EXPECT_EQ(board.requests, 1 + 1 + 1 + 6 + 1);  // no counts request
  EXPECT_TRUE((FirmwareVersion{4, 0, 0}.has_counts()));
  EXPECT_FALSE((FirmwareVersion{2, 9, 0}.has_counts()));
}

TEST(NetcanoemReadout, IgnoresStrayFramesEchoesAndTheSampleStream) {
  FakeBoard board;
  CalibrationReadout readout(kBase, 1);
  const auto samples = *encode_sample(kBase, {1, 2, 3, 4, 5, 6}, 0);
  const ReadoutState state =
      run_readout(readout, board, [&](const CanFrame& request, std::vector<CanFrame>& frames) {
        // Our own request, looped back (not for 0x6, whose response is the same bytes).
        if (opcode_of(request.id) != 0x6) frames.insert(frames.begin(), request);
        frames.insert(frames.begin(), frame(0x123, {1}));
        frames.insert(frames.begin(), samples.begin(), samples.end());
        frames.insert(frames.begin(), frame(0x206 | kCanExtendedFlag, {9}));
      });
  ASSERT_EQ(state, ReadoutState::done);
  EXPECT_EQ(readout.calibration().matrix, board.matrix);
  EXPECT_EQ(readout.ignored_frames(), 4u + 5u * 10u);
}

TEST(NetcanoemReadout, RetriesAfterALostResponse) {
  FakeBoard board;
  CalibrationReadout readout(kBase, 1);
  bool dropped = false;
  const ReadoutState state =
      run_readout(readout, board, [&](const CanFrame& request, std::vector<CanFrame>& frames) {
        if (!dropped && opcode_of(request.id) == 0x2 && request.data[0] == 2) {
          frames.pop_back();  // the 0x4 part of row 2 is lost
          dropped = true;
        }
      });
  ASSERT_EQ(state, ReadoutState::done);
  EXPECT_EQ(readout.calibration().matrix, board.matrix);
  EXPECT_EQ(board.requests, 12);
}

TEST(NetcanoemReadout, EchoMismatchFails) {
  FakeBoard board;
  CalibrationReadout readout(kBase, 4);
  const ReadoutState state =
      run_readout(readout, board, [](const CanFrame&, std::vector<CanFrame>& frames) {
        if (opcode_of(frames.at(0).id) == 0x6) frames[0].data[0] = 5;
      });
  EXPECT_EQ(state, ReadoutState::failed);
  EXPECT_EQ(readout.error(), ReadoutError::echo_mismatch);
}

TEST(NetcanoemReadout, WrongLengthFails) {
  FakeBoard board;
  CalibrationReadout readout(kBase, 0);
  const ReadoutState state =
      run_readout(readout, board, [](const CanFrame&, std::vector<CanFrame>& frames) {
        if (opcode_of(frames.at(0).id) == 0x8) frames[0].len = 3;
      });
  EXPECT_EQ(state, ReadoutState::failed);
  EXPECT_EQ(readout.error(), ReadoutError::wrong_length);
}

TEST(NetcanoemReadout, MatrixPartsOutOfOrderFail) {
  FakeBoard board;
  CalibrationReadout readout(kBase, 0);
  const ReadoutState state =
      run_readout(readout, board, [](const CanFrame&, std::vector<CanFrame>& frames) {
        if (frames.size() == 3) std::swap(frames[1], frames[2]);
      });
  EXPECT_EQ(state, ReadoutState::failed);
  EXPECT_EQ(readout.error(), ReadoutError::out_of_order);
}

TEST(NetcanoemReadout, NonFiniteCoefficientFails) {
  FakeBoard board;
  board.matrix[4][3] = std::numeric_limits<double>::quiet_NaN();
  CalibrationReadout readout(kBase, 0);
  EXPECT_EQ(run_readout(readout, board), ReadoutState::failed);
  EXPECT_EQ(readout.error(), ReadoutError::bad_value);
}

TEST(NetcanoemReadout, BadArgumentsFailAtOnce) {
  EXPECT_EQ(CalibrationReadout(0x80, 0).error(), ReadoutError::bad_argument);
  EXPECT_EQ(CalibrationReadout(kBase, 16).state(), ReadoutState::failed);
}

TEST(NetcanoemDecode, SingleResponses) {
  std::uint32_t f = 0, t = 0;
  EXPECT_EQ(decode_counts(frame(0x207, {0, 0x0F, 0x42, 0x40, 0, 0, 0x03, 0xE8}), kBase, f, t),
            DecodeStatus::ok);
  EXPECT_EQ(f, 1'000'000u);
  EXPECT_EQ(t, 1'000u);
  EXPECT_EQ(decode_counts(frame(0x207, {0, 0, 0, 0, 0, 0, 0, 1}), kBase, f, t),
            DecodeStatus::bad_value);  // zero counts would divide by zero
  EXPECT_EQ(decode_counts(frame(0x217, {0, 0, 0, 1, 0, 0, 0, 1}), kBase, f, t),
            DecodeStatus::wrong_id);
  EXPECT_EQ(decode_counts(frame(0x207, {0, 0, 0, 1}), kBase, f, t), DecodeStatus::wrong_length);
  FirmwareVersion v;
  EXPECT_EQ(decode_firmware_version(frame(0x20F, {3, 8, 0x01, 0x02}), kBase, v), DecodeStatus::ok);
  EXPECT_EQ(v.build, 0x0102);
  std::array<double, 2> c{};
  // 0x3FC00000 = 1.5f, 0xC0100000 = -2.25f
  EXPECT_EQ(decode_matrix_part(frame(0x203, {0x3F, 0xC0, 0, 0, 0xC0, 0x10, 0, 0}), kBase, 1, c),
            DecodeStatus::ok);
  EXPECT_EQ(c, (std::array<double, 2>{1.5, -2.25}));
  EXPECT_EQ(decode_active_calibration(frame(0x206, {7}), kBase, 7), DecodeStatus::ok);
  EXPECT_EQ(decode_active_calibration(frame(0x206, {6}), kBase, 7), DecodeStatus::bad_value);
}

// --- Wrench -----------------------------------------------------------------------------------

TEST(NetcanoemWrench, MatchesHandComputation) {
  Calibration c;
  c.counts_per_force = 10;
  c.counts_per_torque = 100;
  c.force_unit = static_cast<std::uint8_t>(ForceUnit::N);
  c.torque_unit = static_cast<std::uint8_t>(TorqueUnit::N_mm);
  c.matrix = {{
      {2, 1, 0, 0, 0, 0},    // Fx
      {0, 0, 1, -1, 0, 0},   // Fy
      {1, 1, 1, 1, 1, 1},    // Fz
      {0, 0, 0, 0, 4, 0},    // Tx
      {0, 0, 0, 0, 0, -2},   // Ty
      {1, 0, 0, 0, 0, 0.5},  // Tz
  }};
  const std::array<std::int16_t, 6> gauges{100, -50, 20, 5, 0, 10};
  const std::array<double, 6> bias{10, 0, 0, 5, -2.5, 0};
  // SG − bias = (90, −50, 20, 0, 2.5, 10)
  // C·(SG − bias) = (180 − 50, 20 − 0, 90 − 50 + 20 + 0 + 2.5 + 10, 10, −20, 90 + 5)
  //               = (130, 20, 72.5, 10, −20, 95)
  // ÷ (10, 10, 10, 100, 100, 100) = (13, 2, 7.25, 0.1, −0.2, 0.95)
  const std::array<double, 6> w = gauges_to_wrench(c, gauges, bias);
  const std::array<double, 6> expected{13, 2, 7.25, 0.1, -0.2, 0.95};
  for (int i = 0; i < 6; ++i) EXPECT_DOUBLE_EQ(w[i], expected[i]) << i;

  const auto si = gauges_to_wrench_si(c, gauges, bias);  // N·mm → N·m
  ASSERT_TRUE(si);
  for (int i = 0; i < 3; ++i) EXPECT_DOUBLE_EQ((*si)[i], expected[i]);
  for (int i = 3; i < 6; ++i) EXPECT_DOUBLE_EQ((*si)[i], expected[i] * 1e-3);
  c.torque_unit = 0;
  EXPECT_FALSE(gauges_to_wrench_si(c, gauges, bias));
}

TEST(NetcanoemWrench, UnitFactors) {
  EXPECT_DOUBLE_EQ(*newton_per_force_unit(1), 4.4482216152605);
  EXPECT_DOUBLE_EQ(*newton_per_force_unit(2), 1.0);
  EXPECT_DOUBLE_EQ(*newton_per_force_unit(5), 9.80665);
  EXPECT_DOUBLE_EQ(*newton_metre_per_torque_unit(1), 0.1129848290276167);
  EXPECT_DOUBLE_EQ(*newton_metre_per_torque_unit(2), 1.3558179483314004);
  EXPECT_DOUBLE_EQ(*newton_metre_per_torque_unit(4), 1e-3);
  EXPECT_FALSE(newton_per_force_unit(0));
  EXPECT_FALSE(newton_metre_per_torque_unit(7));
}

// --- The DBC against the code -----------------------------------------------------------------

struct DbcSignal {
  std::string name;
  int start = 0, length = 0;
  bool big_endian = false, is_signed = false, is_float = false;
};
struct DbcMessage {
  std::string name;
  int length = 0;
  std::vector<DbcSignal> signals;
};

std::map<std::uint32_t, DbcMessage> read_dbc(const std::string& path) {
  std::ifstream in(path);
  std::map<std::uint32_t, DbcMessage> messages;
  std::string line;
  std::uint32_t current = 0;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string tag;
    ls >> tag;
    if (tag == "BO_") {
      DbcMessage m;
      std::string name;
      ls >> current >> name >> m.length;
      m.name = name.substr(0, name.size() - 1);  // "SampleA:" → "SampleA"
      messages[current] = m;
    } else if (tag == "SG_") {
      DbcSignal s;
      std::string colon, layout;
      ls >> s.name >> colon >> layout;  // 7|16@0+
      const auto bar = layout.find('|'), at = layout.find('@');
      s.start = std::stoi(layout.substr(0, bar));
      s.length = std::stoi(layout.substr(bar + 1, at - bar - 1));
      s.big_endian = layout[at + 1] == '0';
      s.is_signed = layout[at + 2] == '-';
      messages[current].signals.push_back(s);
    } else if (tag == "SIG_VALTYPE_") {
      std::uint32_t id = 0;
      std::string name;
      if (!(ls >> id >> name)) continue;  // the NS_ list names SIG_VALTYPE_ too
      for (DbcSignal& s : messages[id].signals) {
        if (s.name == name) s.is_float = true;
      }
    }
  }
  return messages;
}

// Motorola (big-endian) extraction in DBC bit numbering: start = MSB, counting down within a
// byte, then on to bit 7 of the next byte.
double dbc_value(const DbcSignal& s, const CanFrame& f) {
  std::uint64_t raw = 0;
  int byte = s.start / 8, bit = s.start % 8;
  for (int i = 0; i < s.length; ++i) {
    raw = raw << 1 | ((f.data[byte] >> bit) & 1u);
    if (bit == 0) {
      ++byte;
      bit = 7;
    } else {
      --bit;
    }
  }
  if (s.is_float) return std::bit_cast<float>(static_cast<std::uint32_t>(raw));
  if (s.is_signed && (raw >> (s.length - 1)) & 1u) {
    return static_cast<double>(static_cast<std::int64_t>(raw) - (std::int64_t{1} << s.length));
  }
  return static_cast<double>(raw);
}

TEST(NetcanoemDbc, DescribesTheFramesTheCodeDecodes) {
  const auto dbc = read_dbc(std::string(ZEROG_SOURCE_DIR) + "/proto/netcanoem.dbc");
  ASSERT_EQ(dbc.size(), 11u);
  for (const auto& [id, m] : dbc) {
    EXPECT_EQ(base_id_of(id), kBase) << m.name;
    for (const DbcSignal& s : m.signals) EXPECT_TRUE(s.big_endian) << s.name;
  }
  auto value = [&](Opcode op, const std::string& name, const CanFrame& f) {
    const DbcMessage& m = dbc.at(can_id(kBase, op));
    EXPECT_EQ(m.length, f.len) << m.name;
    for (const DbcSignal& s : m.signals) {
      if (s.name == name) return dbc_value(s, f);
    }
    ADD_FAILURE() << "no signal " << name;
    return 0.0;
  };
  const auto sample = *encode_sample(kBase, {-32768, 2, -3, 400, 32767, -6}, 0x8004);
  EXPECT_EQ(value(Opcode::sample_a, "Status", sample[0]), 0x8004);
  EXPECT_EQ(value(Opcode::sample_a, "SG0", sample[0]), -32768);
  EXPECT_EQ(value(Opcode::sample_a, "SG2", sample[0]), -3);
  EXPECT_EQ(value(Opcode::sample_a, "SG4", sample[0]), 32767);
  EXPECT_EQ(value(Opcode::sample_b, "SG1", sample[1]), 2);
  EXPECT_EQ(value(Opcode::sample_b, "SG3", sample[1]), 400);
  EXPECT_EQ(value(Opcode::sample_b, "SG5", sample[1]), -6);
  const auto row = *encode_matrix_row(kBase, {1.5, -2.25, 3.0, -4.5, 0.125, 1e-3});
  EXPECT_EQ(value(Opcode::matrix_sg01, "Coef_SG0", row[0]), 1.5);
  EXPECT_EQ(value(Opcode::matrix_sg01, "Coef_SG1", row[0]), -2.25);
  EXPECT_EQ(value(Opcode::matrix_sg23, "Coef_SG3", row[1]), -4.5);
  EXPECT_EQ(value(Opcode::matrix_sg45, "Coef_SG5", row[2]), static_cast<double>(1e-3f));
  const CanFrame counts = *encode_counts(kBase, 1'000'000, 4'000'000'000u);
  EXPECT_EQ(value(Opcode::counts, "CountsPerForce", counts), 1e6);
  EXPECT_EQ(value(Opcode::counts, "CountsPerTorque", counts), 4e9);
  const CanFrame fw = *encode_firmware_version(kBase, {3, 7, 0x1234});
  EXPECT_EQ(value(Opcode::firmware_version, "Minor", fw), 7);
  EXPECT_EQ(value(Opcode::firmware_version, "Build", fw), 0x1234);
  const CanFrame units = *encode_units(kBase, 2, 4);
  EXPECT_EQ(value(Opcode::units, "TorqueUnit", units), 4);
  const CanFrame active = *encode_active_calibration(kBase, 9);
  EXPECT_EQ(value(Opcode::active_calibration, "CalibrationIndex", active), 9);
  const CanFrame serial = *encode_serial_number(kBase, {'A', 'B', 'C', 'D', 'E', 'F', 'G', 'H'});
  EXPECT_EQ(value(Opcode::serial_number, "SerialChar7", serial), 'H');
  const CanFrame adc = *encode_diagnostic_adc(kBase, 0xBEEF);
  EXPECT_EQ(value(Opcode::diagnostic_adc, "AdcCounts", adc), 0xBEEF);
}

// --- Opcode 0x9 (diagnostic ADC; the thermistor is index 2) -----------------------------------

TEST(NetcanoemDiagnostic, RequestCarriesTheIndex) {
  const CanFrame r = *request_diagnostic_adc(kBase, DiagnosticIndex::thermistor);
  EXPECT_EQ(r.id, 0x209u);  // (0x20 << 4) | 0x9
  EXPECT_EQ(r.len, kDiagnosticRequestLength);
  EXPECT_EQ(r.data[0], 2);
  EXPECT_EQ(request_diagnostic_adc(kBase, DiagnosticIndex::ground)->data[0], 5);
  EXPECT_FALSE(request_diagnostic_adc(kBase, static_cast<DiagnosticIndex>(6)).has_value());
  EXPECT_FALSE(request_diagnostic_adc(0x80, DiagnosticIndex::thermistor).has_value());
}

TEST(NetcanoemDiagnostic, ResponseIsBigEndianCountsAndRoundTrips) {
  std::uint16_t counts = 0;
  EXPECT_EQ(decode_diagnostic_adc(frame(0x209, {0x12, 0x34}), kBase, counts), DecodeStatus::ok);
  EXPECT_EQ(counts, 0x1234u);
  EXPECT_EQ(decode_diagnostic_adc(frame(0x209, {0xFF, 0xFE}), kBase, counts), DecodeStatus::ok);
  EXPECT_EQ(counts, 0xFFFEu);  // read as unsigned (UNVERIFIED)
  for (std::uint16_t c : std::array<std::uint16_t, 4>{0, 1, 7500, 65535}) {
    EXPECT_EQ(decode_diagnostic_adc(*encode_diagnostic_adc(kBase, c), kBase, counts),
              DecodeStatus::ok);
    EXPECT_EQ(counts, c);
  }
}

// Malformed frames: a clear status naming what is wrong with the frame, and `counts` untouched.
TEST(NetcanoemDiagnostic, MalformedFramesAreRefusedByName) {
  std::uint16_t counts = 77;
  // The looped-back request (1 byte), a truncated and an over-long response.
  EXPECT_EQ(decode_diagnostic_adc(frame(0x209, {0x02}), kBase, counts), DecodeStatus::wrong_length);
  EXPECT_EQ(decode_diagnostic_adc(frame(0x209, {}), kBase, counts), DecodeStatus::wrong_length);
  EXPECT_EQ(decode_diagnostic_adc(frame(0x209, {1, 2, 3}), kBase, counts),
            DecodeStatus::wrong_length);
  // Another board, another opcode (the gauge half 0x1), an extended frame with the same bits.
  EXPECT_EQ(decode_diagnostic_adc(frame(0x219, {1, 2}), kBase, counts), DecodeStatus::wrong_id);
  EXPECT_EQ(decode_diagnostic_adc(frame(0x201, {1, 2}), kBase, counts), DecodeStatus::wrong_id);
  EXPECT_EQ(decode_diagnostic_adc(frame(0x209 | kCanExtendedFlag, {1, 2}), kBase, counts),
            DecodeStatus::wrong_id);
  EXPECT_EQ(counts, 77u);
  EXPECT_STREQ(decode_status_name(DecodeStatus::wrong_length), "wrong_length");
  EXPECT_STREQ(decode_status_name(DecodeStatus::wrong_id), "wrong_id");
}

// The gauge assembler never takes a 0x9 frame as gauge data, whatever its length.
TEST(NetcanoemDiagnostic, AssemblerCountsDiagnosticFramesAsStray) {
  SampleAssembler a(kBase);
  GaugeSample out;
  const auto pair = *encode_sample(kBase, {1, 2, 3, 4, 5, 6}, 0);
  EXPECT_EQ(a.feed(pair[0], out), FeedResult::pending);
  EXPECT_EQ(a.feed(*encode_diagnostic_adc(kBase, 0x0102), out), FeedResult::stray);
  EXPECT_EQ(a.feed(frame(0x209, {0, 7, 0, 8, 0, 9}), out), FeedResult::stray);  // 6 bytes like 0x1
  ASSERT_EQ(a.feed(pair[1], out), FeedResult::sample);
  EXPECT_EQ(out.gauges, (std::array<std::int16_t, 6>{1, 2, 3, 4, 5, 6}));
}

TEST(NetcanoemThermistor, LinearConversionAndItsInverse) {
  const ThermistorConversion c{-50.0, 0.01};
  ASSERT_TRUE(thermistor_conversion_valid(c));
  EXPECT_DOUBLE_EQ(thermistor_celsius(c, 0), -50.0);
  EXPECT_DOUBLE_EQ(thermistor_celsius(c, 7500), 25.0);
  EXPECT_EQ(thermistor_counts(c, 25.0), 7500u);
  EXPECT_EQ(thermistor_counts(c, 25.004), 7500u);          // nearest count
  EXPECT_FALSE(thermistor_counts(c, -50.01).has_value());  // below 0 counts
  EXPECT_FALSE(thermistor_counts(c, 700.0).has_value());   // above 65535 counts
  EXPECT_FALSE(thermistor_counts(c, std::numeric_limits<double>::quiet_NaN()).has_value());
  // A falling characteristic (an NTC divider read high-side) is a negative slope.
  const ThermistorConversion ntc{100.0, -0.002};
  EXPECT_DOUBLE_EQ(thermistor_celsius(ntc, *thermistor_counts(ntc, 20.0)), 20.0);
  EXPECT_FALSE(thermistor_conversion_valid({25.0, 0.0}));
  EXPECT_FALSE(thermistor_conversion_valid({std::numeric_limits<double>::infinity(), 0.01}));
  EXPECT_FALSE(thermistor_counts({25.0, 0.0}, 25.0).has_value());
}

}  // namespace
}  // namespace zerog::proto::netcanoem
