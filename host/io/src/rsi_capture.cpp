#include "zerog/io/rsi_capture.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>

#include "zerog/formats/log.hpp"
#include "zerog/proto/rsi_si.hpp"
#include "zerog/robot/forward_kinematics.hpp"

namespace zerog::io {

using formats::InputError;
using formats::write_file_atomic;

namespace {

namespace rsi = proto::rsi;

// 1-based line and column of byte `offset`, from the sorted offsets of the line starts.
std::pair<std::size_t, std::size_t> line_column(const std::vector<std::size_t>& line_starts,
                                                std::size_t offset) {
  const auto it = std::upper_bound(line_starts.begin(), line_starts.end(), offset);
  const std::size_t line = static_cast<std::size_t>(it - line_starts.begin());  // ≥ 1
  return {line, offset - line_starts[line - 1] + 1};
}

// "<Rob" as an element start (followed by whitespace, '>' or '/'), from `from`.
std::size_t find_element(std::string_view text, std::string_view open, std::size_t from) {
  while (true) {
    const std::size_t at = text.find(open, from);
    if (at == std::string_view::npos) return at;
    const std::size_t next = at + open.size();
    if (next >= text.size()) return at;  // "<Rob" at the very end: a truncated message
    const char c = text[next];
    if (c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '>' || c == '/') return at;
    from = next;
  }
}

Eigen::Quaterniond canonical(const Eigen::Matrix3d& R) {
  Eigen::Quaterniond q(R);
  q.normalize();
  if (q.w() < 0.0) q.coeffs() = -q.coeffs();
  return q;
}

void set_pose(RsiRow& row, const Eigen::Matrix3d& R, const Eigen::Vector3d& p) {
  const Eigen::Quaterniond q = canonical(R);
  row.has_pose = true;
  row.p_base_sensor_m = {p.x(), p.y(), p.z()};
  row.q_base_sensor_wxyz = {q.w(), q.x(), q.y(), q.z()};
}

// One parsed message → a row in SI.
RsiRow make_row(const rsi::RobotMessage& m, const RsiDecodeOptions& o) {
  RsiRow row;
  row.ipoc = m.ipoc;
  row.t_s = static_cast<double>(m.ipoc) * o.ipoc_unit_s;
  const samples::RobotSample si = rsi::robot_sample_from_message(m);
  row.joints_rad = si.joints_rad;
  row.has_delay = m.has_delay;
  row.delay = m.delay;
  row.external_present = m.external_axes_present;
  for (std::size_t i = 0; i < rsi::kMaxExternalAxes && i < o.external_axes.size(); ++i) {
    row.external_si[i] = rsi::external_axis_to_si(m.external_axes[i], o.external_axes[i]);
  }
  Eigen::Matrix3d R_rist = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p_rist = Eigen::Vector3d::Zero();
  if (si.has_pose) {
    R_rist = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(si.R_base_tcp.data());
    p_rist = Eigen::Vector3d(si.p_base_tcp_m[0], si.p_base_tcp_m[1], si.p_base_tcp_m[2]);
  }
  std::optional<robot::Pose> kinematics;
  if (o.robot) kinematics = robot::sensor_pose(*o.robot, row.joints_rad);
  if (m.has_actual_pose && kinematics) {
    row.has_check = true;
    row.check_m = (p_rist - kinematics->p_m).norm();
    row.check_rad = Eigen::AngleAxisd(Eigen::Matrix3d(R_rist.transpose() * kinematics->R)).angle();
  }
  const bool use_rist = m.has_actual_pose && o.pose_source != RsiPoseSource::joints;
  const bool use_joints = kinematics && o.pose_source != RsiPoseSource::rist && !use_rist;
  if (use_rist) {
    set_pose(row, R_rist, p_rist);
  } else if (use_joints) {
    set_pose(row, kinematics->R, kinematics->p_m);
    row.pose_from_joints = true;
  }
  return row;
}

}  // namespace

RsiDecodeResult decode_rsi_capture(std::string_view text, const RsiDecodeOptions& o) {
  RsiDecodeResult r;
  std::vector<std::size_t> line_starts{0};
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '\n') line_starts.push_back(i + 1);
  }
  for (std::size_t at = find_element(text, "<Sen", 0); at != std::string_view::npos;
       at = find_element(text, "<Sen", at + 4)) {
    ++r.replies;
  }

  std::size_t at = find_element(text, "<Rob", 0);
  while (at != std::string_view::npos) {
    ++r.messages;
    const std::size_t next = find_element(text, "<Rob", at + 4);
    // The message ends after "</Rob…>" if that comes before the next message; else it is cut
    // short and runs to the end of its line (the parser then says how it is incomplete).
    std::size_t end = std::string_view::npos;
    const std::size_t close = text.find("</Rob", at);
    if (close != std::string_view::npos && (next == std::string_view::npos || close < next)) {
      const std::size_t gt = text.find('>', close);
      if (gt != std::string_view::npos && (next == std::string_view::npos || gt < next))
        end = gt + 1;
    }
    if (end == std::string_view::npos) {
      const std::size_t eol = text.find('\n', at);
      end = std::min({eol == std::string_view::npos ? text.size() : eol,
                      next == std::string_view::npos ? text.size() : next});
      while (end > at && text[end - 1] == '\r') --end;
    }
    const std::string_view message = text.substr(at, end - at);
    rsi::RobotMessage m;
    const rsi::ParseResult parsed = rsi::parse_robot_message(message, m);
    if (!parsed.ok()) {
      const auto [line, column] = line_column(line_starts, at + parsed.offset);
      r.refusals.push_back({parsed.status, parsed.reason, line, column});
      ++r.refusals_by_status[static_cast<std::size_t>(parsed.status)];
    } else {
      if (!m.has_actual_pose) ++r.without_rist;
      if (m.external_axes_present != 0) ++r.with_external;
      r.skipped_elements += m.skipped_elements;
      if (!r.rows.empty() && m.ipoc <= r.rows.back().ipoc) {
        ++r.stale;
      } else {
        RsiRow row = make_row(m, o);
        row.line = line_column(line_starts, at).first;
        r.rows.push_back(row);
      }
    }
    at = next;
  }

  // The cycle: given, or the most frequent IPOC step.
  r.cycle_ipoc = o.cycle_ipoc;
  if (r.cycle_ipoc == 0 && r.rows.size() >= 2) {
    std::map<std::uint64_t, std::size_t> steps;
    for (std::size_t i = 1; i < r.rows.size(); ++i) ++steps[r.rows[i].ipoc - r.rows[i - 1].ipoc];
    r.cycle_ipoc = std::max_element(steps.begin(), steps.end(), [](const auto& a, const auto& b) {
                     return a.second < b.second;
                   })->first;
  }
  if (r.cycle_ipoc > 0) {
    for (std::size_t i = 1; i < r.rows.size(); ++i) {
      const std::uint64_t step = r.rows[i].ipoc - r.rows[i - 1].ipoc;
      if (2 * step > 3 * r.cycle_ipoc) {
        ++r.ipoc_gaps;
        const auto periods = static_cast<std::uint64_t>(
            std::llround(static_cast<double>(step) / static_cast<double>(r.cycle_ipoc)));
        r.cycles_lost += periods > 1 ? periods - 1 : 0;
      }
    }
  }
  for (const RsiRow& row : r.rows) {
    if (!row.has_pose) r.all_have_pose = false;
    if (row.has_check) {
      ++r.pose_checks;
      r.max_check_m = std::max(r.max_check_m, row.check_m);
      r.max_check_rad = std::max(r.max_check_rad, row.check_rad);
    }
  }
  return r;
}

RsiDecodeResult decode_rsi_capture_file(const std::filesystem::path& path,
                                        const RsiDecodeOptions& options) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, 0, "cannot open the capture");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(path, 0, 0, "cannot read the capture");
  return decode_rsi_capture(text, options);
}

namespace {

// Which external axes are written: those with a kind, given in at least one row.
std::vector<std::size_t> external_columns(const RsiDecodeResult& r, const RsiDecodeOptions& o) {
  std::uint8_t present = 0;
  for (const RsiRow& row : r.rows) present |= row.external_present;
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < rsi::kMaxExternalAxes && i < o.external_axes.size(); ++i) {
    if ((present & (1u << i)) != 0) out.push_back(i);
  }
  return out;
}

}  // namespace

std::string rsi_recording_csv(const RsiDecodeResult& r, const RsiDecodeOptions& o) {
  const bool pose = r.all_have_pose && !r.rows.empty();
  const bool checks = r.pose_checks > 0;
  const std::vector<std::size_t> external = external_columns(r, o);
  std::ostringstream os;
  os << "# zerog-rsi 1: robot messages decoded from RSI XML by zerog decode-rsi (t_s = IPOC * "
     << o.ipoc_unit_s
     << " s, controller clock; joints rad; pose of the sensor frame S in the base frame B, m and "
        "unit quaternion)\n";
  os << "t_s,ipoc,q1_rad,q2_rad,q3_rad,q4_rad,q5_rad,q6_rad";
  if (pose) os << ",px_m,py_m,pz_m,qw,qx,qy,qz,pose_from_joints";
  if (checks) os << ",pose_check_m,pose_check_rad";
  for (std::size_t i : external) {
    os << ",e" << (i + 1) << (o.external_axes[i] == rsi::ExternalAxisKind::linear ? "_m" : "_rad");
  }
  os << ",delay\n";
  char cell[64];
  auto put = [&](const char* format, double v) {
    std::snprintf(cell, sizeof cell, format, v);
    os << ',' << cell;
  };
  for (const RsiRow& row : r.rows) {
    std::snprintf(cell, sizeof cell, "%.3f", row.t_s);
    os << cell << ',' << row.ipoc;
    for (double q : row.joints_rad) put("%.12g", q);
    if (pose) {
      for (double p : row.p_base_sensor_m) put("%.12g", p);
      for (double q : row.q_base_sensor_wxyz) put("%.12g", q);
      os << ',' << (row.pose_from_joints ? 1 : 0);
    }
    if (checks) {
      if (row.has_check) {
        put("%.6g", row.check_m);
        put("%.6g", row.check_rad);
      } else {
        os << ",,";
      }
    }
    for (std::size_t i : external) {
      if ((row.external_present & (1u << i)) != 0) {
        put("%.12g", row.external_si[i]);
      } else {
        os << ',';
      }
    }
    os << ',';
    if (row.has_delay) os << row.delay;
    os << '\n';
  }
  return os.str();
}

void write_rsi_recording(const RsiDecodeResult& r, const RsiDecodeOptions& options,
                         const std::filesystem::path& out,
                         const std::vector<std::filesystem::path>& inputs) {
  write_file_atomic(out, rsi_recording_csv(r, options), inputs);
}

std::string rsi_mapping_snippet(const RsiDecodeResult& r, const std::filesystem::path& csv) {
  std::ostringstream os;
  os << "[files.robot]\n"
     << "path = \"" << csv.generic_string() << "\"\n"
     << "time = { column = \"t_s\", unit = \"s\" }\n"
     << "joints = { columns = [\"q1_rad\", \"q2_rad\", \"q3_rad\", \"q4_rad\", \"q5_rad\", "
        "\"q6_rad\"], unit = \"rad\" }\n";
  if (r.all_have_pose && !r.rows.empty()) {
    os << "position = { columns = [\"px_m\", \"py_m\", \"pz_m\"], unit = \"m\" }\n"
       << "orientation = { type = \"quaternion\", columns = [\"qw\", \"qx\", \"qy\", \"qz\"] }\n";
  }
  return os.str();
}

}  // namespace zerog::io
