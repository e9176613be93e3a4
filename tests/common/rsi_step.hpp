#pragma once
// One cycle for a controller message in the wire's KUKA units (mm, degrees), answered in them:
// for the tests and benchmarks that hold RSI messages. The cycle itself sees SI only
// (zerog/loop/cycle.hpp; docs/STYLE.md habit 13); this helper converts at the border with the
// RSI border's functions (zerog/proto/rsi_si.hpp), as zerog-rt's endpoint (firmware/rtio) does,
// so that zerog::loop needs no protocol type. Real-time safe like Cycle::step (no allocation).
#include <array>
#include <cstdint>

#include "zerog/loop/cycle.hpp"
#include "zerog/proto/rsi.hpp"
#include "zerog/proto/rsi_si.hpp"
#include "zerog/samples/robot_sample.hpp"

namespace zerog::test {

/// What goes back to the robot, in the wire's KUKA units. Always the IPOC of the message just
/// handled.
struct RsiReply {
  bool axis = false;             ///< true: AKorr (collection mode); false: RKorr
  proto::rsi::Correction rkorr;  ///< mm, degrees (zero unless zero-g)
  std::array<double, 6> akorr_deg{};
  std::uint64_t ipoc = 0;
};

/// Cycle::step for `message` (converted with proto::rsi::robot_sample_from_message), its SI
/// answer converted into `reply` (proto::rsi::kuka_units_from_correction).
inline void step_rsi(loop::Cycle& cycle, const proto::rsi::RobotMessage& message,
                     RsiReply& reply) noexcept {
  samples::RobotCorrection correction;
  cycle.step(proto::rsi::robot_sample_from_message(message), correction);
  reply.axis = correction.axis();
  reply.ipoc = correction.ipoc;
  proto::rsi::kuka_units_from_correction(correction, reply.rkorr, reply.akorr_deg);
}

}  // namespace zerog::test
