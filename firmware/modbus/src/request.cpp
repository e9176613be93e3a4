#include "zerog/modbus/request.hpp"

namespace zerog::modbus {
namespace {

constexpr std::uint8_t kReadCoils = 0x01;
constexpr std::uint8_t kReadDiscreteInputs = 0x02;
constexpr std::uint8_t kReadHoldingRegisters = 0x03;
constexpr std::uint8_t kReadInputRegisters = 0x04;
constexpr std::uint8_t kWriteSingleCoil = 0x05;
constexpr std::uint8_t kWriteSingleRegister = 0x06;
constexpr std::uint8_t kWriteMultipleCoils = 0x0F;
constexpr std::uint8_t kWriteMultipleRegisters = 0x10;

std::uint16_t be16(const std::uint8_t* p) {
  return static_cast<std::uint16_t>((static_cast<unsigned>(p[0]) << 8) | p[1]);
}

Decision refuse(Decision d, ExceptionCode code, const char* why, const RegisterDef* reg = nullptr) {
  d.action = Action::exception;
  d.exception = code;
  d.why = why;
  d.reg = reg;
  return d;
}

Decision decide_coil(Decision d, const RegisterDef& r, bool on, loop::State state) {
  d.reg = &r;
  const auto command = [&d](loop::Command c) {
    d.action = Action::command;
    d.command = c;
    return d;
  };
  const auto noop = [&d] {
    d.action = Action::write_noop;
    return d;
  };
  switch (r.coil) {
    case CoilAction::zero_g:
      if (on) return state == loop::State::zero_g ? noop() : command(loop::Command::enable_zero_g);
      return state == loop::State::zero_g ? command(loop::Command::stop) : noop();
    case CoilAction::collect:
      if (on) {
        return state == loop::State::collecting ? noop() : command(loop::Command::start_collection);
      }
      return state == loop::State::collecting ? command(loop::Command::stop) : noop();
    case CoilAction::reset:
      return on && state == loop::State::fault ? command(loop::Command::reset_fault) : noop();
    case CoilAction::none:
      break;
  }
  return refuse(d, ExceptionCode::illegal_data_address, "coil has no action", &r);
}

Decision decide_read(Decision d, Table table, std::span<const std::uint8_t> data) {
  if (data.size() != 4) return refuse(d, ExceptionCode::illegal_data_value, "read needs 4 bytes");
  d.table = table;
  d.address = be16(&data[0]);
  d.count = be16(&data[2]);
  const bool bits = table == Table::coil || table == Table::discrete_input;
  const unsigned max_count = bits ? 2000u : 125u;
  if (d.count < 1 || d.count > max_count)
    return refuse(d, ExceptionCode::illegal_data_value, "quantity out of 1..2000 bits/125 words");
  if (static_cast<unsigned>(d.address) + d.count > table_extent(table))
    return refuse(d, ExceptionCode::illegal_data_address, "read beyond the map");
  d.action = Action::read;
  return d;
}

Decision decide_registers(Decision d, std::span<const std::uint16_t> words,
                          const loop::Tunables& current) {
  const unsigned end = static_cast<unsigned>(d.address) + d.count;
  if (end > table_extent(Table::holding_register))
    return refuse(d, ExceptionCode::illegal_data_address, "write beyond the map");
  // Addresses first: every word must belong to a register written whole.
  for (unsigned a = d.address; a < end;) {
    const RegisterDef* r = find_register(Table::holding_register, static_cast<std::uint16_t>(a));
    if (r == nullptr) {
      return refuse(d, ExceptionCode::illegal_data_address,
                    "not the first word of a holding register (a gap, or the low word of a "
                    "32-bit value)");
    }
    if (a + static_cast<unsigned>(r->words()) > end) {
      return refuse(d, ExceptionCode::illegal_data_address,
                    "a 32-bit register must be written whole (both words, FC 16)", r);
    }
    a += static_cast<unsigned>(r->words());
  }
  // Then values: all in range, or nothing is written.
  d.tunables = current;
  for (unsigned a = d.address; a < end;) {
    const RegisterDef* r = find_register(Table::holding_register, static_cast<std::uint16_t>(a));
    const std::int64_t raw = get_words(r->type, &words[a - d.address]);
    if (raw < r->raw_lo() || raw > r->raw_hi())
      return refuse(d, ExceptionCode::illegal_data_value, "value out of the register's range", r);
    r->set_tunable(d.tunables, from_raw(*r, raw));
    a += static_cast<unsigned>(r->words());
  }
  d.reg = find_register(Table::holding_register, d.address);
  d.action = Action::write_tunables;
  return d;
}

}  // namespace

Frame frame_request(std::span<const std::uint8_t> bytes) noexcept {
  Frame f;
  if (bytes.size() >= 4 && be16(&bytes[2]) != 0) {
    f.status = FrameStatus::invalid;
    f.why = "MBAP protocol identifier is not 0 (not Modbus TCP)";
    return f;
  }
  if (bytes.size() < 6) return f;
  const std::size_t length = be16(&bytes[4]);  // unit id + PDU
  if (length < 2 || length > kMaxAduBytes - 6) {
    f.status = FrameStatus::invalid;
    f.why = "MBAP length out of 2..254";
    return f;
  }
  if (bytes.size() < 6 + length) return f;
  f.status = FrameStatus::complete;
  f.length = 6 + length;
  return f;
}

Decision decide(std::span<const std::uint8_t> adu, const loop::Tunables& current,
                loop::State state) noexcept {
  Decision d;
  if (adu.size() <= kMbapBytes) {
    return refuse(d, ExceptionCode::illegal_data_value, "request without a function code");
  }
  d.function = adu[kMbapBytes];
  const std::span<const std::uint8_t> data = adu.subspan(kMbapBytes + 1);
  switch (d.function) {
    case kReadCoils:
      return decide_read(d, Table::coil, data);
    case kReadDiscreteInputs:
      return decide_read(d, Table::discrete_input, data);
    case kReadHoldingRegisters:
      return decide_read(d, Table::holding_register, data);
    case kReadInputRegisters:
      return decide_read(d, Table::input_register, data);
    case kWriteSingleCoil: {
      if (data.size() != 4) return refuse(d, ExceptionCode::illegal_data_value, "needs 4 bytes");
      d.address = be16(&data[0]);
      d.count = 1;
      const std::uint16_t value = be16(&data[2]);
      if (value != 0xFF00 && value != 0x0000)
        return refuse(d, ExceptionCode::illegal_data_value, "coil value must be 0xFF00 or 0");
      const RegisterDef* r = find_register(Table::coil, d.address);
      if (r == nullptr) return refuse(d, ExceptionCode::illegal_data_address, "no such coil");
      return decide_coil(d, *r, value == 0xFF00, state);
    }
    case kWriteMultipleCoils: {
      if (data.size() < 5) return refuse(d, ExceptionCode::illegal_data_value, "too short");
      d.address = be16(&data[0]);
      d.count = be16(&data[2]);
      const std::size_t byte_count = data[4];
      if (d.count < 1 || d.count > 1968 || byte_count != (d.count + 7u) / 8u ||
          data.size() != 5 + byte_count)
        return refuse(d, ExceptionCode::illegal_data_value, "quantity or byte count wrong");
      if (static_cast<unsigned>(d.address) + d.count > table_extent(Table::coil))
        return refuse(d, ExceptionCode::illegal_data_address, "write beyond the coils");
      if (d.count != 1)
        return refuse(d, ExceptionCode::illegal_data_value, "one coil per write (one command)");
      const RegisterDef* r = find_register(Table::coil, d.address);
      if (r == nullptr) return refuse(d, ExceptionCode::illegal_data_address, "no such coil");
      return decide_coil(d, *r, (data[5] & 1u) != 0, state);
    }
    case kWriteSingleRegister: {
      if (data.size() != 4) return refuse(d, ExceptionCode::illegal_data_value, "needs 4 bytes");
      d.address = be16(&data[0]);
      d.count = 1;
      const std::uint16_t word = be16(&data[2]);
      return decide_registers(d, std::span<const std::uint16_t>(&word, 1), current);
    }
    case kWriteMultipleRegisters: {
      if (data.size() < 5) return refuse(d, ExceptionCode::illegal_data_value, "too short");
      d.address = be16(&data[0]);
      d.count = be16(&data[2]);
      const std::size_t byte_count = data[4];
      if (d.count < 1 || d.count > 123 || byte_count != 2u * d.count ||
          data.size() != 5 + byte_count)
        return refuse(d, ExceptionCode::illegal_data_value, "quantity or byte count wrong");
      std::uint16_t words[123];
      for (std::size_t i = 0; i < d.count; ++i) words[i] = be16(&data[5 + 2 * i]);
      return decide_registers(d, std::span<const std::uint16_t>(words, d.count), current);
    }
    default:
      break;
  }
  return refuse(d, ExceptionCode::illegal_function, "function code not supported");
}

}  // namespace zerog::modbus
