#pragma once
// An emulated ATI NETCANOEM board for tests (unit tests on FakeCanBus, the VM test on vcan0):
// it answers requests with the codec's response encoders. Test code; header-only.
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>

#include "zerog/proto/netcanoem.hpp"

namespace zerog::rtio::test {

namespace netcanoem = proto::netcanoem;

inline constexpr std::size_t kMaxBoardFrames = 8;

/// What the board knows and how it misbehaves.
struct BoardState {
  std::uint8_t base_id = 0x20;
  netcanoem::FirmwareVersion firmware{3, 8, 1201};
  std::array<char, netcanoem::kSerialNumberLength> serial{'F', 'T', '4', '2', '0', '0', '7', 'A'};
  /// Rows Fx..Tz, columns SG0..SG5; multiples of 1/4 below 2^20, so exact in float32.
  std::array<std::array<double, 6>, 6> matrix{{
      {1520.25, -12.5, 33.75, -1498.0, 8.25, 1.5},
      {-20.0, 1730.5, -5.25, 14.0, -1744.75, 6.0},
      {3002.5, 2998.75, 3010.0, 2990.25, 3005.5, 2995.0},
      {0.75, -8.5, 25.25, 2.0, -24.5, 5.75},
      {-28.0, 1.25, 13.5, -23.75, 14.25, 22.0},
      {-4.5, 18.0, -3.25, 19.5, -2.75, 17.25},
  }};
  std::uint32_t counts_per_force = 1'000'000;  ///< reported from firmware 3.7 on
  std::uint32_t counts_per_torque = 1'000'000;
  std::uint8_t force_unit = 2;   ///< N
  std::uint8_t torque_unit = 3;  ///< N·m
  std::array<std::int16_t, 6> gauges{1200, -800, 2500, 640, -1800, 90};
  std::uint16_t status = 0;

  bool silent = false;              ///< answer nothing
  int ignore_requests = 0;          ///< ignore this many requests first (tests retries)
  bool wrong_echo = false;          ///< echo another calibration index
  bool no_sample_response = false;  ///< send only before_sample for a sample request
  /// Sent before each sample response (strays, wrong lengths, error frames).
  std::array<proto::CanFrame, 4> before_sample{};
  std::size_t before_sample_count = 0;
};

/// The frames the board sends for `request` (none for frames that are not its requests).
/// Updates ignore_requests.
inline std::size_t board_respond(BoardState& board, const proto::CanFrame& request,
                                 std::array<proto::CanFrame, kMaxBoardFrames>& out) {
  if ((request.id & ~proto::kCanStandardIdMask) != 0 ||
      netcanoem::base_id_of(request.id) != board.base_id || board.silent) {
    return 0;
  }
  const auto opcode = static_cast<netcanoem::Opcode>(netcanoem::opcode_of(request.id));
  const bool empty = request.len == 0;
  const bool one_byte = request.len == 1;
  bool is_request = false;
  switch (opcode) {
    case netcanoem::Opcode::sample_a:
    case netcanoem::Opcode::serial_number:
    case netcanoem::Opcode::counts:
    case netcanoem::Opcode::units:
    case netcanoem::Opcode::firmware_version:
      is_request = empty;
      break;
    case netcanoem::Opcode::matrix_sg01:
    case netcanoem::Opcode::active_calibration:
      is_request = one_byte;
      break;
    default:
      break;
  }
  if (!is_request) return 0;
  if (board.ignore_requests > 0) {
    --board.ignore_requests;
    return 0;
  }
  std::size_t n = 0;
  auto put = [&](const std::optional<proto::CanFrame>& frame) {
    if (frame && n < out.size()) out[n++] = *frame;
  };
  const std::uint8_t base = board.base_id;
  switch (opcode) {
    case netcanoem::Opcode::sample_a: {
      for (std::size_t i = 0; i < board.before_sample_count; ++i) out[n++] = board.before_sample[i];
      if (board.no_sample_response) break;
      if (auto frames = netcanoem::encode_sample(base, board.gauges, board.status)) {
        put((*frames)[0]);
        put((*frames)[1]);
      }
      break;
    }
    case netcanoem::Opcode::matrix_sg01:
      if (request.data[0] < 6) {
        if (auto frames = netcanoem::encode_matrix_row(base, board.matrix[request.data[0]])) {
          for (const proto::CanFrame& f : *frames) put(f);
        }
      }
      break;
    case netcanoem::Opcode::serial_number:
      put(netcanoem::encode_serial_number(base, board.serial));
      break;
    case netcanoem::Opcode::active_calibration:
      put(netcanoem::encode_active_calibration(
          base, static_cast<std::uint8_t>((request.data[0] + (board.wrong_echo ? 1 : 0)) & 0xF)));
      break;
    case netcanoem::Opcode::counts:
      if (board.firmware.has_counts()) {  // older firmware does not know opcode 0x7
        put(netcanoem::encode_counts(base, board.counts_per_force, board.counts_per_torque));
      }
      break;
    case netcanoem::Opcode::units:
      put(netcanoem::encode_units(base, board.force_unit, board.torque_unit));
      break;
    case netcanoem::Opcode::firmware_version:
      put(netcanoem::encode_firmware_version(base, board.firmware));
      break;
    default:
      break;
  }
  return n;
}

/// The wrench the board's state should produce, computed here without the codec:
/// w_i = scale_i · Σ_j C[i][j] · float32 · (g_j − bias_j) / counts_i (ATI 9610-05-1030).
inline std::array<double, 6> expected_wrench_si(const BoardState& board,
                                                const std::array<double, 6>& bias,
                                                double newton_per_force_unit,
                                                double newton_metre_per_torque_unit) {
  std::array<double, 6> w{};
  const bool device_counts =
      board.firmware.major > 3 || (board.firmware.major == 3 && board.firmware.minor >= 7);
  const double cpf = device_counts ? board.counts_per_force : 1'000'000.0;
  const double cpt = device_counts ? board.counts_per_torque : 1'000'000.0;
  for (int i = 0; i < 6; ++i) {
    double sum = 0;
    for (int j = 0; j < 6; ++j) {
      sum += static_cast<double>(static_cast<float>(board.matrix[i][j])) *
             (static_cast<double>(board.gauges[j]) - bias[j]);
    }
    w[i] = i < 3 ? sum / cpf * newton_per_force_unit : sum / cpt * newton_metre_per_torque_unit;
  }
  return w;
}

}  // namespace zerog::rtio::test
