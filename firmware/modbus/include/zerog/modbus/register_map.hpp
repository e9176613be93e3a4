#pragma once
// The Modbus register map of zerog-rt: ONE table (register_map.cpp) from which the server encodes
// and decodes every value and from which proto/modbus.md's table is generated
// (register_map_markdown(); tests/unit/modbus/doc_test.cpp fails when the two differ).
//
// Values are scaled integers: SI value = raw / raw_per_unit. 32-bit values take two registers,
// the high word first (at the lower address; mbpoll: -B). Addresses are protocol (0-based).
#include <cstdint>
#include <span>
#include <string>
#include <string_view>

#include "zerog/loop/cycle.hpp"
#include "zerog/modbus/target.hpp"

namespace zerog::modbus {

inline constexpr std::uint16_t kRegisterMapVersion = 2;

enum class Table : std::uint8_t { coil, discrete_input, input_register, holding_register };
const char* table_name(Table t);

enum class ValueType : std::uint8_t { bit, uint16, int16, uint32, int32 };
const char* value_type_name(ValueType t);
/// Registers (16-bit words) a value takes: 2 for uint32/int32, else 1 (bits: one bit).
constexpr int word_count(ValueType t) {
  return (t == ValueType::uint32 || t == ValueType::int32) ? 2 : 1;
}
/// The raw range a type can carry.
constexpr std::int64_t raw_min(ValueType t) {
  switch (t) {
    case ValueType::int16:
      return -32768;
    case ValueType::int32:
      return -2147483648LL;
    default:
      return 0;
  }
}
constexpr std::int64_t raw_max(ValueType t) {
  switch (t) {
    case ValueType::bit:
      return 1;
    case ValueType::uint16:
      return 65535;
    case ValueType::int16:
      return 32767;
    case ValueType::uint32:
      return 4294967295LL;
    case ValueType::int32:
      return 2147483647LL;
  }
  return 0;
}

/// What writing a coil does (proto/modbus.md, "Coils").
enum class CoilAction : std::uint8_t {
  none,
  zero_g,   ///< 1: enable_zero_g; 0: stop (if in zero_g)
  collect,  ///< 1: start_collection; 0: stop (if collecting)
  reset,    ///< 1: reset_fault; 0: nothing
};

/// Everything an input register or discrete input can show: the target's snapshot plus what the
/// server itself knows.
struct StatusInputs {
  SupervisorSnapshot target;
  loop::ProposalStatus proposal = loop::ProposalStatus::none;
  std::uint16_t clients_connected = 0;
  std::uint64_t requests = 0;
  std::uint64_t exceptions = 0;
  std::uint64_t writes_refused = 0;
  std::uint64_t clients_refused = 0;
};

struct RegisterDef {
  Table table;
  std::uint16_t address;  ///< protocol address (0-based); 32-bit values take address and +1
  std::string_view name;  ///< with unit and frame, e.g. com_x_sensor_m
  ValueType type;
  double raw_per_unit;    ///< SI value = raw / raw_per_unit (1 for plain numbers)
  std::string_view unit;  ///< SI unit of the value ("" for plain numbers and codes)
  double min, max;        ///< holding registers: accepted SI range, inclusive
  std::string_view description;
  /// Holding registers: read / write the value (SI) in the tunables.
  double (*get_tunable)(const loop::Tunables&) = nullptr;
  void (*set_tunable)(loop::Tunables&, double) = nullptr;
  /// Input registers, discrete inputs and coils (read): the value (SI, or 0/1).
  double (*get_status)(const StatusInputs&) = nullptr;
  CoilAction coil = CoilAction::none;

  int words() const { return word_count(type); }
  /// Raw bounds of a holding register (min/max scaled and rounded).
  std::int64_t raw_lo() const;
  std::int64_t raw_hi() const;
};

/// The whole map, sorted by (table, address).
std::span<const RegisterDef> registers();
/// The register that starts at `address` in `table`, or nullptr.
const RegisterDef* find_register(Table table, std::uint16_t address);
/// One past the highest address used in `table` (the readable extent).
std::uint16_t table_extent(Table table);

/// SI value → raw integer (rounded to nearest; saturated to the type's range; NaN → 0).
std::int64_t to_raw(const RegisterDef& r, double value);
/// Raw integer → SI value.
double from_raw(const RegisterDef& r, std::int64_t raw);
/// Raw integer → register words (32-bit: high word first). `words` has r.words() entries.
void put_words(ValueType t, std::int64_t raw, std::uint16_t* words);
/// Register words → raw integer (sign-extended for int16/int32).
std::int64_t get_words(ValueType t, const std::uint16_t* words);

/// Fill whole tables (index = protocol address; unused addresses are 0). Sizes: table_extent().
/// Real-time safe (no allocation), though only the server's thread calls them.
void fill_holding(const loop::Tunables& t, std::span<std::uint16_t> regs);
void fill_input(const StatusInputs& s, std::span<std::uint16_t> regs);
void fill_bits(Table table, const StatusInputs& s, std::span<std::uint8_t> bits);

/// The register map as markdown tables (proto/modbus.md between its markers).
std::string register_map_markdown();

}  // namespace zerog::modbus
