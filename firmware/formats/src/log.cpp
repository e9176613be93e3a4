#include "zerog/formats/log.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <string_view>
#include <system_error>
#include <utility>

#include "zerog/formats/detail/csv_scan.hpp"
#include "zerog/formats/detail/rig_toml.hpp"
#include "zerog/formats/robot_toml.hpp"

namespace zerog::formats {

namespace fs = std::filesystem;

namespace {

std::string location(const fs::path& file, int line, int column) {
  std::string out = file.string();
  if (line > 0) {
    out += ":" + std::to_string(line);
    if (column > 0) out += ":" + std::to_string(column);
  }
  return out + ": ";
}

// ---------------------------------------------------------------------------------------------
// Columns of the log CSV (proto/log_format.md), in the order the writer emits them.
// clang-format off
enum Col : int {
  kT,
  kQ1, kQ2, kQ3, kQ4, kQ5, kQ6,
  kPx, kPy, kPz,
  kQw, kQx, kQy, kQz,
  kImuFx, kImuFy, kImuFz,
  kImuWx, kImuWy, kImuWz,
  kImuDwx, kImuDwy, kImuDwz,
  kFx, kFy, kFz,
  kMx, kMy, kMz,
  kTemp,
  kNumCols
};
// clang-format on

constexpr std::array<std::string_view, kNumCols> kColumnNames = {"t_s",
                                                                 "q1_rad",
                                                                 "q2_rad",
                                                                 "q3_rad",
                                                                 "q4_rad",
                                                                 "q5_rad",
                                                                 "q6_rad",
                                                                 "px_m",
                                                                 "py_m",
                                                                 "pz_m",
                                                                 "qw",
                                                                 "qx",
                                                                 "qy",
                                                                 "qz",
                                                                 "imu_fx_mps2",
                                                                 "imu_fy_mps2",
                                                                 "imu_fz_mps2",
                                                                 "imu_wx_radps",
                                                                 "imu_wy_radps",
                                                                 "imu_wz_radps",
                                                                 "imu_dwx_radps2",
                                                                 "imu_dwy_radps2",
                                                                 "imu_dwz_radps2",
                                                                 "Fx_N",
                                                                 "Fy_N",
                                                                 "Fz_N",
                                                                 "Mx_Nm",
                                                                 "My_Nm",
                                                                 "Mz_Nm",
                                                                 "temp_C"};
static_assert(kColumnNames[kNumCols - 1] == "temp_C" && kColumnNames[kImuDwx] == "imu_dwx_radps2");

struct Group {
  int first;
  int count;
  int required_until;  ///< required in format versions up to this one (0: optional)
};

// Version 1 requires t_s and the position and has one IMU group of six; version 2 makes t_s
// and the position optional and splits the IMU into specific force and angular rate.
constexpr std::array<Group, 10> kGroups = {{
    {kT, 1, 1},
    {kQ1, 6, 0},
    {kPx, 3, 1},
    {kQw, 4, kLogFormatVersion},
    {kImuFx, 3, 0},
    {kImuWx, 3, 0},
    {kImuDwx, 3, 0},
    {kFx, 3, kLogFormatVersion},
    {kMx, 3, kLogFormatVersion},
    {kTemp, 1, 0},
}};

// The oldest format version that can hold a log with these columns.
int version_for(const Columns& c) {
  return c.position && !c.static_rows && c.specific_force == c.angular_rate && !c.angular_accel ? 1
                                                                                                : 2;
}

std::vector<std::string_view> known_column_names() {
  return {kColumnNames.begin(), kColumnNames.end()};
}

constexpr std::string_view kVersionPrefix = "# zerog-log";

template <typename Lines>
int check_version_line(const fs::path& csv, Lines& lines) {
  std::string_view line;
  // Version 1 is the common case; version 2 adds optional time, position and IMU groups.
  const std::string expected = std::string(kVersionPrefix) + " 1' or '" +
                               std::string(kVersionPrefix) + " " +
                               std::to_string(kLogFormatVersion);
  if (!lines.next(line)) {
    throw InputError(csv, 1, 1, "empty file: the first line must be '" + expected + "'");
  }
  if (line.substr(0, kVersionPrefix.size()) != kVersionPrefix) {
    throw InputError(csv, 1, 1,
                     "not a zerog log: the first line must be '" + expected + "', found '" +
                         detail::shorten(line) + "'");
  }
  const std::size_t at = line.find_first_not_of(" \t", kVersionPrefix.size());
  const int column = detail::char_column(line, at == std::string_view::npos ? line.size() : at);
  const std::string_view rest = detail::trim(line.substr(kVersionPrefix.size()));
  int version = 0;
  const auto [ptr, ec] = std::from_chars(rest.data(), rest.data() + rest.size(), version);
  if (rest.empty() || ec != std::errc() || ptr != rest.data() + rest.size()) {
    throw InputError(
        csv, 1, column,
        "bad version line: expected '" + expected + "', found '" + detail::shorten(line) + "'");
  }
  if (version < 1 || version > kLogFormatVersion) {
    throw InputError(csv, 1, column,
                     "log format version " + std::to_string(version) +
                         " is not supported (this zerog reads versions 1 to " +
                         std::to_string(kLogFormatVersion) + ")");
  }
  return version;
}

bool is_comment(std::string_view line) { return !line.empty() && line.front() == '#'; }

void fill_sample(const std::array<double, kNumCols>& v, const Columns& columns, std::size_t row,
                 Sample& s) {
  s.t_s = columns.static_rows ? static_cast<double>(row) : v[kT];
  if (columns.joints) {
    for (int i = 0; i < 6; ++i) s.joints_rad[i] = v[kQ1 + i];
  }
  if (columns.position) s.p_base_sensor_m = {v[kPx], v[kPy], v[kPz]};
  s.q_base_sensor = Eigen::Quaterniond(v[kQw], v[kQx], v[kQy], v[kQz]).normalized();
  if (columns.specific_force) s.specific_force_imu_mps2 = {v[kImuFx], v[kImuFy], v[kImuFz]};
  if (columns.angular_rate) s.angular_rate_imu_radps = {v[kImuWx], v[kImuWy], v[kImuWz]};
  if (columns.angular_accel) s.angular_accel_imu_radps2 = {v[kImuDwx], v[kImuDwy], v[kImuDwz]};
  s.force_sensor_N = {v[kFx], v[kFy], v[kFz]};
  s.torque_sensor_Nm = {v[kMx], v[kMy], v[kMz]};
  if (columns.temperature) s.temperature_C = v[kTemp];
}

// ---------------------------------------------------------------------------------------------
// Writing.

// Values of one sample in column order; absent groups are skipped by the writer.
std::array<double, kNumCols> sample_values(const Sample& s) {
  std::array<double, kNumCols> v{};
  v[kT] = s.t_s;
  for (int i = 0; i < 6; ++i) v[kQ1 + i] = s.joints_rad[i];
  for (int i = 0; i < 3; ++i) {
    v[kPx + i] = s.p_base_sensor_m[i];
    v[kImuFx + i] = s.specific_force_imu_mps2[i];
    v[kImuWx + i] = s.angular_rate_imu_radps[i];
    v[kImuDwx + i] = s.angular_accel_imu_radps2[i];
    v[kFx + i] = s.force_sensor_N[i];
    v[kMx + i] = s.torque_sensor_Nm[i];
  }
  v[kQw] = s.q_base_sensor.w();
  v[kQx] = s.q_base_sensor.x();
  v[kQy] = s.q_base_sensor.y();
  v[kQz] = s.q_base_sensor.z();
  v[kTemp] = s.temperature_C;
  return v;
}

bool column_written(int c, const Columns& columns) {
  if (c == kT) return !columns.static_rows;
  if (c >= kQ1 && c <= kQ6) return columns.joints;
  if (c >= kPx && c <= kPz) return columns.position;
  if (c >= kImuFx && c <= kImuFz) return columns.specific_force;
  if (c >= kImuWx && c <= kImuWz) return columns.angular_rate;
  if (c >= kImuDwx && c <= kImuDwz) return columns.angular_accel;
  if (c == kTemp) return columns.temperature;
  return true;
}

std::string format_log_csv(const Log& log) {
  std::string out;
  out.reserve(64 + log.samples.size() * 16 * kNumCols);
  LogCsvWriter writer(log.columns);
  writer.append_header(out);
  for (const Sample& sample : log.samples) writer.append_row(sample, out);
  return out;
}

std::string toml_string(std::string_view s) {
  std::string out = "\"";
  for (char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (u < 0x20 || u == 0x7F) {
      char buffer[8];
      std::snprintf(buffer, sizeof buffer, "\\u%04X", static_cast<unsigned>(u));
      out += buffer;
    } else {
      out += c;
    }
  }
  return out + "\"";
}

// TOML floats need a '.' or an exponent, else they read back as integers.
std::string toml_float(double v) {
  std::string s = number_text(v);
  if (s.find_first_of(".eE") == std::string::npos) s += ".0";
  return s;
}

void check_rig_finite(const Rig& rig) {
  const auto finite = [](double v) { return std::isfinite(v); };
  const bool ok = finite(rig.sample_period_s) && rig.sample_period_s > 0.0 &&
                  finite(rig.ft_rate_hz) && finite(rig.imu_rate_hz) && finite(rig.floor_z_m) &&
                  finite(rig.imu_sampling.gyro_noise_radps) &&
                  finite(rig.imu_sampling.accel_noise_mps2) && rig.flange_sensor.p_m.allFinite() &&
                  rig.flange_sensor.q.coeffs().allFinite() && rig.sensor_imu.p_m.allFinite() &&
                  rig.sensor_imu.q.coeffs().allFinite();
  if (!ok) {
    throw std::invalid_argument("write_rig: rig '" + rig.name +
                                "' has a non-finite value or sample_period_s <= 0");
  }
  if (rig.robot_model) {
    if (const zerog::Status status = robot::validate(*rig.robot_model); !status.ok())
      throw std::invalid_argument("write_rig: rig '" + rig.name + "': robot: " + status.text());
  }
}

// Rig numbers are few: written exactly (shortest round-trip text).
std::string format_rig(const Rig& rig) {
  check_rig_finite(rig);
  auto transform = [](const char* table, const char* comment, const Transform& t) {
    const Eigen::Quaterniond q = t.q.normalized();
    return std::string("\n[") + table + "]  # " + comment + "\np_m = [" + toml_float(t.p_m.x()) +
           ", " + toml_float(t.p_m.y()) + ", " + toml_float(t.p_m.z()) + "]\nq_wxyz = [" +
           toml_float(q.w()) + ", " + toml_float(q.x()) + ", " + toml_float(q.y()) + ", " +
           toml_float(q.z()) + "]\n";
  };
  std::string out;
  out += "# zerog rig (proto/log_format.md)\n";
  out += "format = \"zerog-rig\"\n";
  out += "version = " + std::to_string(kRigFormatVersion) + "\n";
  out += "name = " + toml_string(rig.name) + "\n";
  // With kinematics the robot is a [robot] table (below): TOML cannot hold both forms.
  if (!rig.robot_model) out += "robot = " + toml_string(rig.robot) + "\n";
  out += "sample_period_s = " + toml_float(rig.sample_period_s) + "\n";
  out += "ft_rate_hz = " + toml_float(rig.ft_rate_hz) + "\n";
  out += "imu_rate_hz = " + toml_float(rig.imu_rate_hz) + "\n";
  out += "floor_z_m = " + toml_float(rig.floor_z_m) + "\n";
  if (!rig.rows_in_recorded_order)
    out += "row_order = \"unknown\"  # a table's rows are not in the order recorded\n";
  out += transform("flange_sensor", "sensor frame S in the flange frame F", rig.flange_sensor);
  out += transform("sensor_imu", "IMU frame I in the sensor frame S", rig.sensor_imu);
  // Only when said: a rig that does not say stays as every rig before the table.
  const ImuSampling& is = rig.imu_sampling;
  if (!(is == ImuSampling{})) {
    out += "\n[imu_sampling]  # how each row's IMU reading was formed, its noise per row\n";
    out += std::string("rows = \"") + to_string(is.rows) + "\"\n";
    out += "gyro_noise_radps = " + toml_float(is.gyro_noise_radps) + "\n";
    out += "accel_noise_mps2 = " + toml_float(is.accel_noise_mps2) + "\n";
  }
  // Inline, whether it came from a table or a robot_file: the log's rig stands alone.
  if (rig.robot_model) out += robot_toml_text("robot", rig.robot, *rig.robot_model);
  const KinematicsRecord& k = rig.kinematics;
  // A logged ω̇ is said too: without the table imu_dw* would read as the gyro's SG derivative.
  if (k.mode != "imu" || k.derived() || k.angular_accel != KinematicsOrigin::imu) {
    out += "\n[kinematics]  # where the IMU columns came from (zerog import)\n";
    out += "mode = " + toml_string(k.mode) + "\n";
    if (k.crossover_hz > 0.0) out += "crossover_hz = " + toml_float(k.crossover_hz) + "\n";
    out += std::string("angular_rate = \"") + to_string(k.angular_rate) + "\"\n";
    out += std::string("specific_force = \"") + to_string(k.specific_force) + "\"\n";
    out += "angular_rate_reason = " + toml_string(k.angular_rate_reason) + "\n";
    out += "specific_force_reason = " + toml_string(k.specific_force_reason) + "\n";
    if (k.derived()) {
      out += "sg_half_width = " + std::to_string(k.sg_half_width) + "\n";
      out += "sg_order = " + std::to_string(k.sg_order) + "\n";
      out += "period_s = " + toml_float(k.period_s) + "\n";
      out += "bandwidth_hz = " + toml_float(k.bandwidth_hz) + "\n";
      out += "lag_s = " + toml_float(k.lag_s) + "\n";
      out += "noise_gain_rate_per_s = " + toml_float(k.noise_gain_rate_per_s) + "\n";
      out += "noise_gain_accel_per_s2 = " + toml_float(k.noise_gain_accel_per_s2) + "\n";
      out += "cutoff_rate_hz = " + toml_float(k.cutoff_rate_hz) + "\n";
      out += "cutoff_accel_hz = " + toml_float(k.cutoff_accel_hz) + "\n";
    }
    out += std::string("angular_accel = \"") + to_string(k.angular_accel) + "\"\n";
    out += "angular_accel_reason = " + toml_string(k.angular_accel_reason) + "\n";
    if (k.accel_sg_half_width > 0) {
      out += "accel_sg_half_width = " + std::to_string(k.accel_sg_half_width) + "\n";
      out += "accel_sg_order = " + std::to_string(k.accel_sg_order) + "\n";
      out += "accel_period_s = " + toml_float(k.accel_period_s) + "\n";
      out += "accel_bandwidth_hz = " + toml_float(k.accel_bandwidth_hz) + "\n";
      out += "accel_noise_gain = " + toml_float(k.accel_noise_gain) + "\n";
      out += "accel_cutoff_hz = " + toml_float(k.accel_cutoff_hz) + "\n";
    }
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Atomic file replacement.

[[noreturn]] void throw_errno(const fs::path& path, const std::string& what, int error) {
  throw std::runtime_error(path.string() + ": " + what + ": " + std::strerror(error));
}

fs::path canonical_or_self(const fs::path& p) {
  std::error_code ec;
  fs::path c = fs::weakly_canonical(p, ec);
  return ec ? fs::absolute(p).lexically_normal() : c;
}

void refuse_inputs(const fs::path& path, const std::vector<fs::path>& inputs) {
  const fs::path target = canonical_or_self(path);
  for (const fs::path& input : inputs) {
    std::error_code ec;
    const bool same = canonical_or_self(input) == target || fs::equivalent(input, path, ec);
    if (same) {
      throw std::runtime_error("refusing to write " + path.string() + ": it is an input (" +
                               input.string() + "); choose another output name");
    }
  }
}

// A file written under a temporary name beside its target and renamed into place by commit().
// Until then the destructor removes the temporary, so a failed run leaves nothing behind.
class PendingFile {
 public:
  PendingFile(fs::path target, const std::string& text, unsigned mode = 0644)
      : target_(std::move(target)) {
    // A constructor that throws runs no destructor: the folders it made go here.
    try {
      write_temporary(text, mode);
    } catch (...) {
      remove_created_folders();
      throw;
    }
  }
  PendingFile(const PendingFile&) = delete;
  PendingFile& operator=(const PendingFile&) = delete;
  ~PendingFile() {
    if (!temp_.empty()) ::unlink(temp_.c_str());
    // A write that did not happen leaves no folder behind either (the innermost first; one that
    // is no longer empty stays).
    if (!committed_) remove_created_folders();
  }

  void commit() {
    if (::rename(temp_.c_str(), target_.c_str()) != 0) throw_errno(target_, "cannot rename", errno);
    temp_.clear();
    committed_ = true;
    fs::path dir = target_.parent_path();
    if (dir.empty()) dir = ".";
    // Make the rename durable; some file systems refuse fsync on folders, which is harmless.
    const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd >= 0) {
      ::fsync(dfd);
      ::close(dfd);
    }
  }

 private:
  void write_temporary(const std::string& text, unsigned mode) {
    // Renaming onto a device, FIFO or folder would replace it (an --out /dev/null once turned
    // this machine's /dev/null into a regular file): only regular files are ever replaced.
    std::error_code ec;
    const fs::file_status st = fs::status(target_, ec);
    if (!ec && fs::exists(st) && !fs::is_regular_file(st)) {
      throw std::runtime_error("refusing to write " + target_.string() +
                               ": it exists and is not a regular file (" +
                               (fs::is_directory(st)        ? "a folder"
                                : fs::is_character_file(st) ? "a character device"
                                : fs::is_block_file(st)     ? "a block device"
                                : fs::is_fifo(st)           ? "a FIFO"
                                : fs::is_socket(st)         ? "a socket"
                                                            : "not a file") +
                               ")");
    }
    fs::path dir = target_.parent_path();
    if (dir.empty()) dir = ".";
    create_missing_folders(dir);
    std::string name = (dir / ("." + target_.filename().string() + ".tmp-XXXXXX")).string();
    const int fd = ::mkstemp(name.data());
    if (fd < 0) throw_errno(target_, "cannot create a temporary file in " + dir.string(), errno);
    temp_ = name;
    int error = 0;
    if (::fchmod(fd, static_cast<mode_t>(mode & 07777)) != 0) error = errno;
    std::size_t done = 0;
    while (error == 0 && done < text.size()) {
      const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
      if (n < 0) {
        if (errno == EINTR) continue;
        error = errno;
      } else {
        done += static_cast<std::size_t>(n);
      }
    }
    if (error == 0 && ::fsync(fd) != 0) error = errno;
    if (::close(fd) != 0 && error == 0) error = errno;
    if (error != 0) {
      ::unlink(temp_.c_str());
      temp_.clear();
      throw_errno(target_, "cannot write", error);
    }
  }

  void remove_created_folders() {
    for (auto it = created_.rbegin(); it != created_.rend(); ++it) ::rmdir(it->c_str());
    created_.clear();
  }

  // The output's folder is made if it is missing (`--out new/folder/run.csv`), outermost first;
  // remembered so that a failed write can take them away again.
  void create_missing_folders(const fs::path& dir) {
    std::vector<fs::path> missing;
    std::error_code ec;
    for (fs::path p = dir; !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
      missing.push_back(p);
      if (p == p.parent_path()) break;
    }
    for (auto it = missing.rbegin(); it != missing.rend(); ++it) {
      if (::mkdir(it->c_str(), 0777) == 0) {
        created_.push_back(*it);
      } else if (errno != EEXIST) {
        throw_errno(target_, "cannot create the folder " + it->string(), errno);
      }
    }
  }

  fs::path target_;
  std::string temp_;
  std::vector<fs::path> created_;
  bool committed_ = false;
};

}  // namespace

// -------------------------------------------------------------------------------------------------

void LogCsvWriter::append_header(std::string& out) const {
  out += std::string(kVersionPrefix) + " " + std::to_string(version_for(columns_)) + "\n";
  bool first = true;
  for (int c = 0; c < kNumCols; ++c) {
    if (!column_written(c, columns_)) continue;
    if (!first) out += ',';
    out += kColumnNames[c];
    first = false;
  }
  out += '\n';
}

// t_s is written with the shortest text that reads back exactly: at 9 digits a long log at
// 1–2 kHz would round neighbouring times onto each other (t = 20000 s keeps only 0.1 ms).
// Everything else gets 9 significant digits, far below any sensor's resolution.
void LogCsvWriter::append_row(const Sample& sample, std::string& out) {
  const auto v = sample_values(sample);
  const std::size_t i = rows_;
  if (!columns_.static_rows && i > 0 && !(v[kT] > previous_t_)) {
    throw std::invalid_argument("write_log: sample " + std::to_string(i) +
                                ": t_s = " + number_text(v[kT]) + " does not increase (previous " +
                                number_text(previous_t_) + ")");
  }
  for (int c = 0; c < kNumCols; ++c) {
    if (column_written(c, columns_) && !std::isfinite(v[c])) {
      throw std::invalid_argument("write_log: sample " + std::to_string(i) + ": " +
                                  std::string(kColumnNames[c]) + " is not finite");
    }
  }
  bool first = true;
  for (int c = 0; c < kNumCols; ++c) {
    if (!column_written(c, columns_)) continue;
    if (!first) out += ',';
    detail::append_number(out, v[c], c == kT ? 0 : 9);
    first = false;
  }
  out += '\n';
  previous_t_ = v[kT];
  ++rows_;
}

InputError::InputError(fs::path file, int line, int column, const std::string& why)
    : std::runtime_error(location(file, line, column) + why),
      file_(std::move(file)),
      line_(line),
      column_(column) {}

const char* to_string(ImuRows rows) {
  switch (rows) {
    case ImuRows::mean:
      return "mean";
    case ImuRows::point:
      return "point";
    case ImuRows::unknown:
      break;
  }
  return "unknown";
}

const char* to_string(KinematicsOrigin origin) {
  switch (origin) {
    case KinematicsOrigin::joints:
      return "joints";
    case KinematicsOrigin::pose:
      return "pose";
    case KinematicsOrigin::logged:
      return "logged";
    case KinematicsOrigin::fused:
      return "fused";
    case KinematicsOrigin::imu:
      break;
  }
  return "imu";
}

fs::path beside_input(const fs::path& input, const std::string& suffix) {
  fs::path out = input;
  out.replace_extension(suffix);
  return out;
}

fs::path rig_path_for(const fs::path& csv) { return beside_input(csv, ".rig.toml"); }

namespace {

// The lines of a file read a buffer at a time: detail::LineCursor's lines (a '\n' ends a line,
// a '\r' before it is dropped, a last line needs no '\n') without the whole text in memory.
class FileLines {
 public:
  FileLines(const fs::path& path, std::size_t buffer_bytes)
      : path_(path), in_(path, std::ios::binary), chunk_(std::max<std::size_t>(buffer_bytes, 1)) {
    if (!in_) throw InputError(path, 0, 0, std::string("cannot open: ") + std::strerror(errno));
    // A file smaller than the buffer is read in one piece of its own size (+1 to see the end):
    // a 2 kB log does not zero a megabyte (the fuzzer's log_csv target ran 1,600 inputs a
    // second with the full buffer).
    std::error_code ec;
    const auto bytes = fs::file_size(path, ec);
    if (!ec) chunk_ = std::min<std::size_t>(chunk_, static_cast<std::size_t>(bytes) + 1);
  }
  /// The next line; valid until the next call.
  bool next(std::string_view& line) {
    for (;;) {
      const std::size_t nl = buffer_.find('\n', pos_);
      if (nl != std::string::npos || (eof_ && pos_ < buffer_.size())) {
        const std::size_t end = nl == std::string::npos ? buffer_.size() : nl;
        line = std::string_view(buffer_).substr(pos_, end - pos_);
        if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
        pos_ = nl == std::string::npos ? buffer_.size() : nl + 1;
        ++number_;
        return true;
      }
      if (eof_) return false;
      buffer_.erase(0, pos_);
      pos_ = 0;
      const std::size_t kept = buffer_.size();
      buffer_.resize(kept + chunk_);
      in_.read(buffer_.data() + kept, static_cast<std::streamsize>(chunk_));
      if (in_.bad()) throw InputError(path_, 0, 0, "read error");
      buffer_.resize(kept + static_cast<std::size_t>(in_.gcount()));
      if (in_.eof()) eof_ = true;
    }
  }
  int number() const { return number_; }  ///< number of the line last returned

 private:
  fs::path path_;
  std::ifstream in_;
  std::size_t chunk_;
  std::string buffer_;
  std::size_t pos_ = 0;
  bool eof_ = false;
  int number_ = 0;
};

}  // namespace

struct LogReader::State {
  State(const fs::path& path, std::size_t buffer_bytes) : csv(path), lines(path, buffer_bytes) {}
  fs::path csv;
  FileLines lines;
  int version = 0;
  Columns columns;
  std::array<int, kNumCols> cell_of{};
  std::vector<int> column_of_cell;  ///< the log column of each header cell
  std::vector<detail::Cell> cells;
  std::size_t rows = 0;
  double previous_t = 0.0;
  int previous_line = 0;
};

LogReader::LogReader(const fs::path& csv, std::size_t buffer_bytes)
    : state_(std::make_unique<State>(csv, buffer_bytes)) {
  State& st = *state_;
  FileLines& lines = st.lines;
  const int version = check_version_line(csv, lines);
  st.version = version;

  std::string_view line;
  bool have_header = false;
  while (lines.next(line)) {
    if (!is_comment(line) && !detail::is_blank(line)) {
      have_header = true;
      break;
    }
  }
  if (!have_header) {
    throw InputError(csv, lines.number() + 1, 1,
                     "no header line (column names) after line " + std::to_string(lines.number()));
  }

  // Header: map every cell to a known column.
  const int header_line = lines.number();
  std::vector<detail::Cell>& cells = st.cells;
  detail::split_cells(line, ',', cells);
  std::array<int, kNumCols>& cell_of = st.cell_of;
  cell_of.fill(-1);
  std::vector<int>& column_of_cell = st.column_of_cell;
  column_of_cell.assign(cells.size(), 0);
  for (std::size_t i = 0; i < cells.size(); ++i) {
    const std::string_view name = detail::trim(cells[i].text);
    const int column = detail::char_column(line, cells[i].offset);
    int c = 0;
    while (c < kNumCols && kColumnNames[c] != name) ++c;
    if (c == kNumCols) {
      std::string why = name.empty() ? std::string("empty column name in the header")
                                     : "unknown column '" + detail::shorten(name) + "'";
      const std::string_view near = detail::closest_name(name, known_column_names());
      if (!near.empty()) why += " (did you mean '" + std::string(near) + "'?)";
      throw InputError(csv, header_line, column,
                       why + "; columns are listed in proto/log_format.md");
    }
    if (cell_of[c] >= 0) {
      throw InputError(csv, header_line, column,
                       "column '" + std::string(name) + "' appears twice (first at column " +
                           std::to_string(detail::char_column(line, cells[cell_of[c]].offset)) +
                           ")");
    }
    cell_of[c] = static_cast<int>(i);
    column_of_cell[i] = c;
  }
  for (const Group& g : kGroups) {
    int present = -1;
    int missing = -1;
    for (int c = g.first; c < g.first + g.count; ++c) {
      if (cell_of[c] >= 0 && present < 0) present = c;
      if (cell_of[c] < 0 && missing < 0) missing = c;
    }
    if (missing < 0) continue;
    if (version <= g.required_until) {
      std::string why = "missing required column '" + std::string(kColumnNames[missing]) + "'";
      if (version < kLogFormatVersion && kLogFormatVersion > g.required_until)
        why += " (optional from format version " + std::to_string(g.required_until + 1) +
               " on: write '# zerog-log " + std::to_string(kLogFormatVersion) + "' on line 1)";
      throw InputError(csv, header_line, 1, why);
    }
    if (present >= 0) {
      throw InputError(csv, header_line, detail::char_column(line, cells[cell_of[present]].offset),
                       "incomplete column group: '" + std::string(kColumnNames[present]) +
                           "' is present but '" + std::string(kColumnNames[missing]) +
                           "' is missing (give all of " + std::string(kColumnNames[g.first]) +
                           " … " + std::string(kColumnNames[g.first + g.count - 1]) + " or none)");
    }
  }

  Columns& columns = st.columns;
  columns.joints = cell_of[kQ1] >= 0;
  columns.specific_force = cell_of[kImuFx] >= 0;
  columns.angular_rate = cell_of[kImuWx] >= 0;
  columns.angular_accel = cell_of[kImuDwx] >= 0;
  columns.temperature = cell_of[kTemp] >= 0;
  columns.position = cell_of[kPx] >= 0;
  columns.static_rows = cell_of[kT] < 0;
  if (version == 1 && columns.specific_force != columns.angular_rate) {
    const int present = columns.specific_force ? kImuFx : kImuWx;
    const int missing = columns.specific_force ? kImuWx : kImuFx;
    throw InputError(csv, header_line, detail::char_column(line, cells[cell_of[present]].offset),
                     "incomplete column group: '" + std::string(kColumnNames[present]) +
                         "' is present but '" + std::string(kColumnNames[missing]) +
                         "' is missing (format version 1 needs all six IMU columns or none; "
                         "from version 2 on each group of three may come alone: write '# "
                         "zerog-log 2' on line 1)");
  }
  if (columns.angular_accel && (version == 1 || !columns.angular_rate)) {
    throw InputError(csv, header_line, detail::char_column(line, cells[cell_of[kImuDwx]].offset),
                     version == 1 ? std::string("'imu_dwx_radps2' (angular acceleration) is a "
                                                "format version 2 column: write '# zerog-log 2' "
                                                "on line 1")
                                  : std::string("'imu_dwx_radps2' (angular acceleration) needs "
                                                "the angular rate imu_wx_radps … imu_wz_radps "
                                                "beside it: add those columns, or drop the "
                                                "imu_dw*_radps2 columns"));
  }
}

LogReader::~LogReader() = default;
LogReader::LogReader(LogReader&&) noexcept = default;
LogReader& LogReader::operator=(LogReader&&) noexcept = default;

const Columns& LogReader::columns() const { return state_->columns; }
int LogReader::version() const { return state_->version; }
std::size_t LogReader::rows() const { return state_->rows; }
Rig LogReader::read_rig() const { return formats::read_rig(rig_path_for(state_->csv)); }

std::size_t LogReader::read(std::vector<Sample>& out, std::size_t max_rows) {
  State& st = *state_;
  const fs::path& csv = st.csv;
  const Columns& columns = st.columns;
  const std::array<int, kNumCols>& cell_of = st.cell_of;
  const std::vector<int>& column_of_cell = st.column_of_cell;
  std::vector<detail::Cell>& cells = st.cells;
  std::array<double, kNumCols> values{};
  const std::size_t num_cells = column_of_cell.size();
  std::size_t appended = 0;
  std::string_view line;
  while (appended < max_rows && st.lines.next(line)) {
    if (is_comment(line) || detail::is_blank(line)) continue;
    const int n = st.lines.number();
    detail::split_cells(line, ',', cells);
    if (cells.size() > num_cells) {
      throw InputError(csv, n, detail::char_column(line, cells[num_cells].offset),
                       "row has " + std::to_string(cells.size()) + " cells but the header has " +
                           std::to_string(num_cells) + " (extra cell after column '" +
                           std::string(kColumnNames[column_of_cell[num_cells - 1]]) + "')");
    }
    if (cells.size() < num_cells) {
      throw InputError(csv, n, detail::char_column(line, line.size()),
                       "row has " + std::to_string(cells.size()) + " cells but the header has " +
                           std::to_string(num_cells) + " (column '" +
                           std::string(kColumnNames[column_of_cell[cells.size()]]) +
                           "' and after are missing)");
    }
    for (std::size_t i = 0; i < num_cells; ++i) {
      const int c = column_of_cell[i];
      const auto status = detail::parse_number(cells[i].text, values[c]);
      if (status == detail::NumberStatus::ok) continue;
      const std::string why = detail::number_error(status, cells[i].text, kColumnNames[c]);
      throw InputError(csv, n, detail::char_column(line, cells[i].offset), why);
    }
    if (!columns.static_rows && st.rows > 0 && !(values[kT] > st.previous_t)) {
      const double before = st.previous_t;
      throw InputError(csv, n, detail::char_column(line, cells[cell_of[kT]].offset),
                       std::string("time ") +
                           (values[kT] < before ? "goes backwards" : "stands still") + " at line " +
                           std::to_string(n) + ": t=" + number_text(values[kT]) + " after " +
                           number_text(before) + " (line " + std::to_string(st.previous_line) +
                           "); t_s must increase strictly");
    }
    const double norm = std::sqrt(values[kQw] * values[kQw] + values[kQx] * values[kQx] +
                                  values[kQy] * values[kQy] + values[kQz] * values[kQz]);
    if (std::abs(norm - 1.0) > 1e-3) {
      throw InputError(csv, n, detail::char_column(line, cells[cell_of[kQw]].offset),
                       "quaternion (qw, qx, qy, qz) has norm " + number_text(norm) +
                           ", off from 1 by more than 1e-3");
    }
    fill_sample(values, columns, st.rows, out.emplace_back());
    st.previous_t = out.back().t_s;
    st.previous_line = n;
    ++st.rows;
    ++appended;
  }
  return appended;
}

Log read_log(const fs::path& csv) {
  LogReader reader(csv);
  Log log;
  log.columns = reader.columns();
  std::size_t cells = 0;
  for (int c = 0; c < kNumCols; ++c) cells += column_written(c, log.columns) ? 1 : 0;
  std::error_code ec;
  const auto bytes = fs::file_size(csv, ec);
  if (!ec) log.samples.reserve(static_cast<std::size_t>(bytes) / (cells * 8 + 1));
  while (reader.read(log.samples, std::numeric_limits<std::size_t>::max()) > 0) {
  }
  log.rig = reader.read_rig();
  return log;
}

void write_log(const Log& log, const fs::path& csv, const std::vector<fs::path>& inputs) {
  const fs::path rig = rig_path_for(csv);
  refuse_inputs(csv, inputs);
  refuse_inputs(rig, inputs);
  const std::string csv_text = format_log_csv(log);
  const std::string rig_text = format_rig(log.rig);
  PendingFile csv_file(csv, csv_text);
  PendingFile rig_file(rig, rig_text);
  // The rig goes first: whoever sees the new samples also sees their rig.
  rig_file.commit();
  csv_file.commit();
}

void write_rig(const Rig& rig, const fs::path& toml, const std::vector<fs::path>& inputs,
               unsigned mode) {
  write_file_atomic(toml, format_rig(rig), inputs, mode);
}

void write_file_atomic(const fs::path& path, const std::string& text,
                       const std::vector<fs::path>& inputs, unsigned mode) {
  refuse_inputs(path, inputs);
  PendingFile file(path, text, mode);
  file.commit();
}

// -------------------------------------------------------------------------------------------------
// The rig TOML.

namespace detail {

Transform transform_of(const TomlTable& t) {
  Transform out;
  out.p_m = t.vector3("p_m");
  const auto q = t.numbers("q_wxyz", 4);
  const Eigen::Quaterniond quat(q[0], q[1], q[2], q[3]);
  if (std::abs(quat.norm() - 1.0) > 1e-3)
    t.fail("q_wxyz", "has norm " + number_text(quat.norm()) + ", off from 1 by more than 1e-3");
  out.q = quat.normalized();
  return out;
}

namespace {

Transform transform_from_toml(const TomlTable& parent, std::string_view key) {
  return transform_of(
      TomlTable(parent.table(key), parent.file(), parent.name(key) + ".", {"p_m", "q_wxyz"}));
}

// The robot: `robot = "NAME"` (the name only), a [robot] table (name and DH chain), or
// `robot_file = "PATH"` (a calib/robots/*.robot.toml, relative to this file; with an optional
// `robot = "NAME"` that overrides the file's name). The rig's flange_sensor joins the chain.
void read_robot(const TomlTable& t, Rig& rig) {
  const toml::node* robot = t.find("robot");
  const toml::node* file = t.find("robot_file");
  if (robot != nullptr && robot->is_table()) {
    if (file != nullptr)
      t.fail("robot_file",
             "give either a [robot] table or robot_file, not both (the table describes the arm)");
    const toml::table& table = *robot->as_table();
    rig.robot = table["name"].value_or(std::string("unnamed robot"));
    rig.robot_model = robot_from_toml(table, t.file(), rig.flange_sensor, t.name("robot") + ".");
    return;
  }
  if (robot != nullptr && !robot->is_string())
    t.fail("robot",
           "must be the robot's name (a string, e.g. \"KR 210 R2700\") or a [robot] table with "
           "its DH chain (proto/robot_kinematics.md)");
  if (file == nullptr) {
    rig.robot = t.string("robot");  // a missing key is named here
    return;
  }
  const fs::path given = t.string("robot_file");
  const fs::path path = given.is_absolute() ? given : t.file().parent_path() / given;
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    t.fail("robot_file", "robot file not found: " + path.string() +
                             " (a relative path is taken from the folder of " +
                             t.file().filename().string() + "; examples in calib/robots/)");
  const RobotDescription d = read_robot_file(path, rig.flange_sensor);
  rig.robot = robot != nullptr ? t.string("robot") : d.name.empty() ? "unnamed robot" : d.name;
  rig.robot_model = d.model;
}

KinematicsOrigin origin_from_toml(const TomlTable& k, std::string_view key) {
  const std::string v = k.optional_string(key, "imu");
  // "logged" only for the angular acceleration: imu_w* and imu_f* logged are "imu".
  const bool accel = key == "angular_accel";
  for (KinematicsOrigin o :
       {KinematicsOrigin::imu, KinematicsOrigin::joints, KinematicsOrigin::pose,
        KinematicsOrigin::logged, KinematicsOrigin::fused}) {
    if (v == to_string(o) && (accel || o != KinematicsOrigin::logged)) return o;
  }
  k.fail(key, std::string("must be \"imu\", \"joints\", \"fused\"") +
                  (accel ? ", \"pose\" or \"logged\"" : " or \"pose\"") + ", is \"" + v + "\"");
}

ImuSampling imu_sampling_from_toml(const TomlTable& t) {
  const TomlTable k = t.sub_table("imu_sampling", {"rows", "gyro_noise_radps", "accel_noise_mps2"});
  ImuSampling s;
  const std::string rows = k.optional_string("rows", "unknown");
  bool known = false;
  for (ImuRows r : {ImuRows::unknown, ImuRows::mean, ImuRows::point}) {
    if (rows == to_string(r)) s.rows = r, known = true;
  }
  if (!known) k.fail("rows", "must be \"point\", \"mean\" or \"unknown\", is \"" + rows + "\"");
  s.gyro_noise_radps = k.optional_number("gyro_noise_radps", 0.0, {0.0, false});
  s.accel_noise_mps2 = k.optional_number("accel_noise_mps2", 0.0, {0.0, false});
  return s;
}

KinematicsRecord kinematics_from_toml(const TomlTable& t) {
  const TomlTable k = t.sub_table("kinematics", {"mode",
                                                 "angular_rate",
                                                 "specific_force",
                                                 "angular_rate_reason",
                                                 "specific_force_reason",
                                                 "sg_half_width",
                                                 "sg_order",
                                                 "period_s",
                                                 "bandwidth_hz",
                                                 "lag_s",
                                                 "noise_gain_rate_per_s",
                                                 "noise_gain_accel_per_s2",
                                                 "cutoff_rate_hz",
                                                 "cutoff_accel_hz",
                                                 "angular_accel",
                                                 "angular_accel_reason",
                                                 "accel_sg_half_width",
                                                 "accel_sg_order",
                                                 "accel_period_s",
                                                 "accel_bandwidth_hz",
                                                 "accel_noise_gain",
                                                 "accel_cutoff_hz",
                                                 "crossover_hz"});
  KinematicsRecord r;
  r.mode = k.optional_string("mode", "imu");
  if (r.mode != "imu" && r.mode != "robot" && r.mode != "auto" && r.mode != "fused")
    k.fail("mode", "must be \"imu\", \"robot\", \"auto\" or \"fused\", is \"" + r.mode + "\"");
  r.crossover_hz = k.optional_number("crossover_hz", 0.0, NumberRange{0.0, false});
  r.angular_rate = origin_from_toml(k, "angular_rate");
  r.specific_force = origin_from_toml(k, "specific_force");
  r.angular_rate_reason = k.optional_string("angular_rate_reason", "");
  r.specific_force_reason = k.optional_string("specific_force_reason", "");
  r.sg_half_width = static_cast<int>(k.optional_integer("sg_half_width", 0, 0, 100000));
  r.sg_order = static_cast<int>(k.optional_integer("sg_order", 0, 0, 10));
  const NumberRange non_negative{0.0, false};
  r.period_s = k.optional_number("period_s", 0.0, non_negative);
  r.bandwidth_hz = k.optional_number("bandwidth_hz", 0.0, non_negative);
  r.lag_s = k.optional_number("lag_s", 0.0, non_negative);
  r.noise_gain_rate_per_s = k.optional_number("noise_gain_rate_per_s", 0.0, non_negative);
  r.noise_gain_accel_per_s2 = k.optional_number("noise_gain_accel_per_s2", 0.0, non_negative);
  r.cutoff_rate_hz = k.optional_number("cutoff_rate_hz", 0.0, non_negative);
  r.cutoff_accel_hz = k.optional_number("cutoff_accel_hz", 0.0, non_negative);
  r.angular_accel = origin_from_toml(k, "angular_accel");
  r.angular_accel_reason = k.optional_string("angular_accel_reason", "");
  r.accel_sg_half_width = static_cast<int>(k.optional_integer("accel_sg_half_width", 0, 0, 100000));
  r.accel_sg_order = static_cast<int>(k.optional_integer("accel_sg_order", 0, 0, 10));
  r.accel_period_s = k.optional_number("accel_period_s", 0.0, non_negative);
  r.accel_bandwidth_hz = k.optional_number("accel_bandwidth_hz", 0.0, non_negative);
  r.accel_noise_gain = k.optional_number("accel_noise_gain", 0.0, non_negative);
  r.accel_cutoff_hz = k.optional_number("accel_cutoff_hz", 0.0, non_negative);
  return r;
}

}  // namespace

Rig rig_from_toml(const toml::table& table, const fs::path& file, bool embedded,
                  const std::string& key_prefix, bool* has_period) {
  const TomlTable t(table, file, key_prefix,
                    {"format", "version", "name", "robot", "robot_file", "sample_period_s",
                     "ft_rate_hz", "imu_rate_hz", "floor_z_m", "flange_sensor", "sensor_imu",
                     "kinematics", "imu_sampling", "row_order"});
  if (!embedded || t.find("format") != nullptr) {
    const std::string format = t.string("format");
    if (format != "zerog-rig") t.fail("format", "must be \"zerog-rig\", is \"" + format + "\"");
  }
  if (!embedded || t.find("version") != nullptr) {
    const std::int64_t version = t.integer("version");
    if (version != kRigFormatVersion) {
      throw_at(file, t.require("version").source(),
               "rig version " + std::to_string(version) +
                   " is not supported (this zerog reads version " +
                   std::to_string(kRigFormatVersion) + ")");
    }
  }
  Rig rig;
  rig.name = t.string("name");
  const bool period_given = !embedded || t.find("sample_period_s") != nullptr;
  if (period_given) rig.sample_period_s = t.number("sample_period_s", {0.0, true});
  if (has_period != nullptr) *has_period = period_given;
  rig.ft_rate_hz = t.optional_number("ft_rate_hz", 0.0, {0.0, false});
  rig.imu_rate_hz = t.optional_number("imu_rate_hz", 0.0, {0.0, false});
  rig.floor_z_m = t.optional_number("floor_z_m", 0.0);
  const std::string row_order = t.optional_string("row_order", "recorded");
  if (row_order != "recorded" && row_order != "unknown")
    t.fail("row_order",
           "must be \"recorded\" (a table's rows in the order they were recorded) "
           "or \"unknown\", is \"" +
               row_order + "\"");
  rig.rows_in_recorded_order = row_order == "recorded";
  rig.flange_sensor = transform_from_toml(t, "flange_sensor");
  rig.sensor_imu = transform_from_toml(t, "sensor_imu");
  read_robot(t, rig);
  if (t.find("kinematics") != nullptr) rig.kinematics = kinematics_from_toml(t);
  if (t.find("imu_sampling") != nullptr) rig.imu_sampling = imu_sampling_from_toml(t);
  return rig;
}

}  // namespace detail

Rig read_rig(const fs::path& toml) {
  std::error_code ec;
  if (!fs::exists(toml, ec)) {
    throw InputError(toml, 0, 0,
                     "rig file missing (a log NAME.csv needs its rig NAME.rig.toml beside it)");
  }
  const toml::table table = parse_toml_file(toml);
  return detail::rig_from_toml(table, toml, false, "", nullptr);
}

}  // namespace zerog::formats
