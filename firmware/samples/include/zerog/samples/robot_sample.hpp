#pragma once
// The robot's side of the cycle in SI units (proto/rsi.md, "Units at the border"): what the RSI
// endpoint (zerog::rtio) hands the cycle for each controller message, and the correction the
// cycle hands back. The KUKA units of the wire (mm, degrees, A/B/C Euler angles) are converted
// only at the border, by zerog/proto/rsi_si.hpp, in both directions. Plain values, fixed size,
// trivially copyable, no I/O.
//
// Frames: B is the robot's base frame, T the frame the controller reports as its TCP (<RIst>);
// on zerog's rig T is the F/T sensor frame S (proto/frames.md).
#include <array>
#include <cstdint>

namespace zerog::samples {

/// A row-major 3×3 rotation matrix (R[3 * row + col]), as model::FeatureSignals keeps it.
using Rotation = std::array<double, 9>;
inline constexpr Rotation kIdentityRotation{1, 0, 0, 0, 1, 0, 0, 0, 1};

/// One controller message in SI units. Fixed size, trivially copyable.
struct RobotSample {
  std::uint64_t ipoc = 0;   ///< the controller's cycle stamp (to echo in the reply), unchanged
  bool has_delay = false;   ///< the message had <Delay>
  std::uint64_t delay = 0;  ///< late packets counted by the controller (<Delay D>), unchanged
  std::array<double, 6> joints_rad{};  ///< A1..A6 (<AIPos>), rad
  /// <RIst> was present: the pose below is valid. Many RSI configurations send joints only;
  /// the pose then comes from the robot's forward kinematics (zerog::robot).
  bool has_pose = true;
  std::array<double, 3> p_base_tcp_m{};     ///< T's origin in B, m
  Rotation R_base_tcp = kIdentityRotation;  ///< T's axes in B (KUKA A, B, C: Rz(A)·Ry(B)·Rx(C))
};

/// The cycle's answer to one message in SI units. Fixed size, trivially copyable.
/// RSI carries a correction (RKorr in mm and degrees, AKorr in degrees) with this many digits
/// after the point: 0.1 µm and 1e-4° (proto::rsi::kReplyDecimals is this; the motion
/// estimator's servo model rounds to it, loop::as_sent_over_rsi).
inline constexpr int kRsiCorrectionDecimals = 4;

struct RobotCorrection {
  /// What the reply carries: none (an <RKorr> of zeros: answered, nothing to correct), a
  /// Cartesian correction (<RKorr> from translation_m and R_correction) or an axis correction
  /// (<AKorr> from axes_rad, zerog-rt's collection mode).
  enum class Kind : std::uint8_t { none, cartesian, axes };
  std::uint64_t ipoc = 0;  ///< the IPOC of the message answered
  Kind kind = Kind::none;
  std::array<double, 3> translation_m{};  ///< <RKorr> X, Y, Z: in B, m
  /// <RKorr> A, B, C: the rotation to apply this cycle (identity: none), in B.
  Rotation R_correction = kIdentityRotation;
  std::array<double, 6> axes_rad{};  ///< <AKorr> A1..A6, rad
  bool axis() const { return kind == Kind::axes; }
};

}  // namespace zerog::samples
