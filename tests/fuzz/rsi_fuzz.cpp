// RSI XML datagrams (proto/rsi.md) as zerog-rt receives them from the robot controller
// (parse_robot_message) and as the robot emulator receives our replies (parse_reply). The parsers
// report every failure as a status (never throw). Round trip for what parses: formatting the
// values and parsing the text again gives them back to half a unit of the last written digit.
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "fuzz_util.hpp"
#include "zerog/proto/rsi.hpp"

namespace rsi = zerog::proto::rsi;
using zerog::fuzz::near;

namespace {

// format_* write kReplyDecimals digits; a value as large as 1e30 mm cannot come back through the
// 32-character number limit, and no robot sends one: the round trip is checked below 1e9.
constexpr double kRoundTripLimit = 1e9;
constexpr double kHalfDigit = 0.5e-4;

bool in_round_trip_range(double v) { return std::fabs(v) < kRoundTripLimit; }

void check_values(double a, double b) {
  ZEROG_FUZZ_CHECK(near(a, b, kHalfDigit * (1.0 + 1e-9), 1e-15));
}

void robot_message_round_trip(const rsi::RobotMessage& m) {
  const rsi::CartesianPose& p = m.actual_pose;
  const std::array<double, 6> pose{p.x_mm, p.y_mm, p.z_mm, p.a_deg, p.b_deg, p.c_deg};
  for (double v : pose)
    if (!in_round_trip_range(v)) return;
  for (double v : m.joints_deg)
    if (!in_round_trip_range(v)) return;
  std::array<char, rsi::kMaxMessageBytes> buffer{};
  const rsi::FormatResult written = rsi::format_robot_message(m, buffer);
  ZEROG_FUZZ_CHECK(written.status == rsi::FormatStatus::ok);
  rsi::RobotMessage back;
  const rsi::ParseResult again =
      rsi::parse_robot_message(std::string_view(buffer.data(), written.size), back);
  ZEROG_FUZZ_CHECK(again.ok());
  const rsi::CartesianPose& q = back.actual_pose;
  const std::array<double, 6> pose_back{q.x_mm, q.y_mm, q.z_mm, q.a_deg, q.b_deg, q.c_deg};
  for (int i = 0; i < 6; ++i) check_values(pose[i], pose_back[i]);
  for (int i = 0; i < 6; ++i) check_values(m.joints_deg[i], back.joints_deg[i]);
  ZEROG_FUZZ_CHECK(back.ipoc == m.ipoc);
  ZEROG_FUZZ_CHECK(back.has_delay == m.has_delay);
  ZEROG_FUZZ_CHECK(!m.has_delay || back.delay == m.delay);
}

void reply_round_trip(const rsi::Reply& r) {
  if (r.has_rkorr == r.has_akorr) return;  // the writers produce one kind of correction each
  std::array<double, 6> values{};
  if (r.has_rkorr) {
    values = {r.rkorr.x_mm,  r.rkorr.y_mm,  r.rkorr.z_mm,
              r.rkorr.a_deg, r.rkorr.b_deg, r.rkorr.c_deg};
  } else {
    values = r.akorr_deg;
  }
  for (double v : values)
    if (!in_round_trip_range(v)) return;
  std::array<char, rsi::kMaxMessageBytes> buffer{};
  const rsi::FormatResult written = r.has_rkorr
                                        ? rsi::format_reply(r.rkorr, r.ipoc, buffer)
                                        : rsi::format_axis_reply(r.akorr_deg, r.ipoc, buffer);
  ZEROG_FUZZ_CHECK(written.status == rsi::FormatStatus::ok);
  rsi::Reply back;
  ZEROG_FUZZ_CHECK(rsi::parse_reply(std::string_view(buffer.data(), written.size), back).ok());
  ZEROG_FUZZ_CHECK(back.has_rkorr == r.has_rkorr && back.has_akorr == r.has_akorr);
  ZEROG_FUZZ_CHECK(back.ipoc == r.ipoc);
  const std::array<double, 6> values_back =
      back.has_rkorr ? std::array<double, 6>{back.rkorr.x_mm,  back.rkorr.y_mm,  back.rkorr.z_mm,
                                             back.rkorr.a_deg, back.rkorr.b_deg, back.rkorr.c_deg}
                     : back.akorr_deg;
  for (int i = 0; i < 6; ++i) check_values(values[i], values_back[i]);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = zerog::fuzz::as_text(data, size);

  rsi::RobotMessage message;
  const rsi::ParseResult parsed = rsi::parse_robot_message(text, message);
  ZEROG_FUZZ_CHECK(parsed.reason != nullptr);
  ZEROG_FUZZ_CHECK(parsed.offset <= size);
  if (parsed.ok()) robot_message_round_trip(message);

  rsi::Reply reply;
  const rsi::ParseResult parsed_reply = rsi::parse_reply(text, reply);
  ZEROG_FUZZ_CHECK(parsed_reply.reason != nullptr);
  ZEROG_FUZZ_CHECK(parsed_reply.offset <= size);
  if (parsed_reply.ok()) reply_round_trip(reply);
  return 0;
}
