#include "zerog/model/dictionary.hpp"

#include <Eigen/Geometry>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>

#include "zerog/model/effects.hpp"
#include "zerog/model/predict.hpp"
#include "zerog/model/user_effects.hpp"

namespace zerog::model {
namespace {

using Src = SignalSource;

// name, unit, source, angle, velocity — in the order of Signal.
constexpr SignalInfo kSignals[kSignalCount] = {
    {"q1", "rad", Src::joints, true, false},
    {"q2", "rad", Src::joints, true, false},
    {"q3", "rad", Src::joints, true, false},
    {"q4", "rad", Src::joints, true, false},
    {"q5", "rad", Src::joints, true, false},
    {"q6", "rad", Src::joints, true, false},
    {"qd1", "rad/s", Src::joints, false, true},
    {"qd2", "rad/s", Src::joints, false, true},
    {"qd3", "rad/s", Src::joints, false, true},
    {"qd4", "rad/s", Src::joints, false, true},
    {"qd5", "rad/s", Src::joints, false, true},
    {"qd6", "rad/s", Src::joints, false, true},
    {"qdd1", "rad/s^2", Src::joints, false, false},
    {"qdd2", "rad/s^2", Src::joints, false, false},
    {"qdd3", "rad/s^2", Src::joints, false, false},
    {"qdd4", "rad/s^2", Src::joints, false, false},
    {"qdd5", "rad/s^2", Src::joints, false, false},
    {"qdd6", "rad/s^2", Src::joints, false, false},
    {"vx_S", "m/s", Src::position, false, true},
    {"vy_S", "m/s", Src::position, false, true},
    {"vz_S", "m/s", Src::position, false, true},
    {"vx_B", "m/s", Src::position, false, true},
    {"vy_B", "m/s", Src::position, false, true},
    {"vz_B", "m/s", Src::position, false, true},
    {"ax_S", "m/s^2", Src::imu, false, false},
    {"ay_S", "m/s^2", Src::imu, false, false},
    {"az_S", "m/s^2", Src::imu, false, false},
    {"ax_B", "m/s^2", Src::imu, false, false},
    {"ay_B", "m/s^2", Src::imu, false, false},
    {"az_B", "m/s^2", Src::imu, false, false},
    {"wx_S", "rad/s", Src::imu, false, true},
    {"wy_S", "rad/s", Src::imu, false, true},
    {"wz_S", "rad/s", Src::imu, false, true},
    {"wx_B", "rad/s", Src::imu, false, true},
    {"wy_B", "rad/s", Src::imu, false, true},
    {"wz_B", "rad/s", Src::imu, false, true},
    {"wdx_S", "rad/s^2", Src::imu, false, false},
    {"wdy_S", "rad/s^2", Src::imu, false, false},
    {"wdz_S", "rad/s^2", Src::imu, false, false},
    {"wdx_B", "rad/s^2", Src::imu, false, false},
    {"wdy_B", "rad/s^2", Src::imu, false, false},
    {"wdz_B", "rad/s^2", Src::imu, false, false},
    {"gx_S", "1", Src::pose, false, false},
    {"gy_S", "1", Src::pose, false, false},
    {"gz_S", "1", Src::pose, false, false},
    {"px_B", "m", Src::position, false, false},
    {"py_B", "m", Src::position, false, false},
    {"pz_B", "m", Src::position, false, false},
    {"temperature", "K", Src::temperature, false, false},
    {"time", "s", Src::time, false, false},
};

constexpr int at(Signal s) { return static_cast<int>(s); }

double factor_value(const Factor& f, const DictionarySignals& s) {
  const double x = s[static_cast<std::size_t>(at(f.signal))];
  switch (f.op) {
    case FactorOp::value:
      return x;
    case FactorOp::sin:
      return std::sin(x);
    case FactorOp::cos:
      return std::cos(x);
    case FactorOp::sign:
      return x > 0.0 ? 1.0 : (x < 0.0 ? -1.0 : 0.0);
    case FactorOp::tanh:
      return std::tanh(x / f.eps);
  }
  return 0.0;
}

// Appends `text` to out[pos..size), keeping the terminating zero; returns the new position.
std::size_t append(char* out, std::size_t size, std::size_t pos, const char* text) {
  while (*text != '\0' && pos + 1 < size) out[pos++] = *text++;
  if (size > 0) out[pos < size ? pos : size - 1] = '\0';
  return pos;
}

std::size_t append_factor(const Factor& f, char* out, std::size_t size, std::size_t pos) {
  const char* name = signal_info(f.signal).name;
  switch (f.op) {
    case FactorOp::value:
      return append(out, size, pos, name);
    case FactorOp::sin:
    case FactorOp::cos:
    case FactorOp::sign:
      pos = append(out, size, pos,
                   f.op == FactorOp::sin ? "sin(" : (f.op == FactorOp::cos ? "cos(" : "sign("));
      pos = append(out, size, pos, name);
      return append(out, size, pos, ")");
    case FactorOp::tanh: {
      pos = append(out, size, pos, "tanh(");
      pos = append(out, size, pos, name);
      char eps[40];
      // Shortest text that reads back exactly.
      const auto r = std::to_chars(eps, eps + sizeof eps - 1, f.eps);
      *r.ptr = '\0';
      pos = append(out, size, pos, "/");
      pos = append(out, size, pos, eps);
      return append(out, size, pos, ")");
    }
  }
  return pos;
}

const char* factor_unit(const Factor& f) {
  return f.op == FactorOp::value ? signal_info(f.signal).unit : "1";
}

bool is_blank(char c) { return c == ' ' || c == '\t'; }

// Parses one factor from text[pos..end); advances pos.
bool parse_factor(std::string_view text, std::size_t& pos, std::size_t end, Factor& f,
                  const char*& error, std::size_t& error_pos) {
  while (pos < end && is_blank(text[pos])) ++pos;
  const std::size_t start = pos;
  std::size_t name_end = pos;
  while (name_end < end && text[name_end] != '(' && text[name_end] != '*' &&
         !is_blank(text[name_end]))
    ++name_end;
  const std::string_view word = text.substr(start, name_end - start);
  if (word.empty()) {
    error = "expected a signal name or sin(, cos(, sign(, tanh(";
    error_pos = start;
    return false;
  }
  if (name_end < end && text[name_end] == '(') {
    if (word == "sin") {
      f.op = FactorOp::sin;
    } else if (word == "cos") {
      f.op = FactorOp::cos;
    } else if (word == "sign") {
      f.op = FactorOp::sign;
    } else if (word == "tanh") {
      f.op = FactorOp::tanh;
    } else {
      error = "unknown function (sin, cos, sign, tanh)";
      error_pos = start;
      return false;
    }
    std::size_t p = name_end + 1;
    while (p < end && is_blank(text[p])) ++p;
    const std::size_t sig_start = p;
    while (p < end && text[p] != ')' && text[p] != '/' && !is_blank(text[p])) ++p;
    if (!signal_from_name(text.substr(sig_start, p - sig_start), f.signal)) {
      error = "unknown signal (proto/user_effects.md lists them)";
      error_pos = sig_start;
      return false;
    }
    while (p < end && is_blank(text[p])) ++p;
    if (f.op == FactorOp::tanh) {
      if (p >= end || text[p] != '/') {
        error = "tanh needs a scale: tanh(signal/eps), eps > 0 in the signal's unit";
        error_pos = p;
        return false;
      }
      ++p;
      while (p < end && is_blank(text[p])) ++p;
      const char* first = text.data() + p;
      const auto r = std::from_chars(first, text.data() + end, f.eps);
      if (r.ec != std::errc() || !(f.eps > 0.0) || !std::isfinite(f.eps)) {
        error = "tanh's eps must be a number > 0";
        error_pos = p;
        return false;
      }
      p = static_cast<std::size_t>(r.ptr - text.data());
      while (p < end && is_blank(text[p])) ++p;
    }
    if (p >= end || text[p] != ')') {
      error = "expected ')'";
      error_pos = p;
      return false;
    }
    pos = p + 1;
    const SignalInfo& si = signal_info(f.signal);
    if ((f.op == FactorOp::sin || f.op == FactorOp::cos) && !si.angle) {
      error = "sin and cos apply to joint angles (q1..q6) only";
      error_pos = start;
      return false;
    }
    if ((f.op == FactorOp::sign || f.op == FactorOp::tanh) && !si.velocity) {
      error = "sign and tanh apply to velocities only (qd*, v*_S, v*_B, w*_S, w*_B)";
      error_pos = start;
      return false;
    }
  } else {
    f.op = FactorOp::value;
    f.eps = 0.0;
    if (!signal_from_name(word, f.signal)) {
      error = "unknown signal (proto/user_effects.md lists them)";
      error_pos = start;
      return false;
    }
    pos = name_end;
  }
  while (pos < end && is_blank(text[pos])) ++pos;
  return true;
}

}  // namespace

const SignalInfo& signal_info(Signal s) { return kSignals[at(s)]; }

bool signal_from_name(std::string_view name, Signal& out) {
  for (int i = 0; i < kSignalCount; ++i) {
    if (name == kSignals[i].name) {
      out = static_cast<Signal>(i);
      return true;
    }
  }
  return false;
}

void central_differences(const double* x0, const double* x1, const double* x2, int n, double t0,
                         double t1, double t2, double* v, double* a) {
  const double h0 = t1 - t0, h1 = t2 - t1;
  for (int k = 0; k < n; ++k) {
    v[k] = (x2[k] - x0[k]) / (t2 - t0);
    if (a != nullptr) a[k] = 2.0 * ((x2[k] - x1[k]) / h1 - (x1[k] - x0[k]) / h0) / (h0 + h1);
  }
}

DictionarySignals dictionary_signals(const KinematicInputs& in, const RigGeometry& rig) {
  DictionarySignals s{};
  const FeatureSignals& f = in.features;
  for (int j = 0; j < 6; ++j) {
    const auto k = static_cast<std::size_t>(j);
    s[k] = f.joints_rad[k];
    s[6 + k] = f.joint_vel_radps[k];
    s[12 + k] = in.joint_acc_radps2[k];
  }
  const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> R(f.R_base_sensor.data());
  const Eigen::Vector3d v_B(in.v_base_sensor_mps[0], in.v_base_sensor_mps[1],
                            in.v_base_sensor_mps[2]);
  const Eigen::Vector3d f_I(f.imu[0], f.imu[1], f.imu[2]);
  const Eigen::Vector3d w_I(f.imu[3], f.imu[4], f.imu[5]);
  const Eigen::Vector3d wd_I(f.imu[6], f.imu[7], f.imu[8]);
  const Eigen::Vector3d g_dir_S = R.transpose() * Eigen::Vector3d(0.0, 0.0, -1.0);
  const Eigen::Vector3d w_S = rig.R_sensor_imu * w_I;
  const Eigen::Vector3d wd_S = rig.R_sensor_imu * wd_I;
  const Eigen::Vector3d r = -rig.p_sensor_imu_m;  // from the IMU to the S origin, in S
  const Eigen::Vector3d a_S =
      rig.R_sensor_imu * f_I + kStandardGravity * g_dir_S + wd_S.cross(r) + w_S.cross(w_S.cross(r));
  const Eigen::Vector3d v_S = R.transpose() * v_B;
  auto put = [&](Signal first, const Eigen::Vector3d& v) {
    for (int k = 0; k < 3; ++k) s[static_cast<std::size_t>(at(first) + k)] = v[k];
  };
  put(Signal::vx_S, v_S);
  put(Signal::vx_B, v_B);
  put(Signal::ax_S, a_S);
  put(Signal::ax_B, R * a_S);
  put(Signal::wx_S, w_S);
  put(Signal::wx_B, R * w_S);
  put(Signal::wdx_S, wd_S);
  put(Signal::wdx_B, R * wd_S);
  put(Signal::gx_S, g_dir_S);
  put(Signal::px_B,
      Eigen::Vector3d(f.p_base_sensor_m[0], f.p_base_sensor_m[1], f.p_base_sensor_m[2]));
  s[at(Signal::temperature)] = f.temperature_C - kTemperatureReferenceC;
  s[at(Signal::time)] = f.t_s;
  return s;
}

double basis_value(const Basis& b, const DictionarySignals& s) {
  const double a = factor_value(b.a, s);
  return b.product ? a * factor_value(b.b, s) : a;
}

void basis_unit(const Basis& b, char* out, std::size_t size) {
  if (size == 0) return;
  out[0] = '\0';
  const char* ua = factor_unit(b.a);
  if (!b.product) {
    append(out, size, 0, ua);
    return;
  }
  const char* ub = factor_unit(b.b);
  if (std::strcmp(ua, "1") == 0) {
    append(out, size, 0, ub);
  } else if (std::strcmp(ub, "1") == 0) {
    append(out, size, 0, ua);
  } else {
    std::size_t pos = append(out, size, 0, ua);
    pos = append(out, size, pos, "*");
    append(out, size, pos, ub);
  }
}

void format_basis(const Basis& b, char* out, std::size_t size) {
  if (size == 0) return;
  out[0] = '\0';
  std::size_t pos = append_factor(b.a, out, size, 0);
  if (b.product) {
    pos = append(out, size, pos, "*");
    append_factor(b.b, out, size, pos);
  }
}

bool parse_basis(std::string_view text, Basis& out, const char*& error, std::size_t& error_pos) {
  Basis b;
  std::size_t pos = 0;
  const std::size_t end = text.size();
  if (!parse_factor(text, pos, end, b.a, error, error_pos)) return false;
  if (pos < end && text[pos] == '*') {
    ++pos;
    b.product = true;
    if (!parse_factor(text, pos, end, b.b, error, error_pos)) return false;
  }
  if (pos != end) {
    error = "unexpected text after the basis (a basis is one factor or a product of two)";
    error_pos = pos;
    return false;
  }
  out = b;
  return true;
}

unsigned basis_sources(const Basis& b) {
  unsigned m = 1u << static_cast<unsigned>(signal_info(b.a.signal).source);
  if (b.product) m |= 1u << static_cast<unsigned>(signal_info(b.b.signal).source);
  return m;
}

Eigen::Matrix<double, 6, 1> term_direction(const UserTerm& t,
                                           const Eigen::Matrix3d& R_base_sensor) {
  Eigen::Matrix<double, 6, 1> d = Eigen::Matrix<double, 6, 1>::Zero();
  if (t.frame == TermFrame::sensor) {
    d[t.axis] = 1.0;
  } else {
    // R_BSᵀ e_k: row k of R_BS.
    const int part = t.axis < 3 ? 0 : 3;
    d.segment<3>(part) = R_base_sensor.row(t.axis % 3).transpose();
  }
  return d;
}

void user_design(const UserEffects& u, const DictionarySignals& s,
                 const Eigen::Matrix3d& R_base_sensor, double* out) {
  for (int j = 0; j < u.num_terms; ++j) {
    const UserTerm& t = u.terms[static_cast<std::size_t>(j)];
    Eigen::Map<Eigen::Matrix<double, 6, 1>>(out + 6 * j) =
        basis_value(t.basis, s) * term_direction(t, R_base_sensor);
  }
}

Eigen::Matrix<double, 6, 1> user_wrench(const UserEffects& u, const DictionarySignals& s,
                                        const Eigen::Matrix3d& R_base_sensor) {
  Eigen::Matrix<double, 6, 1> w = Eigen::Matrix<double, 6, 1>::Zero();
  for (int j = 0; j < u.num_terms; ++j) {
    const UserTerm& t = u.terms[static_cast<std::size_t>(j)];
    w += u.coeff[static_cast<std::size_t>(j)] * basis_value(t.basis, s) *
         term_direction(t, R_base_sensor);
  }
  return w;
}

unsigned user_sources(const UserEffects& u) {
  unsigned m = 0;
  for (int j = 0; j < u.num_terms; ++j)
    m |= basis_sources(u.terms[static_cast<std::size_t>(j)].basis);
  return m;
}

}  // namespace zerog::model
