#pragma once
// zerog decode-rsi: a text capture of KUKA RSI traffic → a robot recording (proto/rsi_capture.md).
//
// The capture is any text holding the controller's `<Rob …>…</Rob>` messages: one a line (a
// packet dump), several a line, spread over lines, or embedded in another program's log lines;
// CR LF or LF. Each message is parsed by the real-time parser (proto::rsi::parse_robot_message);
// refusals are counted by status with their line and column. Units become SI here (the border):
// joints in rad, the pose of the sensor frame S in the robot base frame B in m and a unit
// quaternion, time in s from the IPOC (the controller's interpolation-cycle stamp, ms).
// Host code: allocates, throws formats::InputError on an unreadable file.
#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "zerog/proto/rsi.hpp"
#include "zerog/robot/robot_model.hpp"

namespace zerog::io {

/// Where each row's pose comes from.
enum class RsiPoseSource : std::uint8_t {
  automatic,  ///< RIst where the message has one, else the robot's kinematics (if given)
  rist,       ///< RIst only (messages without it have no pose)
  joints,     ///< the robot's forward kinematics of AIPos only (needs a robot)
};

struct RsiDecodeOptions {
  /// The arm with its flange_sensor (a rig's robot): S in B from AIPos by
  /// robot::sensor_pose. Without it, poses come from RIst only.
  std::optional<robot::RobotModel> robot;
  RsiPoseSource pose_source = RsiPoseSource::automatic;
  double ipoc_unit_s = 1e-3;  ///< KUKA's IPOC counts milliseconds
  /// The RSI cycle in IPOC units (4 or 12 ms); 0: the most frequent IPOC step of the capture.
  std::uint64_t cycle_ipoc = 0;
  /// Kinds of E1, E2, … (EIPos) for their SI conversion; axes beyond this list are not written.
  std::vector<proto::rsi::ExternalAxisKind> external_axes;
};

/// One decoded message, SI.
struct RsiRow {
  std::uint64_t ipoc = 0;
  double t_s = 0.0;  ///< ipoc · ipoc_unit_s: the controller's clock
  std::array<double, 6> joints_rad{};
  bool has_pose = false;
  bool pose_from_joints = false;  ///< the pose is the kinematics' (no RIst, or pose_source joints)
  std::array<double, 3> p_base_sensor_m{};
  std::array<double, 4> q_base_sensor_wxyz{1.0, 0.0, 0.0, 0.0};
  /// RIst against the kinematics when both exist (valid if has_check): distance of the
  /// origins (m) and angle of the relative rotation (rad).
  double check_m = 0.0, check_rad = 0.0;
  bool has_check = false;
  bool has_delay = false;
  std::uint64_t delay = 0;
  std::array<double, proto::rsi::kMaxExternalAxes> external_si{};  ///< m or rad, by kind
  std::uint8_t external_present = 0;                               ///< bit i: E(i+1)
  std::size_t line = 0;                                            ///< 1-based, of "<Rob"
};

/// A message the parser refused.
struct RsiRefusal {
  proto::rsi::ParseStatus status = proto::rsi::ParseStatus::ok;
  const char* reason = "";
  std::size_t line = 0, column = 0;  ///< 1-based, of the problem in the capture
};

struct RsiDecodeResult {
  std::vector<RsiRow> rows;  ///< in capture order, IPOC strictly increasing
  std::size_t messages = 0;  ///< `<Rob` found
  std::size_t replies = 0;   ///< `<Sen` found (our side of the traffic): ignored
  std::vector<RsiRefusal> refusals;
  std::array<std::size_t, static_cast<std::size_t>(proto::rsi::ParseStatus::bad_number) + 1>
      refusals_by_status{};
  std::size_t without_rist = 0;      ///< parsed messages without RIst
  std::size_t with_external = 0;     ///< parsed messages with EIPos
  std::size_t skipped_elements = 0;  ///< children the parser skipped (ASPos, Tech, …), all messages
  std::size_t stale = 0;             ///< IPOC not above the previous one: dropped
  std::uint64_t cycle_ipoc = 0;      ///< the RSI cycle used for gaps (IPOC units)
  std::size_t ipoc_gaps = 0;         ///< steps longer than 1.5 cycles
  std::uint64_t cycles_lost = 0;     ///< Σ (round(step / cycle) − 1) over the gaps
  std::size_t pose_checks = 0;       ///< rows with both RIst and kinematics
  double max_check_m = 0.0, max_check_rad = 0.0;
  bool all_have_pose = true;  ///< every row has a pose (else the CSV has no pose columns)
};

/// Decodes a capture held in memory. Never throws on content: refusals are counted.
RsiDecodeResult decode_rsi_capture(std::string_view text, const RsiDecodeOptions& options);
/// Reads and decodes a file. Throws formats::InputError if it cannot be read.
RsiDecodeResult decode_rsi_capture_file(const std::filesystem::path& path,
                                        const RsiDecodeOptions& options);

/// The recording as CSV text (`zerog-rsi 1`, proto/rsi_capture.md).
std::string rsi_recording_csv(const RsiDecodeResult& r, const RsiDecodeOptions& options);
/// Writes it atomically.
void write_rsi_recording(const RsiDecodeResult& r, const RsiDecodeOptions& options,
                         const std::filesystem::path& out,
                         const std::vector<std::filesystem::path>& inputs);

/// The `[files.robot]` table of an import mapping that reads the recording
/// (proto/import_mapping.md).
std::string rsi_mapping_snippet(const RsiDecodeResult& r, const std::filesystem::path& csv);

}  // namespace zerog::io
