// KUKA RSI XML, the controller side (proto/rsi.md): the <Rob> formatter and the <Sen> reply parser
// the robot emulator uses, the axis-correction reply, their round trips through the parsers,
// every truncation and undersized buffer, the malformed replies, and that nothing allocates.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "alloc_count.hpp"
#include "zerog/proto/rsi.hpp"

namespace zerog::proto::rsi {
namespace {

RobotMessage sample_message() {
  RobotMessage m;
  m.actual_pose = {1765.1234, -0.25, 1784.0001, 179.9999, -89.5, -0.0001};
  m.joints_deg = {0.0, -90.0, 90.0, -350.0, 45.1234, 12.25};
  m.has_delay = true;
  m.delay = 17;
  m.ipoc = 1'000'012;
  return m;
}

std::string format(const RobotMessage& m) {
  std::array<char, 1024> buf{};
  const FormatResult f = format_robot_message(m, buf);
  EXPECT_EQ(f.status, FormatStatus::ok);
  return std::string(buf.data(), f.size);
}

// A copy of exactly the first n bytes (so reading past the end is caught by sanitizers).
template <typename Check>
void for_each_prefix(const std::string& text, Check&& check) {
  for (std::size_t n = 0; n < text.size(); ++n) {
    const std::unique_ptr<char[]> copy(new char[n == 0 ? 1 : n]);
    std::copy(text.begin(), text.begin() + static_cast<std::ptrdiff_t>(n), copy.get());
    check(std::string_view(copy.get(), n), n);
  }
}

void expect_reply_error(const std::string& text, ParseStatus status, std::size_t offset) {
  Reply r;
  r.ipoc = 99;
  const ParseResult p = parse_reply(text, r);
  EXPECT_EQ(p.status, status) << text << "\n" << p.reason << " at " << p.offset;
  EXPECT_EQ(p.offset, offset) << text << "\n" << p.reason;
  EXPECT_EQ(r.ipoc, 99u) << "output written on error: " << text;
}

TEST(RsiController, RobotMessageExactText) {
  RobotMessage m = sample_message();
  EXPECT_EQ(format(m),
            "<Rob Type=\"KUKA\"><RIst X=\"1765.1234\" Y=\"-0.2500\" Z=\"1784.0001\" "
            "A=\"179.9999\" B=\"-89.5000\" C=\"-0.0001\"/><AIPos A1=\"0.0000\" A2=\"-90.0000\" "
            "A3=\"90.0000\" A4=\"-350.0000\" A5=\"45.1234\" A6=\"12.2500\"/><Delay D=\"17\"/>"
            "<IPOC>1000012</IPOC></Rob>");
  m.has_delay = false;
  EXPECT_EQ(format(m).find("Delay"), std::string::npos);
}

TEST(RsiController, RobotMessageRoundTrip) {
  for (bool has_delay : {true, false}) {
    RobotMessage m = sample_message();
    m.has_delay = has_delay;
    m.delay = has_delay ? 18446744073709551615u : 0;
    m.ipoc = 18446744073709551615u;
    m.actual_pose.x_mm = 1234.56789;  // rounds to 4 decimals
    RobotMessage back;
    const std::string text = format(m);
    const ParseResult p = parse_robot_message(text, back);
    ASSERT_TRUE(p.ok()) << p.reason << " at " << p.offset << ": " << text;
    EXPECT_NEAR(back.actual_pose.x_mm, m.actual_pose.x_mm, 0.5e-4);
    EXPECT_DOUBLE_EQ(back.actual_pose.x_mm, 1234.5679);
    EXPECT_DOUBLE_EQ(back.actual_pose.y_mm, m.actual_pose.y_mm);
    EXPECT_DOUBLE_EQ(back.actual_pose.z_mm, m.actual_pose.z_mm);
    EXPECT_DOUBLE_EQ(back.actual_pose.a_deg, m.actual_pose.a_deg);
    EXPECT_DOUBLE_EQ(back.actual_pose.b_deg, m.actual_pose.b_deg);
    EXPECT_DOUBLE_EQ(back.actual_pose.c_deg, m.actual_pose.c_deg);
    EXPECT_EQ(back.joints_deg, m.joints_deg);
    EXPECT_EQ(back.has_delay, has_delay);
    EXPECT_EQ(back.delay, m.delay);
    EXPECT_EQ(back.ipoc, m.ipoc);
  }
}

TEST(RsiController, JointsOnlyAndExternalAxesRoundTrip) {
  RobotMessage m = sample_message();
  m.has_actual_pose = false;
  m.actual_pose.x_mm = std::numeric_limits<double>::quiet_NaN();  // not written: not checked
  m.external_axes_present = 0x05;                                 // E1 and E3
  m.external_axes = {1500.25, 99.0, -12.5, 0, 0, 0};
  const std::string text = format(m);
  EXPECT_EQ(text.find("RIst"), std::string::npos) << text;
  EXPECT_NE(text.find("<EIPos E1=\"1500.2500\" E3=\"-12.5000\"/>"), std::string::npos) << text;
  RobotMessage back;
  const ParseResult p = parse_robot_message(text, back);
  ASSERT_TRUE(p.ok()) << p.reason << " at " << p.offset << ": " << text;
  EXPECT_FALSE(back.has_actual_pose);
  EXPECT_EQ(back.external_axes_present, 0x05);
  EXPECT_DOUBLE_EQ(back.external_axes[0], 1500.25);
  EXPECT_DOUBLE_EQ(back.external_axes[2], -12.5);
  EXPECT_EQ(back.joints_deg, m.joints_deg);
}

TEST(RsiController, RobotMessageRefusesNonFiniteAndSmallBuffers) {
  RobotMessage m = sample_message();
  const std::string text = format(m);
  std::vector<char> buf(text.size() + 8, '#');
  for (std::size_t n = 0; n < text.size(); ++n) {
    std::fill(buf.begin(), buf.end(), '#');
    const FormatResult f = format_robot_message(m, std::span<char>(buf.data(), n));
    EXPECT_EQ(f.status, FormatStatus::buffer_too_small) << n;
    EXPECT_EQ(f.size, 0u);
    EXPECT_TRUE(std::all_of(buf.begin() + static_cast<std::ptrdiff_t>(n), buf.end(),
                            [](char c) { return c == '#'; }))
        << "wrote past " << n;
  }
  EXPECT_EQ(format_robot_message(m, std::span<char>(buf.data(), text.size())).size, text.size());
  m.joints_deg[3] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(format_robot_message(m, buf).status, FormatStatus::not_finite);
  m = sample_message();
  m.actual_pose.c_deg = std::numeric_limits<double>::infinity();
  EXPECT_EQ(format_robot_message(m, buf).status, FormatStatus::not_finite);
}

TEST(RsiController, EveryTruncatedRobotMessageIsRejected) {
  for_each_prefix(format(sample_message()), [](std::string_view prefix, std::size_t n) {
    RobotMessage out;
    const ParseResult p = parse_robot_message(prefix, out);
    EXPECT_EQ(p.status, ParseStatus::truncated) << n << ": " << prefix;
    EXPECT_EQ(p.offset, n);
  });
}

TEST(RsiController, CorrectionReplyRoundTrip) {
  std::array<char, 256> buf{};
  const Correction c{1.0, -0.0001, 2.5, 0.01, -0.02, 0.0};
  const FormatResult f = format_reply(c, 4208157, buf);
  ASSERT_EQ(f.status, FormatStatus::ok);
  Reply r;
  const ParseResult p = parse_reply(std::string_view(buf.data(), f.size), r);
  ASSERT_TRUE(p.ok()) << p.reason << " at " << p.offset;
  EXPECT_TRUE(r.has_rkorr);
  EXPECT_FALSE(r.has_akorr);
  EXPECT_EQ(r.ipoc, 4208157u);
  EXPECT_DOUBLE_EQ(r.rkorr.x_mm, 1.0);
  EXPECT_DOUBLE_EQ(r.rkorr.y_mm, -0.0001);
  EXPECT_DOUBLE_EQ(r.rkorr.z_mm, 2.5);
  EXPECT_DOUBLE_EQ(r.rkorr.a_deg, 0.01);
  EXPECT_DOUBLE_EQ(r.rkorr.b_deg, -0.02);
  EXPECT_DOUBLE_EQ(r.rkorr.c_deg, 0.0);
}

TEST(RsiController, AxisReplyExactTextAndRoundTrip) {
  std::array<char, 256> buf{};
  const std::array<double, 6> akorr{0.001, -0.5, 0.0, 12.25, -0.0001, 3.0};
  const FormatResult f = format_axis_reply(akorr, 77, buf, "calib");
  ASSERT_EQ(f.status, FormatStatus::ok);
  const std::string text(buf.data(), f.size);
  EXPECT_EQ(text,
            "<Sen Type=\"calib\"><AKorr A1=\"0.0010\" A2=\"-0.5000\" A3=\"0.0000\" A4=\"12.2500\" "
            "A5=\"-0.0001\" A6=\"3.0000\"/><IPOC>77</IPOC></Sen>");
  Reply r;
  ASSERT_TRUE(parse_reply(text, r).ok());
  EXPECT_FALSE(r.has_rkorr);
  EXPECT_TRUE(r.has_akorr);
  EXPECT_EQ(r.akorr_deg, akorr);
  EXPECT_EQ(r.ipoc, 77u);

  EXPECT_EQ(format_axis_reply(akorr, 77, buf, "").status, FormatStatus::bad_sensor_type);
  EXPECT_EQ(format_axis_reply(akorr, 77, buf, "a b").status, FormatStatus::bad_sensor_type);
  std::array<double, 6> nan = akorr;
  nan[5] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(format_axis_reply(nan, 77, buf).status, FormatStatus::not_finite);
  for (std::size_t n = 0; n < text.size(); ++n) {
    EXPECT_EQ(format_axis_reply(akorr, 77, std::span<char>(buf.data(), n), "calib").status,
              FormatStatus::buffer_too_small)
        << n;
  }
}

TEST(RsiController, ReplyWithBothCorrectionsSkippedElementsAndProlog) {
  const std::string text =
      "<?xml version=\"1.0\"?>\n<Sen Type='ImFree'>\n"
      "  <EStr>hello &amp; more</EStr>\n"
      "  <AKorr A6='6' A5='5' A4='4' A3='3' A2='2' A1='1'></AKorr>\n"
      "  <Tech T21=\"1\"><Inner x='1'/></Tech>\n"
      "  <RKorr X='.5' Y='-1e-3' Z='0' A='1' B='2' C='3'/>\n"
      "  <IPOC> 42 </IPOC>\n"
      "</Sen>\n";
  Reply r;
  const ParseResult p = parse_reply(text, r);
  ASSERT_TRUE(p.ok()) << p.reason << " at " << p.offset;
  EXPECT_TRUE(r.has_rkorr);
  EXPECT_TRUE(r.has_akorr);
  EXPECT_EQ(r.akorr_deg, (std::array<double, 6>{1, 2, 3, 4, 5, 6}));
  EXPECT_DOUBLE_EQ(r.rkorr.x_mm, 0.5);
  EXPECT_DOUBLE_EQ(r.rkorr.y_mm, -1e-3);
  EXPECT_DOUBLE_EQ(r.rkorr.c_deg, 3.0);
  EXPECT_EQ(r.ipoc, 42u);

  // Neither correction: a valid reply that corrects nothing.
  Reply bare;
  ASSERT_TRUE(parse_reply("<Sen Type=\"zerog\"><IPOC>5</IPOC></Sen>", bare).ok());
  EXPECT_FALSE(bare.has_rkorr);
  EXPECT_FALSE(bare.has_akorr);
  EXPECT_EQ(bare.ipoc, 5u);
}

TEST(RsiController, MalformedReplies) {
  const std::string good =
      "<Sen Type=\"zerog\"><RKorr X=\"1\" Y=\"2\" Z=\"3\" A=\"4\" B=\"5\" C=\"6\"/>"
      "<IPOC>7</IPOC></Sen>";
  auto with = [&](std::string_view from, std::string_view to) {
    std::string s = good;
    const std::size_t at = s.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return s.replace(at, from.size(), to);
  };
  expect_reply_error(with("<Sen", "<Rob"), ParseStatus::wrong_root, 1);
  std::string s = with("<IPOC>7</IPOC>", "");
  expect_reply_error(s, ParseStatus::missing_element, s.size() - 6);
  s = with("<IPOC>", "<IPOC>7</IPOC><IPOC>");
  expect_reply_error(s, ParseStatus::duplicate_element, good.find("<IPOC>") + 14);
  s = with("<IPOC>", "<RKorr X=\"1\" Y=\"2\" Z=\"3\" A=\"4\" B=\"5\" C=\"6\"/><IPOC>");
  expect_reply_error(s, ParseStatus::duplicate_element, good.find("<IPOC>"));
  s = with(" C=\"6\"", "");
  expect_reply_error(s, ParseStatus::missing_attribute, s.find("/>") + 1);
  expect_reply_error(with("C=\"6\"", "C=\"6\" D=\"1\""), ParseStatus::unknown_attribute,
                     good.find("/>") + 1);
  expect_reply_error(with("X=\"1\"", "X=\"1\" X=\"1\""), ParseStatus::duplicate_attribute,
                     good.find("X=") + 6);
  expect_reply_error(with("Y=\"2\"", "Y=\"nan\""), ParseStatus::bad_number, good.find("Y=") + 3);
  expect_reply_error(with("<IPOC>7", "<IPOC>-7"), ParseStatus::bad_number, good.find("<IPOC>") + 6);
  expect_reply_error(with("<IPOC>", "<!-- x --><IPOC>"), ParseStatus::unsupported,
                     good.find("<IPOC>"));
  expect_reply_error(with("</Sen>", "</Sen>x"), ParseStatus::unexpected_content, good.size());
  expect_reply_error(with("<IPOC>", "text<IPOC>"), ParseStatus::unexpected_content,
                     good.find("<IPOC>"));
  expect_reply_error(good + std::string(kMaxMessageBytes, ' '), ParseStatus::too_long,
                     kMaxMessageBytes);
  // An AKorr with robot-pose attribute names is refused, not misread.
  expect_reply_error(with("RKorr", "AKorr"), ParseStatus::unknown_attribute, good.find("X="));
}

TEST(RsiController, EveryTruncatedReplyIsRejected) {
  std::array<char, 256> buf{};
  const FormatResult f = format_reply({1, 2, 3, 4, 5, 6}, 123456, buf);
  ASSERT_EQ(f.status, FormatStatus::ok);
  for (const std::string& text :
       {std::string(buf.data(), f.size),
        std::string("<Sen Type=\"x\"><AKorr A1=\"1\" A2=\"2\" A3=\"3\" A4=\"4\" A5=\"5\" "
                    "A6=\"6\"></AKorr><Extra><a/></Extra><IPOC>9</IPOC></Sen>")}) {
    for_each_prefix(text, [](std::string_view prefix, std::size_t n) {
      Reply out;
      const ParseResult p = parse_reply(prefix, out);
      EXPECT_EQ(p.status, ParseStatus::truncated) << n << ": " << prefix;
      EXPECT_EQ(p.offset, n);
    });
  }
}

TEST(RsiController, NeitherFormattingNorParsingAllocates) {
  const RobotMessage m = sample_message();
  std::array<char, 1024> buf{};
  std::array<char, 256> reply{};
  RobotMessage back;
  Reply r;
  std::size_t bytes = 0;
  const std::size_t before = zerog::test::allocation_count();
  for (int i = 0; i < 100; ++i) {
    const FormatResult f = format_robot_message(m, buf);
    bytes += parse_robot_message(std::string_view(buf.data(), f.size), back).ok();
    const FormatResult a = format_axis_reply(m.joints_deg, m.ipoc, reply);
    bytes += parse_reply(std::string_view(reply.data(), a.size), r).ok();
    bytes += parse_reply(std::string_view(reply.data(), a.size / 2), r).ok();
  }
  EXPECT_EQ(zerog::test::allocation_count(), before);
  EXPECT_EQ(bytes, 200u);
}

}  // namespace
}  // namespace zerog::proto::rsi
