// The server's decisions without sockets: framing, every exception path, all-or-nothing writes,
// scaling and the 32-bit word order (proto/modbus.md).
#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <vector>

#include "loop_fixtures.hpp"
#include "zerog/modbus/register_map.hpp"
#include "zerog/modbus/request.hpp"

namespace zerog::modbus {
namespace {

using Bytes = std::vector<std::uint8_t>;

Bytes adu(std::uint8_t function, const Bytes& data) {
  const std::size_t length = 2 + data.size();
  Bytes b = {0x12,
             0x34,
             0x00,
             0x00,
             static_cast<std::uint8_t>(length >> 8),
             static_cast<std::uint8_t>(length & 0xFF),
             0x01,
             function};
  b.insert(b.end(), data.begin(), data.end());
  return b;
}
void push16(Bytes& b, unsigned v) {
  b.push_back(static_cast<std::uint8_t>(v >> 8));
  b.push_back(static_cast<std::uint8_t>(v & 0xFF));
}
Bytes read(std::uint8_t function, unsigned address, unsigned count) {
  Bytes d;
  push16(d, address);
  push16(d, count);
  return adu(function, d);
}
Bytes write_registers(unsigned address, const std::vector<std::uint16_t>& words) {
  Bytes d;
  push16(d, address);
  push16(d, static_cast<unsigned>(words.size()));
  d.push_back(static_cast<std::uint8_t>(2 * words.size()));
  for (std::uint16_t w : words) push16(d, w);
  return adu(0x10, d);
}
Bytes write_coil(unsigned address, unsigned value) {
  Bytes d;
  push16(d, address);
  push16(d, value);
  return adu(0x05, d);
}
std::vector<std::uint16_t> int32_words(std::int64_t raw) {
  std::uint16_t w[2];
  put_words(ValueType::int32, raw, w);
  return {w[0], w[1]};
}

loop::Tunables current() {
  const loop::CycleConfig c = loop::test::test_cycle_config();
  return {c.body, c.limits, c.p_sensor_com_m};
}

Decision run(const Bytes& b, loop::State state = loop::State::idle) {
  return decide(b, current(), state);
}

TEST(ModbusFrame, FindsTheEndOfARequestAndRejectsWhatIsNotModbusTcp) {
  const Bytes r = read(0x04, 0, 2);
  for (std::size_t n = 0; n < r.size(); ++n) {
    EXPECT_EQ(frame_request({r.data(), n}).status, FrameStatus::incomplete) << n;
  }
  Frame f = frame_request(r);
  EXPECT_EQ(f.status, FrameStatus::complete);
  EXPECT_EQ(f.length, r.size());
  Bytes two = r;
  two.insert(two.end(), r.begin(), r.end());  // pipelined: the first one only
  EXPECT_EQ(frame_request(two).length, r.size());

  Bytes bad = r;
  bad[2] = 0x01;  // protocol identifier
  EXPECT_EQ(frame_request(bad).status, FrameStatus::invalid);
  bad = r;
  bad[4] = 0x01;  // length 256+: beyond a PDU
  EXPECT_EQ(frame_request(bad).status, FrameStatus::invalid);
  bad = r;
  bad[5] = 1;  // length 1: no function code
  EXPECT_EQ(frame_request(bad).status, FrameStatus::invalid);
}

TEST(ModbusDecide, ReadsWithinEachTableAreAnsweredFromTheMap) {
  const struct {
    std::uint8_t function;
    Table table;
  } cases[] = {{0x01, Table::coil},
               {0x02, Table::discrete_input},
               {0x03, Table::holding_register},
               {0x04, Table::input_register}};
  for (const auto& c : cases) {
    const std::uint16_t n = table_extent(c.table);
    ASSERT_GT(n, 0);
    Decision d = run(read(c.function, 0, n));
    EXPECT_EQ(d.action, Action::read) << table_name(c.table);
    EXPECT_EQ(d.table, c.table);
    d = run(read(c.function, 1, n));  // one past the end
    EXPECT_EQ(d.action, Action::exception);
    EXPECT_EQ(d.exception, ExceptionCode::illegal_data_address) << table_name(c.table);
    d = run(read(c.function, 0, 0));  // quantity 0
    EXPECT_EQ(d.exception, ExceptionCode::illegal_data_value);
  }
  EXPECT_EQ(run(read(0x03, 0, 126)).exception, ExceptionCode::illegal_data_value);
  EXPECT_EQ(run(read(0x01, 0, 2001)).exception, ExceptionCode::illegal_data_value);
  Bytes short_read = read(0x04, 0, 1);
  short_read.pop_back();
  short_read[5] = static_cast<std::uint8_t>(short_read[5] - 1);
  EXPECT_EQ(run(short_read).exception, ExceptionCode::illegal_data_value);
}

TEST(ModbusDecide, UnsupportedFunctionsAreIllegalFunction) {
  for (int f : {0x07, 0x08, 0x11, 0x16, 0x17, 0x2B, 0x00, 0x80, 0xFF}) {
    const Decision d = run(adu(static_cast<std::uint8_t>(f), {0, 0, 0, 1}));
    EXPECT_EQ(d.action, Action::exception);
    EXPECT_EQ(d.exception, ExceptionCode::illegal_function) << int(f);
  }
}

TEST(ModbusDecide, WritingTheMassProposesCurrentTunablesWithOnlyTheMassChanged) {
  const RegisterDef* mass = find_register(Table::holding_register, 0);
  ASSERT_NE(mass, nullptr);
  ASSERT_EQ(mass->name, "mass_kg");
  const Decision d = run(write_registers(0, int32_words(80'250)));  // 80.25 kg
  ASSERT_EQ(d.action, Action::write_tunables) << d.why;
  EXPECT_EQ(d.tunables.body.mass_kg, 80.25);
  const loop::Tunables before = current();
  EXPECT_EQ(d.tunables.body.inertia_body_kgm2, before.body.inertia_body_kgm2);
  EXPECT_EQ(d.tunables.p_sensor_com_m, before.p_sensor_com_m);
  EXPECT_EQ(d.tunables.limits.max_speed_mps, before.limits.max_speed_mps);
}

TEST(ModbusDecide, OutOfRangeValuesAreIllegalDataValueNamingTheRegister) {
  // 0.5 kg and 3000 kg: outside 1..2000 kg.
  for (std::int64_t raw : {500, 3'000'000, -1}) {
    const Decision d = run(write_registers(0, int32_words(raw)));
    EXPECT_EQ(d.exception, ExceptionCode::illegal_data_value) << raw;
    ASSERT_NE(d.reg, nullptr);
    EXPECT_EQ(d.reg->name, "mass_kg");
  }
  // Every holding register: its bounds are accepted, one raw unit beyond them is not.
  for (const RegisterDef& r : registers()) {
    if (r.table != Table::holding_register) continue;
    EXPECT_EQ(run(write_registers(r.address, int32_words(r.raw_lo()))).action,
              Action::write_tunables)
        << r.name;
    EXPECT_EQ(run(write_registers(r.address, int32_words(r.raw_hi()))).action,
              Action::write_tunables)
        << r.name;
    EXPECT_EQ(run(write_registers(r.address, int32_words(r.raw_lo() - 1))).exception,
              ExceptionCode::illegal_data_value)
        << r.name;
    EXPECT_EQ(run(write_registers(r.address, int32_words(r.raw_hi() + 1))).exception,
              ExceptionCode::illegal_data_value)
        << r.name;
  }
}

TEST(ModbusDecide, AMultiRegisterWriteIsAllOrNothing) {
  // mass (ok), Ixx (ok), Iyy (0: out of range) → refused whole, naming Iyy.
  std::vector<std::uint16_t> words = int32_words(90'000);
  for (std::int64_t raw : {70'000, 0}) {
    const auto w = int32_words(raw);
    words.insert(words.end(), w.begin(), w.end());
  }
  const Decision d = run(write_registers(0, words));
  EXPECT_EQ(d.action, Action::exception);
  EXPECT_EQ(d.exception, ExceptionCode::illegal_data_value);
  ASSERT_NE(d.reg, nullptr);
  EXPECT_EQ(d.reg->name, "inertia_yy_kgm2");
  // The same block with a valid Iyy: every value lands.
  words[5] = 60'000 & 0xFFFF;
  words[4] = 0;
  const Decision ok = run(write_registers(0, words));
  ASSERT_EQ(ok.action, Action::write_tunables) << ok.why;
  EXPECT_EQ(ok.tunables.body.mass_kg, 90.0);
  EXPECT_EQ(ok.tunables.body.inertia_body_kgm2(0, 0), 7.0);
  EXPECT_EQ(ok.tunables.body.inertia_body_kgm2(1, 1), 6.0);
}

TEST(ModbusDecide, HalfOfA32BitRegisterIsAnIllegalAddress) {
  // The low word alone, the high word alone (FC 16 and FC 6), a block ending mid-value.
  EXPECT_EQ(run(write_registers(1, {0x0001})).exception, ExceptionCode::illegal_data_address);
  EXPECT_EQ(run(write_registers(0, {0x0001})).exception, ExceptionCode::illegal_data_address);
  EXPECT_EQ(run(write_registers(0, {0, 1000, 0})).exception, ExceptionCode::illegal_data_address);
  Bytes fc6;
  push16(fc6, 0);
  push16(fc6, 100);
  EXPECT_EQ(run(adu(0x06, fc6)).exception, ExceptionCode::illegal_data_address);
  // Beyond the map.
  const std::uint16_t end = table_extent(Table::holding_register);
  EXPECT_EQ(run(write_registers(end, int32_words(1))).exception,
            ExceptionCode::illegal_data_address);
}

TEST(ModbusDecide, WrongByteCountsAreIllegalDataValue) {
  Bytes b = write_registers(0, int32_words(80'000));
  b[12] = 3;  // byte count ≠ 2 × quantity
  EXPECT_EQ(run(b).exception, ExceptionCode::illegal_data_value);
  Bytes d;
  push16(d, 0);
  push16(d, 124);  // quantity above 123
  d.push_back(248);
  d.resize(d.size() + 248);
  EXPECT_EQ(run(adu(0x10, d)).exception, ExceptionCode::illegal_data_value);
}

TEST(ModbusDecide, CoilsAreCommandsThatRespectTheState) {
  using loop::Command;
  using loop::State;
  Decision d = run(write_coil(0, 0xFF00), State::idle);
  ASSERT_EQ(d.action, Action::command);
  EXPECT_EQ(d.command, Command::enable_zero_g);
  EXPECT_EQ(run(write_coil(0, 0xFF00), State::zero_g).action, Action::write_noop);
  d = run(write_coil(0, 0x0000), State::zero_g);
  ASSERT_EQ(d.action, Action::command);
  EXPECT_EQ(d.command, Command::stop);
  EXPECT_EQ(run(write_coil(0, 0x0000), State::idle).action, Action::write_noop);
  d = run(write_coil(1, 0xFF00), State::idle);
  ASSERT_EQ(d.action, Action::command);
  EXPECT_EQ(d.command, Command::start_collection);
  d = run(write_coil(1, 0x0000), State::collecting);
  EXPECT_EQ(d.command, Command::stop);
  d = run(write_coil(2, 0xFF00), State::fault);
  ASSERT_EQ(d.action, Action::command);
  EXPECT_EQ(d.command, Command::reset_fault);
  EXPECT_EQ(run(write_coil(2, 0xFF00), State::idle).action, Action::write_noop);
  // Bad coil value, no such coil, several coils at once.
  EXPECT_EQ(run(write_coil(0, 0x1234)).exception, ExceptionCode::illegal_data_value);
  EXPECT_EQ(run(write_coil(3, 0xFF00)).exception, ExceptionCode::illegal_data_address);
  Bytes one;
  push16(one, 0);
  push16(one, 1);
  one.push_back(1);
  one.push_back(1);
  d = run(adu(0x0F, one));
  EXPECT_EQ(d.command, Command::enable_zero_g);
  Bytes two;
  push16(two, 0);
  push16(two, 2);
  two.push_back(1);
  two.push_back(3);
  EXPECT_EQ(run(adu(0x0F, two)).exception, ExceptionCode::illegal_data_value);
}

TEST(ModbusRegisters, WordOrderIsHighWordFirst) {
  std::uint16_t w[2];
  put_words(ValueType::int32, -2, w);
  EXPECT_EQ(w[0], 0xFFFF);
  EXPECT_EQ(w[1], 0xFFFE);
  EXPECT_EQ(get_words(ValueType::int32, w), -2);
  put_words(ValueType::uint32, 0x12345678, w);
  EXPECT_EQ(w[0], 0x1234);
  EXPECT_EQ(w[1], 0x5678);
  EXPECT_EQ(get_words(ValueType::uint32, w), 0x12345678);
  put_words(ValueType::int32, 100'000, w);  // 100 kg in the mass register
  EXPECT_EQ(w[0], 0x0001);
  EXPECT_EQ(w[1], 0x86A0);
  put_words(ValueType::int16, -5, w);
  EXPECT_EQ(get_words(ValueType::int16, w), -5);
}

TEST(ModbusRegisters, ScalingRoundTripsAndRangesFitTheirTypes) {
  for (const RegisterDef& r : registers()) {
    if (r.table != Table::holding_register) continue;
    EXPECT_LT(r.raw_lo(), r.raw_hi()) << r.name;
    EXPECT_GE(r.raw_lo(), raw_min(r.type)) << r.name;
    EXPECT_LE(r.raw_hi(), raw_max(r.type)) << r.name;
    for (std::int64_t raw : {r.raw_lo(), r.raw_hi(), (r.raw_lo() + r.raw_hi()) / 2 + 1}) {
      EXPECT_EQ(to_raw(r, from_raw(r, raw)), raw) << r.name;
    }
    EXPECT_NE(r.get_tunable, nullptr);
    EXPECT_NE(r.set_tunable, nullptr);
  }
  // The resolutions the brief asks for: mass ≤ 0.01 kg, lengths ≤ 0.1 mm, inertia ≤ 0.001.
  for (const RegisterDef& r : registers()) {
    if (r.table != Table::holding_register) continue;
    if (r.unit == "kg") {
      EXPECT_LE(1.0 / r.raw_per_unit, 0.01) << r.name;
    }
    if (r.unit == "m") {
      EXPECT_LE(1.0 / r.raw_per_unit, 1e-4) << r.name;
    }
    if (r.unit == "kg·m²") {
      EXPECT_LE(1.0 / r.raw_per_unit, 1e-3) << r.name;
    }
  }
  // Saturation and NaN for status values.
  const RegisterDef* fx = find_register(Table::input_register, 10);
  ASSERT_NE(fx, nullptr);
  EXPECT_EQ(to_raw(*fx, 1e12), raw_max(ValueType::int32));
  EXPECT_EQ(to_raw(*fx, -1e12), raw_min(ValueType::int32));
  EXPECT_EQ(to_raw(*fx, std::nan("")), 0);
  EXPECT_EQ(to_raw(*fx, -12.3456), -12346);
}

TEST(ModbusRegisters, TheWholeHoldingTableReadBackAndWrittenGivesTheSameTunables) {
  std::vector<std::uint16_t> regs(table_extent(Table::holding_register));
  const loop::Tunables t = current();
  fill_holding(t, regs);
  const Decision d = run(write_registers(0, regs));
  ASSERT_EQ(d.action, Action::write_tunables) << d.why << " " << (d.reg ? d.reg->name : "");
  EXPECT_NEAR(d.tunables.body.mass_kg, t.body.mass_kg, 1e-3);
  EXPECT_TRUE(d.tunables.body.inertia_body_kgm2.isApprox(t.body.inertia_body_kgm2, 1e-4));
  EXPECT_TRUE(d.tunables.p_sensor_com_m.isApprox(t.p_sensor_com_m, 1e-5));
  EXPECT_EQ(d.tunables.limits.contact_confirm_cycles, t.limits.contact_confirm_cycles);
  EXPECT_NEAR(d.tunables.limits.max_speed_mps, t.limits.max_speed_mps, 1e-5);
  EXPECT_TRUE(d.tunables.limits.workspace_min_m.isApprox(t.limits.workspace_min_m, 1e-5));
  EXPECT_TRUE(d.tunables.limits.workspace_max_m.isApprox(t.limits.workspace_max_m, 1e-5));
  EXPECT_TRUE(loop::check_tunables(d.tunables).ok()) << loop::check_tunables(d.tunables).message;
}

TEST(ModbusRegisters, InputRegistersShowTheSnapshot) {
  StatusInputs in;
  in.target.state = loop::State::zero_g;
  in.target.fault = loop::Fault::imu_stale;
  in.target.cycle = 0x1'0000'0005ULL;  // wraps modulo 2^32
  in.target.contact_sensor = {1.5, -2.25, 0.0, 0.125, 0.0, -0.0001};
  in.target.compute_last_s = 8.5e-6;
  in.target.model_crc32 = 0xDEADBEEF;
  in.target.pose_disagreements = 0x1'0000'0007ULL;  // wraps modulo 2^32
  in.target.poses_from_joints = 11;
  in.target.poses_missing = 13;
  in.proposal = loop::ProposalStatus::refused_state;
  std::vector<std::uint16_t> regs(table_extent(Table::input_register));
  fill_input(in, regs);
  EXPECT_EQ(regs[0], kRegisterMapVersion);
  EXPECT_EQ(regs[1], 2);
  EXPECT_EQ(regs[2], 4);
  EXPECT_EQ(regs[4], 3);
  EXPECT_EQ(get_words(ValueType::uint32, &regs[6]), 5);
  EXPECT_EQ(get_words(ValueType::int32, &regs[10]), 1500);
  EXPECT_EQ(get_words(ValueType::int32, &regs[12]), -2250);
  EXPECT_EQ(get_words(ValueType::int32, &regs[16]), 1250);
  EXPECT_EQ(get_words(ValueType::int32, &regs[20]), -1);
  EXPECT_EQ(get_words(ValueType::uint32, &regs[22]), 8500);
  EXPECT_EQ(get_words(ValueType::uint32, &regs[40]), 0xDEADBEEF);
  ASSERT_GE(regs.size(), 62u);
  EXPECT_EQ(get_words(ValueType::uint32, &regs[56]), 7);
  EXPECT_EQ(get_words(ValueType::uint32, &regs[58]), 11);
  EXPECT_EQ(get_words(ValueType::uint32, &regs[60]), 13);
  std::vector<std::uint8_t> coils(table_extent(Table::coil));
  fill_bits(Table::coil, in, coils);
  EXPECT_EQ(coils, (std::vector<std::uint8_t>{1, 0, 0}));
}

TEST(ModbusDecide, ArbitraryBytesNeverCrashAndGetAProperAnswer) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> byte(0, 255), len(0, 40);
  const Bytes seeds[] = {read(0x03, 0, 4), write_registers(0, int32_words(80'000)),
                         write_coil(0, 0xFF00)};
  for (int i = 0; i < 20000; ++i) {
    Bytes b = seeds[i % 3];
    if (i % 2 == 0) {
      b.resize(static_cast<std::size_t>(len(rng)));
      for (auto& x : b) x = static_cast<std::uint8_t>(byte(rng));
    } else {
      b[static_cast<std::size_t>(byte(rng)) % b.size()] = static_cast<std::uint8_t>(byte(rng));
    }
    const Frame f = frame_request(b);
    if (f.status != FrameStatus::complete) continue;
    const Decision d = decide({b.data(), f.length}, current(), loop::State::idle);
    if (d.action == Action::exception) {
      EXPECT_TRUE(d.exception == ExceptionCode::illegal_function ||
                  d.exception == ExceptionCode::illegal_data_address ||
                  d.exception == ExceptionCode::illegal_data_value);
    }
    if (d.action == Action::read) {
      EXPECT_LE(d.address + d.count, table_extent(d.table));
    }
  }
}

}  // namespace
}  // namespace zerog::modbus
