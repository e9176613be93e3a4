#include "zerog/rt/record_csv.hpp"

#include <charconv>
#include <cstdint>
#include <initializer_list>
#include <string_view>

namespace zerog::rt {

namespace {

// clang-format off
constexpr std::string_view kColumns[] = {
    "cycle", "ipoc", "t_s", "dt_s", "state", "fault", "flags", "limit_flags", "model_status",
    "q1_rad", "q2_rad", "q3_rad", "q4_rad", "q5_rad", "q6_rad",
    "px_m", "py_m", "pz_m", "qw", "qx", "qy", "qz",
    "Fx_N", "Fy_N", "Fz_N", "Mx_Nm", "My_Nm", "Mz_Nm",
    "imu_fx_mps2", "imu_fy_mps2", "imu_fz_mps2", "imu_wx_radps", "imu_wy_radps", "imu_wz_radps",
    "ft_samples", "imu_samples",
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
  row.number(r.t_eval_s);
  row.numbers(r.wrench_at_eval);
  row.numbers(r.predicted);
  row.numbers(r.contact);
  row.integer(r.axis_reply ? 1 : 0);
  for (double v :
       {r.rkorr.x_mm, r.rkorr.y_mm, r.rkorr.z_mm, r.rkorr.a_deg, r.rkorr.b_deg, r.rkorr.c_deg})
    row.number(v);
  row.numbers(r.akorr_deg);
  row.numbers(r.body.p_world_m);
  for (double v : {r.body.q_world_body.w(), r.body.q_world_body.x(), r.body.q_world_body.y(),
                   r.body.q_world_body.z()})
    row.number(v);
  row.numbers(r.body.v_world_mps);
  row.numbers(r.body.L_world_kgm2ps);
  row.signed_integer(r.compute_ns);
  row.end();
}

}  // namespace zerog::rt
