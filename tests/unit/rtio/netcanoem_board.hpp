#pragma once
// Test helpers around the one emulated ATI NETCANOEM board, zerog::emu::AtiBoard
// (host/emu/include/zerog/emu/ati_board.hpp): an independent computation of the wrench a sensor
// should report, and a transitional adapter for tests still written against the old test-only
// board state. Test code; header-only.
#include <array>
#include <cstddef>
#include <cstdint>

#include "zerog/emu/ati_board.hpp"
#include "zerog/proto/netcanoem.hpp"

namespace zerog::rtio::test {

namespace netcanoem = proto::netcanoem;

inline constexpr std::size_t kMaxBoardFrames = emu::AtiBoard::kMaxResponseFrames;

/// The wrench a board with `config` and `gauges` should produce, computed here without the
/// codec: w_i = scale_i · Σ_j float32(C[i][j]) · (g_j − bias_j) / counts_i (ATI 9610-05-1030).
inline std::array<double, 6> expected_wrench_si(const emu::AtiBoardConfig& config,
                                                const std::array<std::int16_t, 6>& gauges,
                                                const std::array<double, 6>& bias,
                                                double newton_per_force_unit,
                                                double newton_metre_per_torque_unit) {
  std::array<double, 6> w{};
  const bool device_counts =
      config.firmware.major > 3 || (config.firmware.major == 3 && config.firmware.minor >= 7);
  const double cpf = device_counts ? config.counts_per_force : 1'000'000.0;
  const double cpt = device_counts ? config.counts_per_torque : 1'000'000.0;
  for (int i = 0; i < 6; ++i) {
    double sum = 0;
    for (int j = 0; j < 6; ++j) {
      sum += static_cast<double>(static_cast<float>(config.matrix[i][j])) *
             (static_cast<double>(gauges[j]) - bias[j]);
    }
    w[i] = i < 3 ? sum / cpf * newton_per_force_unit : sum / cpt * newton_metre_per_torque_unit;
  }
  return w;
}

/// Transitional: the fields of the old test-only board that tests/unit/rtio/no_alloc_test.cpp
/// still sets, forwarded to an emu::AtiBoard by board_respond (no second implementation of the
/// protocol). New tests use emu::AtiBoard and emu::AtiBoardResponder directly.
struct BoardState {
  std::uint8_t base_id = emu::AtiBoardConfig{}.base_id;  ///< of the default board; fixed
  std::array<std::int16_t, 6> gauges{1200, -800, 2500, 640, -1800, 90};
  std::uint16_t status = 0;
  bool silent = false;
  std::array<proto::CanFrame, 4> before_sample{};
  std::size_t before_sample_count = 0;
  emu::AtiBoard board;
};

/// The frames `state.board` sends for `request`, after taking over the fields above.
inline std::size_t board_respond(BoardState& state, const proto::CanFrame& request,
                                 std::array<proto::CanFrame, kMaxBoardFrames>& out) {
  state.board.set_gauges(state.gauges);
  state.board.set_status_word(state.status);
  state.board.set_fault(state.silent ? emu::FtFault::silent : emu::FtFault::none);
  emu::AtiBoardQuirks quirks;
  quirks.before_sample = state.before_sample;
  quirks.before_sample_count = state.before_sample_count;
  state.board.set_quirks(quirks);
  return state.board.respond(request, out);
}

}  // namespace zerog::rtio::test
