// zerog decode-rsi: a text capture of KUKA RSI traffic → a robot recording in SI
// (proto/rsi_capture.md).
#include <cstdio>
#include <memory>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "commands.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/io/rsi_capture.hpp"

namespace zerog::cli {

namespace {

std::vector<proto::rsi::ExternalAxisKind> parse_external_axes(const std::string& list) {
  std::vector<proto::rsi::ExternalAxisKind> kinds;
  std::stringstream ss(list);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item == "linear") {
      kinds.push_back(proto::rsi::ExternalAxisKind::linear);
    } else if (item == "rotary") {
      kinds.push_back(proto::rsi::ExternalAxisKind::rotary);
    } else {
      throw CLI::ValidationError("--external-axes",
                                 "'" + item + "' is neither linear nor rotary (E1,E2,… in order)");
    }
  }
  if (kinds.size() > proto::rsi::kMaxExternalAxes)
    throw CLI::ValidationError("--external-axes", "at most 6 external axes (E1..E6)");
  return kinds;
}

}  // namespace

void add_decode_rsi_command(CLI::App& app) {
  struct Args {
    std::string capture, out, rig, pose_from = "auto", external_axes;
    int cycle_ms = 0;
    bool verbose = false;
  };
  auto a = std::make_shared<Args>();
  CLI::App* s = app.add_subcommand(
      "decode-rsi",
      "Decode a text capture of KUKA RSI traffic (the controller's <Rob> messages, one a line, "
      "several a line or inside another program's log lines; LF or CR LF) into a robot recording: "
      "time from the IPOC (ms → s), joints (rad), the pose of the sensor frame S in the base "
      "frame B (from RIst, or from the rig's robot kinematics with --rig), Delay. Counts messages, "
      "IPOC gaps and refusals by reason. zerog import merges the recording "
      "(proto/rsi_capture.md).");
  s->add_option("capture", a->capture, "the capture (text)")->required()->check(CLI::ExistingFile);
  s->add_option("-o,--out", a->out, "robot recording to write (CSV, atomically)")->required();
  s->add_option("--rig", a->rig,
                "a .rig.toml whose robot ([robot] or robot_file) and flange_sensor give S from "
                "AIPos: the pose where RIst is missing, and the check of RIst where both are")
      ->check(CLI::ExistingFile);
  s->add_option("--pose-from", a->pose_from,
                "auto: RIst where present, else the kinematics; rist: RIst only; joints: the "
                "kinematics only (needs --rig)")
      ->check(CLI::IsMember({"auto", "rist", "joints"}))
      ->capture_default_str();
  s->add_option("--cycle-ms", a->cycle_ms,
                "the RSI cycle for IPOC gaps (4 or 12); 0: the most frequent IPOC step")
      ->check(CLI::IsMember({0, 4, 12}))
      ->capture_default_str();
  s->add_option("--external-axes", a->external_axes,
                "kinds of E1,E2,… of EIPos, e.g. linear or linear,rotary: written in m or rad");
  s->add_flag("-v,--verbose", a->verbose, "print every refusal with its line and column");
  s->callback([a] {
    io::RsiDecodeOptions o;
    if (!a->rig.empty()) {
      const formats::Rig rig = formats::read_rig(a->rig);
      if (!rig.robot_model)
        throw std::runtime_error(a->rig + ": the rig describes no robot ([robot] or robot_file)");
      if (rig.robot_model->joint_count != 6)
        throw std::runtime_error(a->rig + ": RSI reports 6 axes (A1..A6); the rig's robot has " +
                                 std::to_string(rig.robot_model->joint_count));
      o.robot = rig.robot_model;
    }
    o.pose_source = a->pose_from == "rist"     ? io::RsiPoseSource::rist
                    : a->pose_from == "joints" ? io::RsiPoseSource::joints
                                               : io::RsiPoseSource::automatic;
    if (o.pose_source == io::RsiPoseSource::joints && !o.robot)
      throw CLI::ValidationError("--pose-from", "joints needs --rig with a robot");
    o.cycle_ipoc = static_cast<std::uint64_t>(a->cycle_ms);
    o.external_axes = parse_external_axes(a->external_axes);

    const io::RsiDecodeResult r = io::decode_rsi_capture_file(a->capture, o);
    io::write_rsi_recording(r, o, a->out, {a->capture});

    std::printf("%zu messages: %zu rows written to %s (%zu refused, %zu stale IPOC dropped)\n",
                r.messages, r.rows.size(), a->out.c_str(), r.refusals.size(), r.stale);
    if (r.replies > 0) std::printf("%zu replies (<Sen>) ignored\n", r.replies);
    if (!r.rows.empty()) {
      std::printf("IPOC %llu .. %llu; cycle %llu ms%s; %zu gaps, %llu cycles lost\n",
                  static_cast<unsigned long long>(r.rows.front().ipoc),
                  static_cast<unsigned long long>(r.rows.back().ipoc),
                  static_cast<unsigned long long>(r.cycle_ipoc),
                  a->cycle_ms == 0 ? " (most frequent step)" : "", r.ipoc_gaps,
                  static_cast<unsigned long long>(r.cycles_lost));
    }
    std::size_t from_joints = 0;
    for (const io::RsiRow& row : r.rows) from_joints += row.pose_from_joints ? 1 : 0;
    if (r.rows.empty()) {
      std::printf("pose: none (no message decoded)\n");
    } else if (r.all_have_pose) {
      std::printf("pose of S in B: %zu rows from RIst, %zu from the robot's kinematics\n",
                  r.rows.size() - from_joints, from_joints);
    } else {
      std::printf(
          "pose: not written (%zu messages without RIst and no robot: give --rig with a robot)\n",
          r.without_rist);
    }
    if (r.pose_checks > 0) {
      std::printf("RIst against the kinematics (%zu rows): at most %.6f mm, %.6f deg apart\n",
                  r.pose_checks, r.max_check_m * 1e3, r.max_check_rad / proto::rsi::kRadPerDeg);
    }
    if (r.with_external > 0) {
      std::printf("%zu messages with external axes (EIPos)%s\n", r.with_external,
                  o.external_axes.empty() ? ": not written (give --external-axes)" : "");
    }
    if (r.skipped_elements > 0)
      std::printf("%zu other elements skipped (RSol, ASPos, Tech, DiL, Digout, …)\n",
                  r.skipped_elements);
    for (std::size_t k = 0; k < r.refusals_by_status.size(); ++k) {
      if (r.refusals_by_status[k] == 0) continue;
      std::printf("refused %s: %zu\n",
                  proto::rsi::to_string(static_cast<proto::rsi::ParseStatus>(k)),
                  r.refusals_by_status[k]);
    }
    if (a->verbose) {
      for (const io::RsiRefusal& f : r.refusals) {
        std::printf("%s:%zu:%zu: %s: %s\n", a->capture.c_str(), f.line, f.column,
                    proto::rsi::to_string(f.status), f.reason);
      }
    }
    std::printf("import it with this table in the mapping (proto/import_mapping.md):\n%s",
                io::rsi_mapping_snippet(r, a->out).c_str());
  });
}

}  // namespace zerog::cli
