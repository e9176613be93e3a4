// Writes the seed corpora of the fuzz targets (tests/fuzz/corpus/<target>/) with zerog's own
// writers, so the seeds are exactly what the programs exchange:
//
//     build/fuzz/tests/fuzz/fuzz_make_seeds tests/fuzz/corpus
//
// Run it again when a format changes (and keep the crash inputs, `crash-*`, that are there).
#include <array>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "../unit/infer/infer_fixtures.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/infer/deploy_file.hpp"
#include "zerog/io/candump.hpp"
#include "zerog/io/model_file.hpp"
#include "zerog/model/effects.hpp"
#include "zerog/proto/netcanoem.hpp"
#include "zerog/proto/rsi.hpp"
#include "zerog/proto/stim300.hpp"

namespace fs = std::filesystem;
using namespace zerog;

namespace {

fs::path g_root;

void put(const std::string& target, const std::string& name, std::string_view bytes) {
  const fs::path dir = g_root / target;
  fs::create_directories(dir);
  std::ofstream out(dir / name, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + (dir / name).string());
}
void put(const std::string& target, const std::string& name,
         const std::vector<std::uint8_t>& bytes) {
  put(target, name, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}
std::string read_text(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + path.string());
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void rsi_seeds() {
  namespace rsi = proto::rsi;
  std::array<char, rsi::kMaxMessageBytes> buffer{};
  rsi::RobotMessage m;
  m.actual_pose = {1772.2163, 315.0421, 1500.0, 10.08, 0.0, 180.0};
  m.joints_deg = {10.08, -90.0, 90.0, 0.0, 30.0, -12.25};
  m.ipoc = 4208157;
  auto r = rsi::format_robot_message(m, buffer);
  put("rsi", "robot_message", std::string_view(buffer.data(), r.size));
  m.has_delay = true;
  m.delay = 3;
  m.ipoc = 18446744073709551615u;
  r = rsi::format_robot_message(m, buffer);
  put("rsi", "robot_message_delay", std::string_view(buffer.data(), r.size));
  // Shaped like what a KR C4 with RSI 4 sends (tests/unit/proto/rsi_test.cpp).
  put("rsi", "kr_c4_message",
      "<Rob Type=\"KUKA\">"
      "<RIst X=\"445.5\" Y=\"-0.25\" Z=\"900.0001\" A=\"180\" B=\"0.5\" C=\"-179.9\"/>"
      "<RSol X=\"445.5\" Y=\"-0.25\" Z=\"900\" A=\"180\" B=\"0.5\" C=\"-179.9\"/>"
      "<AIPos A1=\"0\" A2=\"-90\" A3=\"90\" A4=\"0\" A5=\"45.5\" A6=\"-12.25\"/>"
      "<ASPos A1=\"0\" A2=\"-90\" A3=\"90\" A4=\"0\" A5=\"45\" A6=\"-12\"/>"
      "<Delay D=\"3\"/><Digout o1=\"0\" o2=\"1\" o3=\"0\"/><ProgStatus R=\"1\"/>"
      "<Tech C11=\"0\" C12=\"0\"><T21>1.5</T21><T22 x='a &amp; b'/></Tech>"
      "<DiL>0</DiL><IPOC>4208157</IPOC></Rob>");
  put("rsi", "prolog_whitespace",
      "<?xml version=\"1.0\"?>\n<Rob Type='KUKA'>\n  <RIst X='1e2' Y='-0.5' Z='+3' A='0' B='0' "
      "C='0' />\n  <AIPos A1='1' A2='2' A3='3' A4='4' A5='5' A6='6'/>\n  <IPOC>7</IPOC>\n</Rob>\n");
  r = rsi::format_reply({0.0015, -0.25, 0.0, 12.3457, 0.0, -0.5}, 4208157, buffer);
  put("rsi", "reply_rkorr", std::string_view(buffer.data(), r.size));
  r = rsi::format_axis_reply({0.01, -0.02, 0.0, 0.0, 0.005, 0.0}, 99, buffer, "ImFree");
  put("rsi", "reply_akorr", std::string_view(buffer.data(), r.size));
}

void stim300_seeds() {
  namespace stim = proto::stim300;
  auto stream_of = [](std::uint8_t config, std::uint8_t id, int n, bool crlf,
                      std::string_view garbage) {
    std::vector<std::uint8_t> out{config, 0x35};
    out.insert(out.end(), garbage.begin(), garbage.end());
    std::array<std::uint8_t, stim::kMaxDatagramLength + 2> buf{};
    for (int i = 0; i < n; ++i) {
      stim::RawDatagram d;
      d.identifier = id;
      d.rate.counts = {16384 * i, -5000, 8388607};
      d.accel.counts = {0, 524288, -524288};
      d.incl.counts = {4194304, 0, -1};
      d.pps = 0xFFFFFFu;
      d.rate_temperature.counts = {25 * 256, 26 * 256, -10};
      d.accel.status = i == 2 ? 0x01 : 0x00;
      d.counter = static_cast<std::uint8_t>(250 + (i == 3 ? 2 * i : i));  // wraps, one gap
      d.latency_us = static_cast<std::uint16_t>(500 + i);
      const auto r = stim::encode_datagram(d, crlf, buf);
      out.insert(out.end(), buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(r.size));
    }
    return out;
  };
  put("stim300_stream", "any_0x93_crlf", stream_of(0, 0x93, 6, true, ""));
  put("stim300_stream", "fixed_0x93_garbage", stream_of(4, 0x93, 5, false, "\x93\x00junk\r\n"));
  put("stim300_stream", "any_0x90", stream_of(0, 0x90, 4, false, ""));
  put("stim300_stream", "any_0xa7_g80", stream_of(0x60, 0xA7, 4, true, "\xA7"));
  put("stim300_stream", "any_0xf7_crlf", stream_of(0, 0xF7, 4, true, "\xF7"));
}

void netcanoem_seeds() {
  namespace nc = proto::netcanoem;
  using proto::CanFrame;
  auto append = [](std::vector<std::uint8_t>& out, const CanFrame& f) {
    for (int s = 24; s >= 0; s -= 8) out.push_back(static_cast<std::uint8_t>(f.id >> s));
    out.push_back(f.len);
    out.insert(out.end(), f.data.begin(), f.data.begin() + f.len);
  };
  const std::uint8_t base = 0x20;
  auto readout = [&](nc::FirmwareVersion fw) {
    std::vector<std::uint8_t> out{base, 3};
    append(out, *nc::encode_active_calibration(base, 3));
    append(out, *nc::encode_firmware_version(base, fw));
    append(out, *nc::encode_serial_number(base, {'F', 'T', '1', '2', '3', '4', '5', '6'}));
    for (int row = 0; row < 6; ++row) {
      std::array<double, 6> coefficients{};
      for (int c = 0; c < 6; ++c) coefficients[c] = (row == c ? 0.25 : 0.001 * (c - row));
      const auto frames = nc::encode_matrix_row(base, coefficients);
      for (const CanFrame& f : *frames) append(out, f);
    }
    if (fw.has_counts()) append(out, *nc::encode_counts(base, 1000000, 1000000));
    append(out, *nc::encode_units(base, 2, 3));
    const auto sample = nc::encode_sample(base, {100, -200, 32767, -32768, 5, 0}, 0);
    for (const CanFrame& f : *sample) append(out, f);
    return out;
  };
  put("netcanoem_frames", "readout_fw37", readout({3, 7, 12}));
  put("netcanoem_frames", "readout_fw36", readout({3, 6, 1}));
  std::vector<std::uint8_t> samples{base, 0};
  append(samples, *nc::request_sample(base));
  for (int i = 0; i < 3; ++i) {
    const auto frames =
        nc::encode_sample(base, {static_cast<std::int16_t>(10 * i), -20, 30, -40, 50, -60},
                          static_cast<std::uint16_t>(i == 1 ? 0x8000 : 0));
    for (const CanFrame& f : *frames) append(samples, f);
  }
  samples.insert(samples.end(), {0, 0, 0, 0, 0xFF});  // a timeout
  put("netcanoem_frames", "samples", samples);
}

void candump_seeds() {
  put("candump", "ati_stream",
      "(1700000000.123456) can0 200#\n"
      "(1700000000.123789) can0 200#000000640000FF38\n"
      "(1700000000.124000) can0 201#FF9CFFFF0005\n"
      "(1700000000.125000) can0 202#DE.AD.BE.EF.00.11.22.33 R\n");
  put("candump", "kinds",
      "(0.000000001) vcan0 123#R\n"
      "(1.5) can1 12345678#0102 T\n"
      "\r\n"
      "(2.000000) can0 123#R4\n"
      "(3.123456789) can0 20000004#0000000000000000\n");
  put("candump", "default_output",
      "  can1  7F6   [1]  00\n"
      "  can0  12345678   [2]  01 02\n"
      "  can0       201   [0]  remote request\n"
      "  can0  RX - -  123  [12]  00 11 22 33 44 55 66 77 88 99 AA BB\n"
      "  can0  20000004   [8]  00 04 00 00 00 00 00 00   ERRORFRAME\n");
  put("candump", "default_ta", " (1700000000.123456)  can0  201   [2]  AB CD\n");
  put("candump", "default_td",
      " (000.000000)  can0  201   [2]  AB CD\n (000.000700)  can0  201   [0] \n");
  put("candump", "default_tA",
      " (2023-11-14 22:13:20.123456)  can0  201   [4]  41 42 43 44   'ABCD'\n");
  io::CandumpRecord r;
  r.timestamp_ns = 1700000000123456000;
  r.interface = "can0";
  r.frame.id = 0x7FF;
  r.frame.len = 8;
  r.frame.data = {1, 2, 3, 4, 5, 6, 7, 8};
  put("candump", "formatted", io::format_candump_line(r) + "\n");
}

void modbus_seeds() {
  auto adu = [](std::uint16_t transaction, std::vector<std::uint8_t> pdu) {
    std::vector<std::uint8_t> out{static_cast<std::uint8_t>(transaction >> 8),
                                  static_cast<std::uint8_t>(transaction),
                                  0,
                                  0,
                                  static_cast<std::uint8_t>((pdu.size() + 1) >> 8),
                                  static_cast<std::uint8_t>(pdu.size() + 1),
                                  1};
    out.insert(out.end(), pdu.begin(), pdu.end());
    return out;
  };
  auto cat = [](std::uint8_t state, std::vector<std::vector<std::uint8_t>> parts) {
    std::vector<std::uint8_t> out{state};
    for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
    return out;
  };
  put("modbus_request", "reads",
      cat(0, {adu(1, {0x03, 0x00, 0x00, 0x00, 0x10}), adu(2, {0x04, 0x00, 0x00, 0x00, 0x08}),
              adu(3, {0x01, 0x00, 0x00, 0x00, 0x03}), adu(4, {0x02, 0x00, 0x00, 0x00, 0x03})}));
  // Mass 100 kg = 100000 raw at holding registers 0–1 (proto/modbus.md).
  put("modbus_request", "write_mass_idle",
      cat(0, {adu(7, {0x10, 0x00, 0x00, 0x00, 0x02, 0x04, 0x00, 0x01, 0x86, 0xA0})}));
  put("modbus_request", "coils_zero_g",
      cat(2, {adu(9, {0x05, 0x00, 0x00, 0xFF, 0x00}), adu(10, {0x05, 0x00, 0x00, 0x00, 0x00}),
              adu(11, {0x0F, 0x00, 0x00, 0x00, 0x03, 0x01, 0x05})}));
  put("modbus_request", "bad_function_partial",
      cat(3, {adu(12, {0x2B, 0x0E, 0x01, 0x00}), {0x00, 0x0D, 0x00, 0x00, 0x00}}));
}

void io_seeds(const fs::path& source) {
  formats::Rig rig;
  rig.name = "fuzz";
  rig.flange_sensor.p_m = {0.0, 0.0, 0.06};
  rig.sensor_imu.p_m = {0.0, 0.0, -0.03};
  rig.ft_rate_hz = 1000.0;
  rig.imu_rate_hz = 2000.0;
  rig.floor_z_m = -0.675;
  const fs::path tmp = fs::temp_directory_path() / "zerog-make-seeds";
  fs::create_directories(tmp);
  formats::write_rig(rig, tmp / "w.rig.toml");
  put("rig_toml", "written.rig.toml", read_text(tmp / "w.rig.toml"));
  put("rig_toml", "import_example.rig.toml",
      read_text(source / "calib/import_example/kr210.rig.toml"));

  formats::Log log;
  log.rig = rig;
  for (bool all : {true, false}) {
    log.columns = {.joints = all, .specific_force = all, .angular_rate = all, .temperature = all};
    log.samples.clear();
    for (int i = 0; i < 4; ++i) {
      formats::Sample s;
      s.t_s = 0.012 * i;
      s.joints_rad = {0.1 * i, -1.5, 1.5, 0.0, 0.5, -0.2};
      s.p_base_sensor_m = {1.7, 0.3 + 0.001 * i, 1.5};
      s.q_base_sensor = Eigen::Quaterniond(0.0, 1.0, 0.0, 0.0);
      s.specific_force_imu_mps2 = {0.0, 0.0, 9.80665};
      s.angular_rate_imu_radps = {0.01 * i, 0.0, -0.3};
      s.force_sensor_N = {1.5, -0.8, 980.665 + i};
      s.torque_sensor_Nm = {0.12, -9.58, -0.008};
      s.temperature_C = 31.5;
      log.samples.push_back(s);
    }
    formats::write_log(log, tmp / "w.csv");
    put("log_csv", all ? "all_columns.csv" : "required_columns.csv", read_text(tmp / "w.csv"));
  }
  put("log_csv", "comments_crlf.csv",
      "# zerog-log 1\r\n# a comment\r\nt_s,px_m,py_m,pz_m,qw,qx,qy,qz,Fx_N,Fy_N,Fz_N,Mx_Nm,My_Nm,"
      "Mz_Nm\r\n0, 1,2,3, 1,0,0,0, "
      "+1e1,2,3,4,5,6\r\n\r\n0.5,1,2,3,0.5,0.5,0.5,0.5,1,2,3,4,5,6\r\n");

  put("import_mapping", "import_example.toml",
      read_text(source / "calib/import_example/mapping.toml"));
  put("import_mapping", "one_file_with_data.toml",
      "format = \"zerog-import\"\nversion = 1\n\n[rig]\nname = \"r\"\nrobot = \"KR 210 R2700\"\n"
      "flange_sensor = { p_m = [0, 0, 0.06], q_wxyz = [1, 0, 0, 0] }\n"
      "sensor_imu = { p_m = [0, 0, -0.03], q_wxyz = [1, 0, 0, 0] }\n\n"
      "[files.all]\npath = \"data.txt\"\nskip_lines = 1\ndelimiter = \"tab\"\n"
      "time = { column = \"t\", unit = \"ms\" }\n"
      "position = { columns = [\"x\", \"y\", \"z\"], unit = \"mm\" }\n"
      "orientation = { type = \"quaternion\", columns = [\"qw\", \"qx\", \"qy\", \"qz\"] }\n"
      "force = { columns = [\"fx\", \"fy\", \"fz\"], unit = \"kN\" }\n"
      "torque = { columns = [\"mx\", \"my\", \"mz\"], unit = \"N*m\" }\n"
      "#@data\n"
      "exported by hand\n"
      "t\tx\ty\tz\tqw\tqx\tqy\tqz\tfx\tfy\tfz\tmx\tmy\tmz\n"
      "0\t1700\t300\t1500\t1\t0\t0\t0\t0.001\t0\t0.98\t0\t0\t0\n"
      "12\t1701\t300\t1500\t1\t0\t0\t0\t0.001\t0\t0.98\t0\t0\t0.5\n"
      "24\t1702\t300\t1500\t1\t0\t0\t0\t0.001\t0\t0.98\t0\t0\t1\n");

  io::ModelFile model;
  model.params = infer::test::demo_physics();
  model.rig_name = "kr210-omega191-stim300";
  model.extra = {{"fit", {{"rms_N", 1.33}}}};
  put("model_file", "demo_truth.json", io::to_json(model).dump(2) + "\n");
  std::array<std::array<double, model::kMaxEffectParams>, model::kEffectCount> stds{};
  for (auto& row : stds) row.fill(0.01);
  model.std = stds;
  model.params.effects = {model::Effect::bias, model::Effect::gravity};
  put("model_file", "fit_with_std.json", io::to_json(model).dump(2) + "\n");

  put("rt_config", "sample.toml", read_text(source / "firmware/rt/zerog-rt.sample.toml"));
  put("rt_config", "minimal.toml",
      "[model]\nfile = \"deploy.zgm\"\n[rig]\nfile = \"rig.rig.toml\"\n[robot]\ncycle_ms = 4\n"
      "[body]\nmass_kg = 60.0\ninertia_kgm2 = [[2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 3.0]]\n"
      "[modbus]\nbind_address = \"127.0.0.1\"\nallow = [\"10.0.1.0/24\"]\n");
  fs::remove_all(tmp);
}

void deploy_seeds() {
  infer::DeployedModel model;
  model.rig = infer::test::demo_rig();
  model.physics = infer::test::demo_physics();
  model.provenance_json = R"({"source": "tests/fuzz/make_seeds.cpp"})";
  const std::string physics_only = infer::serialise_deployed_model(model);
  put("deploy_file", "physics_only.zgm", physics_only);
  put("deploy_file", "physics_only_content.json", physics_only.substr(physics_only.find('\n') + 1));
  const auto data = infer::test::random_samples(64, 7);
  model.network = infer::test::make_network(
      {model::Feature::sign_qd6, model::Feature::qd6, model::Feature::sin_q4}, {4},
      model::Activation::tanh, data, 1.0, 11, 8);
  const std::string with_network = infer::serialise_deployed_model(model);
  put("deploy_file", "network.zgm", with_network);
  put("deploy_file", "network_content.json", with_network.substr(with_network.find('\n') + 1));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s CORPUS_DIR (e.g. tests/fuzz/corpus)\n", argv[0]);
    return 2;
  }
  g_root = argv[1];
  try {
    rsi_seeds();
    stim300_seeds();
    netcanoem_seeds();
    candump_seeds();
    modbus_seeds();
    io_seeds(ZEROG_SOURCE_DIR);
    deploy_seeds();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_seeds: %s\n", e.what());
    return 1;
  }
  return 0;
}
