#pragma once
// KUKA RSI-like XML over UDP (proto/rsi.md). The controller sends, every interpolation cycle,
//
//     <Rob Type="KUKA"><RIst X=".." Y=".." Z=".." A=".." B=".." C=".."/>
//       <AIPos A1=".." A2=".." A3=".." A4=".." A5=".." A6=".."/><Delay D=".."/>
//       <IPOC>123</IPOC> ...other elements, ignored... </Rob>
//
// (RIst, EIPos and Delay optional; the root's attributes, Type or TYPE, are not checked) in mm
// and degrees; we answer within the cycle with
//
//     <Sen Type="zerog"><RKorr X=".." Y=".." Z=".." A=".." B=".." C=".."/><IPOC>123</IPOC></Sen>
//
// Why a dedicated parser and not a general XML library: this runs in the real-time cycle, so it
// must not allocate (DOM and most SAX libraries allocate per node or per string), must finish in
// time bounded by the input length (which is itself bounded, kMaxMessageBytes), and should accept
// exactly the subset a KUKA controller sends, rejecting everything else loudly (no entities, no
// DTD, no comments, no CDATA, no namespaces) instead of guessing. It never reads past the buffer
// and reports every failure as a status with the byte offset and a reason.
//
// Units are converted only here, at the border: helpers below give SI (m, rad) and back.
//
// Everything here is real-time safe (no allocation, no exceptions, no locks, bounded time).
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "zerog/samples/robot_sample.hpp"

namespace zerog::proto::rsi {

inline constexpr std::size_t kMaxMessageBytes = 4096;  ///< larger messages are rejected whole
inline constexpr int kMaxDepth = 8;                    ///< element nesting, root included
inline constexpr std::size_t kMaxNameLength = 32;      ///< element and attribute names
inline constexpr std::size_t kMaxNumberLength = 32;    ///< characters of one numeric value

/// KUKA Cartesian pose: X, Y, Z in mm; A, B, C in degrees (rotations about Z, Y', X'').
struct CartesianPose {
  double x_mm = 0, y_mm = 0, z_mm = 0;
  double a_deg = 0, b_deg = 0, c_deg = 0;
};

inline constexpr std::size_t kMaxExternalAxes = 6;  ///< EIPos E1..E6

/// What we read from one controller message.
struct RobotMessage {
  /// <RIst> is optional: many RSI configurations send joints only (AIPos). false when the
  /// message had none; then actual_pose is zero and the pose must come from the robot's
  /// forward kinematics (zerog::robot). format_robot_message writes RIst only when true.
  bool has_actual_pose = true;
  CartesianPose actual_pose;           ///< <RIst>: actual TCP pose in the base frame
  std::array<double, 6> joints_deg{};  ///< <AIPos A1..A6>: actual axis positions, degrees
  /// <EIPos E1..E6> (optional, any non-empty subset of its attributes): actual external axis
  /// positions in KUKA units, mm for a linear axis and degrees for a rotary one (the robot's
  /// configuration says which: external_axis_to_si). Bit i of external_axes_present: E(i+1)
  /// was given.
  std::array<double, kMaxExternalAxes> external_axes{};
  std::uint8_t external_axes_present = 0;
  bool has_delay = false;              ///< <Delay> is optional
  std::uint64_t delay = 0;             ///< <Delay D>: late packets counted by the controller
  std::uint64_t ipoc = 0;              ///< <IPOC>: cycle stamp to echo in the reply
  std::uint16_t skipped_elements = 0;  ///< children we do not read (RSol, ASPos, Tech, …)
};

enum class ParseStatus : std::uint8_t {
  ok,
  too_long,            ///< more than kMaxMessageBytes
  truncated,           ///< input ends inside the message
  syntax,              ///< malformed XML (in the subset we accept)
  unsupported,         ///< comment, CDATA, DTD, processing instruction after the start
  wrong_root,          ///< root element is not <Rob> (<Sen> for parse_reply)
  unexpected_content,  ///< text where only elements may be, or content after </Rob>
  too_deep,            ///< nesting beyond kMaxDepth
  duplicate_element,   ///< RIst, AIPos, EIPos, Delay or IPOC twice (RKorr, AKorr, IPOC in a reply)
  missing_element,     ///< AIPos or IPOC absent (IPOC in a reply)
  missing_attribute,   ///< e.g. RIst without Z
  unknown_attribute,   ///< an attribute our elements do not have
  duplicate_attribute,
  bad_number,  ///< not a finite decimal number (or too long), or IPOC/Delay not an integer
};

struct ParseResult {
  ParseStatus status = ParseStatus::ok;
  std::size_t offset = 0;     ///< byte offset of the problem in the input
  const char* reason = "ok";  ///< static string, human readable
  constexpr bool ok() const { return status == ParseStatus::ok; }
};

/// The status's name as written here ("ok", "too_long", …, "bad_number"). Real-time safe.
const char* to_string(ParseStatus status);

/// Parses one controller message. `out` is complete only when the result is ok.
ParseResult parse_robot_message(std::string_view message, RobotMessage& out);

/// Our correction, in the RSI units (mm, degrees).
struct Correction {
  double x_mm = 0, y_mm = 0, z_mm = 0;
  double a_deg = 0, b_deg = 0, c_deg = 0;
};

enum class FormatStatus : std::uint8_t {
  ok,
  buffer_too_small,
  not_finite,       ///< a correction value is NaN or infinite
  bad_sensor_type,  ///< empty, too long, or characters other than [A-Za-z0-9_.-]
};
struct FormatResult {
  FormatStatus status;
  std::size_t size;  ///< bytes written, no terminating NUL (0 unless ok)
};

/// Digits after the point in RKorr and AKorr (0.1 µm, 0.0001°).
inline constexpr int kReplyDecimals = samples::kRsiCorrectionDecimals;

/// Writes the reply into `out` (no NUL terminator); never writes past `out`.
FormatResult format_reply(const Correction& correction, std::uint64_t ipoc, std::span<char> out,
                          std::string_view sensor_type = "zerog");

/// An axis-correction reply, for zerog-rt's calibration-collection mode:
/// `<Sen Type=".."><AKorr A1=".." … A6=".."/><IPOC>..</IPOC></Sen>`, degrees, kReplyDecimals
/// digits. Same statuses and bounds as format_reply.
FormatResult format_axis_reply(const std::array<double, 6>& akorr_deg, std::uint64_t ipoc,
                               std::span<char> out, std::string_view sensor_type = "zerog");

// --- The controller side (the robot emulator, host/emu; tests) --------------------------------

/// Writes `<Rob Type="KUKA"><RIst X.. C../><AIPos A1..A6/><EIPos ../><Delay D=".."/>
/// <IPOC>n</IPOC></Rob>` (RIst only when m.has_actual_pose, EIPos with the attributes of
/// m.external_axes_present when any, Delay only when m.has_delay), numbers with
/// kReplyDecimals digits: parse_robot_message reads
/// it back to within half a unit of the last digit. `not_finite` for a NaN or infinite value,
/// `buffer_too_small` if it does not fit; never writes past `out`.
FormatResult format_robot_message(const RobotMessage& m, std::span<char> out);

/// A reply as the controller reads it: `<Sen Type="..">` with RKorr X..C and/or AKorr A1..A6
/// (each at most once, both optional) and the IPOC (required); other elements are skipped. Same
/// syntax subset, bounds and error reporting as parse_robot_message.
struct Reply {
  bool has_rkorr = false;
  Correction rkorr;  ///< mm, degrees (valid if has_rkorr)
  bool has_akorr = false;
  std::array<double, 6> akorr_deg{};  ///< A1..A6, degrees (valid if has_akorr)
  std::uint64_t ipoc = 0;
};

/// Parses one reply. `out` is written only when the result is ok.
ParseResult parse_reply(std::string_view message, Reply& out);

// --- Border unit conversions -----------------------------------------------------------------

inline constexpr double kRadPerDeg = 3.14159265358979323846 / 180.0;

/// A pose in SI: position in m, A, B, C in rad (same angle convention as KUKA).
struct PoseSi {
  std::array<double, 3> position_m{};
  std::array<double, 3> abc_rad{};
};
PoseSi to_si(const CartesianPose& pose);
std::array<double, 6> joints_to_rad(const std::array<double, 6>& joints_deg);
/// What kind of axis an external axis is: its EIPos value is in mm (linear) or degrees (rotary).
enum class ExternalAxisKind : std::uint8_t { rotary, linear };
/// An EIPos value in SI: m (linear) or rad (rotary).
double external_axis_to_si(double value, ExternalAxisKind kind);
/// Correction from SI: translation in m, A, B, C in rad.
Correction correction_from_si(const std::array<double, 3>& translation_m,
                              const std::array<double, 3>& abc_rad);

}  // namespace zerog::proto::rsi
