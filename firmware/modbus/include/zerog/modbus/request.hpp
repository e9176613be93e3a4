#pragma once
// The server's decisions as pure functions over raw bytes (no sockets, no libmodbus), so they can
// be unit-tested and fuzzed: Modbus TCP framing (MBAP header) and, for one complete request, what
// to do — answer a read from the map, propose new tunables, request a command, or send an
// exception (proto/modbus.md, "Exceptions").
#include <cstddef>
#include <cstdint>
#include <span>

#include "zerog/loop/cycle.hpp"
#include "zerog/modbus/register_map.hpp"

namespace zerog::modbus {

inline constexpr std::size_t kMbapBytes = 7;      ///< transaction, protocol, length, unit id
inline constexpr std::size_t kMaxAduBytes = 260;  ///< MBAP + the largest PDU (253 bytes)

enum class FrameStatus : std::uint8_t {
  incomplete,  ///< more bytes needed
  complete,    ///< the first `length` bytes are one request
  invalid,     ///< not Modbus TCP (protocol id ≠ 0, length field out of 2..254): close
};
struct Frame {
  FrameStatus status = FrameStatus::incomplete;
  std::size_t length = 0;  ///< complete: bytes of the first request (MBAP + PDU)
  const char* why = "";    ///< invalid: what is wrong
};
/// Where the first request in `bytes` ends (Modbus Messaging on TCP/IP, §3.1.3).
Frame frame_request(std::span<const std::uint8_t> bytes) noexcept;

/// Modbus exception codes (Modbus Application Protocol v1.1b3, §7).
enum class ExceptionCode : std::uint8_t {
  none = 0,
  illegal_function = 1,
  illegal_data_address = 2,
  illegal_data_value = 3,
  server_device_failure = 4,
  acknowledge = 5,
  server_device_busy = 6,
};

enum class Action : std::uint8_t {
  read,            ///< answer from the map (refreshed from the snapshot / tunables)
  write_tunables,  ///< propose `tunables`, then answer (or an exception, by the outcome)
  command,         ///< request `command`, then answer (or an exception, by the outcome)
  write_noop,      ///< a coil write that asks for what already is: answer, nothing to do
  exception,       ///< answer with `exception`
};

struct Decision {
  Action action = Action::exception;
  std::uint8_t function = 0;
  ExceptionCode exception = ExceptionCode::none;
  const char* why = "";                   ///< exception: the reason (static text)
  const RegisterDef* reg = nullptr;       ///< the register concerned, if one is
  Table table = Table::holding_register;  ///< read: which table
  std::uint16_t address = 0, count = 0;   ///< as requested
  loop::Tunables tunables;                ///< write_tunables: current + the written values
  loop::Command command = loop::Command::stop;
};

/// What to do with one complete request `adu` (MBAP + PDU, as framed by frame_request) given the
/// tunables in use and the state. Checks in the specification's order: function (01), quantity
/// and byte counts (03), addresses (02: outside the map, a gap, a read-only table, half of a
/// 32-bit value), then values (03: out of a register's range). A multi-register write is all or
/// nothing: one bad register refuses it whole. Never throws; any byte string is safe.
Decision decide(std::span<const std::uint8_t> adu, const loop::Tunables& current,
                loop::State state) noexcept;

}  // namespace zerog::modbus
