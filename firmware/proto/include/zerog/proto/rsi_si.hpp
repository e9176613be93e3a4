#pragma once
// The RSI border's unit conversions (proto/rsi.md, "Units at the border"): KUKA units on the wire
// (mm, degrees, A/B/C Euler angles about Z, Y', X'') ↔ the SI samples of
// zerog/samples/robot_sample.hpp (m, rad, rotation matrices). One function per direction and
// kind, shared by everyone who converts: zerog-rt's RSI endpoint (zerog::rtio), the robot
// emulator (host/emu), `zerog decode-rsi` (host/io) and the tests. Nothing else converts RSI
// units.
//
// Frames: positions and rotations are T (the TCP the controller reports; the F/T sensor frame
// on zerog's rig) in the base frame B; a correction's translation and rotation are in B too.
// A rotation R from A, B, C is Rz(A)·Ry(B)·Rx(C) (model::rotation_from_kuka_abc); back, B is in
// [−90°, 90°] and A, C in (−180°, 180°] (model::kuka_abc_from_rotation).
//
// Real-time safe: no allocation, no exceptions, no locks.
#include <array>

#include "zerog/proto/rsi.hpp"
#include "zerog/samples/robot_sample.hpp"

namespace zerog::proto::rsi {

/// Controller message (mm, degrees) → SI: joints in rad, RIst as p_base_tcp_m and R_base_tcp
/// (has_pose = has_actual_pose; identity and zero without RIst), IPOC and Delay as they are.
/// External axes (EIPos) are not part of the sample (their kind is the cell's configuration:
/// external_axis_to_si).
samples::RobotSample robot_sample_from_message(const RobotMessage& message);

/// SI → controller message (the controller's side: the emulator, tests). RIst only when
/// has_pose; no EIPos. The inverse of robot_sample_from_message up to rounding (and A, B, C
/// normalised to the ranges above).
RobotMessage robot_message_from_sample(const samples::RobotSample& sample);

/// Our SI correction → the reply's KUKA units: RKorr (mm, degrees) for Kind::cartesian, RKorr
/// of exact zeros for Kind::none, AKorr (degrees) for Kind::axes; the other one is absent
/// (has_* false, zero). IPOC as it is.
Reply reply_from_correction(const samples::RobotCorrection& correction);

/// reply_from_correction's RKorr and AKorr, written straight into the caller's fields (the
/// absent one zero): for an answer kept in another struct (the tests' test::RsiReply,
/// tests/common/rsi_step.hpp), with no Reply in between.
void kuka_units_from_correction(const samples::RobotCorrection& correction, Correction& rkorr,
                                std::array<double, 6>& akorr_deg);

/// The RKorr angles A, B, C of `correction` in rad (KUKA's Euler angles of R_correction, in the
/// ranges above) for Kind::cartesian; exact zeros otherwise. reply_from_correction's angles are
/// these in degrees. For telemetry, which carries them in rad.
std::array<double, 3> rkorr_abc_rad(const samples::RobotCorrection& correction);

/// A reply's KUKA units → SI (the controller's side: the emulator applies it; tests). RKorr
/// gives translation_m and R_correction, AKorr gives axes_rad (zero when absent); kind is axes
/// with AKorr, else cartesian with RKorr, else none. The inverse of reply_from_correction up to
/// rounding.
samples::RobotCorrection correction_from_reply(const Reply& reply);

}  // namespace zerog::proto::rsi
