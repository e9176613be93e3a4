#include "zerog/formats/cycles_csv.hpp"

#include <charconv>
#include <cmath>
#include <cstdint>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <map>
#include <sstream>
#include <stdexcept>
#include <string_view>

#include "zerog/proto/rsi_si.hpp"

namespace zerog::formats {

namespace {

// clang-format off
constexpr std::string_view kColumns[] = {
    "cycle", "ipoc", "t_s", "dt_s", "state", "fault", "flags", "limit_flags", "model_status",
    "q1_rad", "q2_rad", "q3_rad", "q4_rad", "q5_rad", "q6_rad",
    "px_m", "py_m", "pz_m", "qw", "qx", "qy", "qz",
    "Fx_N", "Fy_N", "Fz_N", "Mx_Nm", "My_Nm", "Mz_Nm",
    "imu_fx_mps2", "imu_fy_mps2", "imu_fz_mps2", "imu_wx_radps", "imu_wy_radps", "imu_wz_radps",
    "ft_samples", "imu_samples",
    "temp_C", "temp_measured",
    "t_eval_s",
    "eval_Fx_N", "eval_Fy_N", "eval_Fz_N", "eval_Mx_Nm", "eval_My_Nm", "eval_Mz_Nm",
    "pred_Fx_N", "pred_Fy_N", "pred_Fz_N", "pred_Mx_Nm", "pred_My_Nm", "pred_Mz_Nm",
    "contact_Fx_N", "contact_Fy_N", "contact_Fz_N", "contact_Mx_Nm", "contact_My_Nm", "contact_Mz_Nm",
    "axis_reply",
    "rkorr_x_mm", "rkorr_y_mm", "rkorr_z_mm", "rkorr_a_deg", "rkorr_b_deg", "rkorr_c_deg",
    "akorr_a1_deg", "akorr_a2_deg", "akorr_a3_deg", "akorr_a4_deg", "akorr_a5_deg", "akorr_a6_deg",
    "body_px_m", "body_py_m", "body_pz_m", "body_qw", "body_qx", "body_qy", "body_qz",
    "body_vx_mps", "body_vy_mps", "body_vz_mps",
    "body_Lx_kgm2ps", "body_Ly_kgm2ps", "body_Lz_kgm2ps",
    "compute_ns",
};
// clang-format on

class Row {
 public:
  explicit Row(std::string& out) : out_(out) {}
  void text(std::string_view s) {
    sep();
    out_ += s;
  }
  void integer(std::uint64_t v) {
    char buffer[24];
    const auto r = std::to_chars(buffer, buffer + sizeof buffer, v);
    text(std::string_view(buffer, static_cast<std::size_t>(r.ptr - buffer)));
  }
  void signed_integer(std::int64_t v) {
    char buffer[24];
    const auto r = std::to_chars(buffer, buffer + sizeof buffer, v);
    text(std::string_view(buffer, static_cast<std::size_t>(r.ptr - buffer)));
  }
  /// A number that may be unknown: NaN (an older file's record read back) as an empty cell.
  void optional_number(double v) {
    if (std::isnan(v)) {
      text("");
    } else {
      number(v);
    }
  }
  void number(double v) {
    char buffer[32];
    const auto r = std::to_chars(buffer, buffer + sizeof buffer, v);
    text(std::string_view(buffer, static_cast<std::size_t>(r.ptr - buffer)));
  }
  template <typename Array>
  void numbers(const Array& a) {
    for (double v : a) number(v);
  }
  void end() { out_ += '\n'; }

 private:
  void sep() {
    if (!first_) out_ += ',';
    first_ = false;
  }
  std::string& out_;
  bool first_ = true;
};

template <typename Enum, int N>
Enum enum_from_name(const std::string& name, const char* (*name_of)(Enum), const char* what) {
  for (int i = 0; i < N; ++i)
    if (name == name_of(static_cast<Enum>(i))) return static_cast<Enum>(i);
  throw std::runtime_error(std::string("unknown ") + what + " \"" + name + "\"");
}

}  // namespace

int record_column_count() { return static_cast<int>(std::size(kColumns)); }

void append_record_header(std::string& out) {
  Row row(out);
  for (std::string_view c : kColumns) row.text(c);
  row.end();
}

void append_record_row(const loop::CycleRecord& r, std::string& out) {
  Row row(out);
  row.integer(r.cycle);
  row.integer(r.ipoc);
  row.number(r.t_s);
  row.number(r.dt_s);
  row.text(loop::state_name(r.state));
  row.text(loop::fault_name(r.fault));
  row.integer(r.flags);
  row.integer(r.limit_flags);
  row.text(infer::status_name(r.model_status));
  row.numbers(r.joints_rad);
  row.numbers(r.p_base_sensor_m);
  for (double v :
       {r.q_base_sensor.w(), r.q_base_sensor.x(), r.q_base_sensor.y(), r.q_base_sensor.z()})
    row.number(v);
  row.numbers(r.wrench_measured);
  row.numbers(r.specific_force_imu);
  row.numbers(r.rate_imu);
  row.integer(r.ft_samples);
  row.integer(r.imu_samples);
  row.optional_number(r.temperature_C);
  row.integer(r.temperature_measured ? 1 : 0);
  row.number(r.t_eval_s);
  row.numbers(r.wrench_at_eval);
  row.numbers(r.predicted);
  row.numbers(r.contact);
  // The record's reply is SI; the file keeps the wire's units (proto/loop.md): the RSI
  // border's conversion, here and not in the cycle.
  const proto::rsi::Reply kuka = proto::rsi::reply_from_correction(r.reply);
  row.integer(r.reply.axis() ? 1 : 0);
  for (double v : {kuka.rkorr.x_mm, kuka.rkorr.y_mm, kuka.rkorr.z_mm, kuka.rkorr.a_deg,
                   kuka.rkorr.b_deg, kuka.rkorr.c_deg})
    row.number(v);
  row.numbers(kuka.akorr_deg);
  row.numbers(r.body.p_world_m);
  for (double v : {r.body.q_world_body.w(), r.body.q_world_body.x(), r.body.q_world_body.y(),
                   r.body.q_world_body.z()})
    row.number(v);
  row.numbers(r.body.v_world_mps);
  row.numbers(r.body.L_world_kgm2ps);
  row.signed_integer(r.compute_ns);
  row.end();
}

std::vector<loop::CycleRecord> read_cycles_csv(const std::filesystem::path& file) {
  const std::string path = file.string();
  std::ifstream in(file);
  if (!in) throw std::runtime_error(path + ": cannot be read");
  std::string line;
  if (!std::getline(in, line)) throw std::runtime_error(path + ": empty");
  std::map<std::string, std::size_t> column;
  {
    std::stringstream ss(line);
    std::string name;
    for (std::size_t i = 0; std::getline(ss, name, ','); ++i) column[name] = i;
  }
  std::vector<loop::CycleRecord> records;
  for (int line_no = 2; std::getline(in, line); ++line_no) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    for (std::string cell; std::getline(ss, cell, ',');) f.push_back(cell);
    const std::string where = path + ":" + std::to_string(line_no);
    const auto cell = [&](const char* name) -> const std::string& {
      const auto it = column.find(name);
      if (it == column.end()) throw std::runtime_error(path + ": no column " + name);
      if (it->second >= f.size()) throw std::runtime_error(where + ": too few cells");
      return f[it->second];
    };
    const auto num = [&](const char* name) {
      const std::string& s = cell(name);
      double v = 0.0;
      const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
      if (r.ec != std::errc{} || r.ptr != s.data() + s.size())
        throw std::runtime_error(where + ": " + name + " \"" + s + "\" is not a number");
      return v;
    };
    const auto uint = [&](const char* name) {
      const std::string& s = cell(name);
      std::uint64_t v = 0;
      const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
      if (r.ec != std::errc{} || r.ptr != s.data() + s.size())
        throw std::runtime_error(where + ": " + name + " \"" + s + "\" is not an integer");
      return v;
    };
    loop::CycleRecord r;
    r.cycle = uint("cycle");
    r.ipoc = uint("ipoc");
    r.t_s = num("t_s");
    r.dt_s = num("dt_s");
    r.state = enum_from_name<loop::State, 4>(cell("state"), loop::state_name, "state");
    r.fault = enum_from_name<loop::Fault, 8>(cell("fault"), loop::fault_name, "fault");
    r.flags = static_cast<std::uint32_t>(uint("flags"));
    r.limit_flags = static_cast<std::uint32_t>(uint("limit_flags"));
    r.model_status = enum_from_name<infer::StatusCode, 4>(cell("model_status"), infer::status_name,
                                                          "model status");
    const char* q[] = {"q1_rad", "q2_rad", "q3_rad", "q4_rad", "q5_rad", "q6_rad"};
    for (int i = 0; i < 6; ++i) r.joints_rad[i] = num(q[i]);
    r.p_base_sensor_m = {num("px_m"), num("py_m"), num("pz_m")};
    r.q_base_sensor = Eigen::Quaterniond(num("qw"), num("qx"), num("qy"), num("qz"));
    const char* axes[] = {"Fx_N", "Fy_N", "Fz_N", "Mx_Nm", "My_Nm", "Mz_Nm"};
    for (int i = 0; i < 6; ++i) {
      const std::string a = axes[i];
      r.wrench_measured[i] = num(a.c_str());
      r.wrench_at_eval[i] = num(("eval_" + a).c_str());
      r.predicted[i] = num(("pred_" + a).c_str());
      r.contact[i] = num(("contact_" + a).c_str());
    }
    const char* imu[] = {"imu_fx_mps2",  "imu_fy_mps2",  "imu_fz_mps2",
                         "imu_wx_radps", "imu_wy_radps", "imu_wz_radps"};
    for (int i = 0; i < 3; ++i) {
      r.specific_force_imu[i] = num(imu[i]);
      r.rate_imu[i] = num(imu[3 + i]);
    }
    r.ft_samples = static_cast<std::uint16_t>(uint("ft_samples"));
    r.imu_samples = static_cast<std::uint16_t>(uint("imu_samples"));
    // The temperature fed to the model (°C), from cycles.csv files that have it: an older file
    // (or an empty cell) reads as unknown (NaN), not measured.
    r.temperature_C = std::numeric_limits<double>::quiet_NaN();
    r.temperature_measured = false;
    if (column.contains("temp_C") && !cell("temp_C").empty()) r.temperature_C = num("temp_C");
    if (column.contains("temp_measured")) r.temperature_measured = uint("temp_measured") != 0;
    r.t_eval_s = num("t_eval_s");
    // Back to SI (the writer's inverse, up to rounding): AKorr when axis_reply, else RKorr; an
    // RKorr of zeros is Kind::none (what the cycle answers outside zero-g).
    proto::rsi::Reply kuka;
    kuka.ipoc = r.ipoc;
    kuka.has_akorr = uint("axis_reply") != 0;
    kuka.rkorr = {num("rkorr_x_mm"),  num("rkorr_y_mm"),  num("rkorr_z_mm"),
                  num("rkorr_a_deg"), num("rkorr_b_deg"), num("rkorr_c_deg")};
    const proto::rsi::Correction& k = kuka.rkorr;
    kuka.has_rkorr = !kuka.has_akorr && (k.x_mm != 0.0 || k.y_mm != 0.0 || k.z_mm != 0.0 ||
                                         k.a_deg != 0.0 || k.b_deg != 0.0 || k.c_deg != 0.0);
    if (!kuka.has_rkorr) kuka.rkorr = {};
    const char* ak[] = {"akorr_a1_deg", "akorr_a2_deg", "akorr_a3_deg",
                        "akorr_a4_deg", "akorr_a5_deg", "akorr_a6_deg"};
    for (int i = 0; i < 6; ++i) kuka.akorr_deg[i] = num(ak[i]);
    r.reply = proto::rsi::correction_from_reply(kuka);
    r.body.p_world_m = {num("body_px_m"), num("body_py_m"), num("body_pz_m")};
    r.body.q_world_body =
        Eigen::Quaterniond(num("body_qw"), num("body_qx"), num("body_qy"), num("body_qz"));
    r.body.v_world_mps = {num("body_vx_mps"), num("body_vy_mps"), num("body_vz_mps")};
    r.body.L_world_kgm2ps = {num("body_Lx_kgm2ps"), num("body_Ly_kgm2ps"), num("body_Lz_kgm2ps")};
    const std::string& c = cell("compute_ns");
    std::int64_t ns = 0;
    std::from_chars(c.data(), c.data() + c.size(), ns);
    r.compute_ns = ns;
    records.push_back(r);
  }
  return records;
}

}  // namespace zerog::formats
