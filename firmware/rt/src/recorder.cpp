#include "zerog/rt/recorder.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <system_error>

#include "zerog/formats/cycles_csv.hpp"

namespace zerog::rt {

namespace fs = std::filesystem;

namespace {

constexpr std::size_t kFlushBytes = 1 << 20;

[[noreturn]] void fail(const fs::path& path, const std::string& what, int error) {
  throw std::runtime_error(path.string() + ": " + what + ": " + std::strerror(error));
}

void sync_dir(const fs::path& file) {
  fs::path dir = file.parent_path();
  if (dir.empty()) dir = ".";
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

}  // namespace

PartialFile::~PartialFile() {
  if (fd_ >= 0) {
    try {
      flush();
    } catch (const std::exception&) {  // best effort: the .partial shows it was not finished
    }
    ::close(fd_);
  }
}

void PartialFile::open(const fs::path& target) {
  std::error_code ec;
  if (fs::exists(target, ec)) {
    throw std::runtime_error(target.string() +
                             ": exists already; zerog-rt never writes over a recording (choose "
                             "another --record folder)");
  }
  target_ = target;
  partial_ = target;
  partial_ += ".partial";
  fd_ = ::open(partial_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd_ < 0) fail(partial_, "cannot create", errno);
  if (::fchmod(fd_, kRecordFileMode) != 0) fail(partial_, "cannot set its mode", errno);
  buffer_.reserve(kFlushBytes + 64 * 1024);
}

void PartialFile::append(const std::string& text) {
  buffer_ += text;
  if (buffer_.size() >= kFlushBytes) flush();
}

void PartialFile::flush() {
  std::size_t done = 0;
  while (done < buffer_.size()) {
    const ssize_t n = ::write(fd_, buffer_.data() + done, buffer_.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int error = errno;
      buffer_.clear();
      fail(partial_, "cannot write", error);
    }
    done += static_cast<std::size_t>(n);
  }
  buffer_.clear();
}

void PartialFile::finish() {
  if (fd_ < 0) return;
  flush();
  if (::fsync(fd_) != 0) fail(partial_, "cannot fsync", errno);
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) fail(partial_, "cannot close", errno);
  if (::rename(partial_.c_str(), target_.c_str()) != 0) fail(target_, "cannot rename", errno);
  sync_dir(target_);
}

Recorder::Recorder(RecorderOptions options) : options_(std::move(options)) {
  if (!options_.dir) return;
  const fs::path& dir = *options_.dir;
  std::error_code ec;
  const bool existed = fs::exists(dir, ec);
  fs::create_directories(dir, ec);
  if (!ec && !existed) {
    fs::permissions(dir, static_cast<fs::perms>(kRecordDirMode), fs::perm_options::replace, ec);
  }
  if (ec || !fs::is_directory(dir)) {
    throw std::runtime_error(dir.string() + ": cannot create the record folder" +
                             (ec ? " (" + ec.message() + ")" : std::string(" (not a folder)")));
  }
  if (fs::exists(formats::rig_path_for(log_path()), ec)) {
    throw std::runtime_error(formats::rig_path_for(log_path()).string() +
                             ": exists already; zerog-rt never writes over a recording (choose "
                             "another --record folder)");
  }
  log_.open(log_path());
  cycles_.open(cycles_path());
  row_.reserve(4096);
  row_.clear();
  log_writer_.append_header(row_);
  log_.append(row_);
  row_.clear();
  formats::append_record_header(row_);
  cycles_.append(row_);
}

fs::path Recorder::log_path() const {
  return options_.dir ? *options_.dir / "run.csv" : fs::path();
}
fs::path Recorder::cycles_path() const {
  return options_.dir ? *options_.dir / "cycles.csv" : fs::path();
}

void Recorder::add(const loop::CycleRecord& r) {
  ++counters_.records;
  if (!options_.dir) return;
  row_.clear();
  formats::append_record_row(r, row_);
  cycles_.append(row_);

  if (r.ft_samples > 0) seen_ft_ = true;
  if (r.imu_samples > 0) seen_imu_ = true;
  if ((r.flags & loop::kIpocStale) != 0) {
    ++counters_.skipped_stale;
    return;
  }
  if (!seen_ft_ || !seen_imu_) {
    ++counters_.skipped_no_samples;
    return;
  }
  if (options_.temperature && !r.temperature_measured) {
    ++counters_.skipped_no_temperature;  // temp_C would be the configured guess, not a reading
    return;
  }
  formats::Sample s;
  s.t_s = r.t_s;
  s.temperature_C = r.temperature_C;  // °C, the log's unit for temp_C (written with the column)
  s.joints_rad = r.joints_rad;
  s.p_base_sensor_m = r.p_base_sensor_m;
  s.q_base_sensor = r.q_base_sensor;
  s.specific_force_imu_mps2 = Eigen::Vector3d(r.specific_force_imu.data());
  s.angular_rate_imu_radps = Eigen::Vector3d(r.rate_imu.data());
  s.force_sensor_N =
      Eigen::Vector3d(r.wrench_measured[0], r.wrench_measured[1], r.wrench_measured[2]);
  s.torque_sensor_Nm =
      Eigen::Vector3d(r.wrench_measured[3], r.wrench_measured[4], r.wrench_measured[5]);
  row_.clear();
  try {
    log_writer_.append_row(s, row_);
  } catch (const std::invalid_argument&) {
    ++counters_.rejected;
    return;
  }
  log_.append(row_);
  ++counters_.log_rows;
}

fs::path Recorder::dump_black_box(const loop::Cycle::Box& box) {
  const fs::path dir = options_.dir ? *options_.dir : options_.blackbox_dir;
  const loop::CycleRecord* last = box.size() > 0 ? &box.at(box.size() - 1) : nullptr;
  const std::uint64_t cycle = last != nullptr ? last->cycle : 0;
  const fs::path path = dir / ("blackbox-" + std::to_string(cycle) + ".csv");
  std::string text = "# zerog-rt black box: " + std::to_string(box.size()) +
                     " cycles, oldest first; fault " +
                     (last != nullptr ? loop::fault_name(last->fault) : "none") + " at cycle " +
                     std::to_string(cycle) + " (proto/loop.md)\n";
  formats::append_record_header(text);
  for (std::size_t i = 0; i < box.size(); ++i) formats::append_record_row(box.at(i), text);
  formats::write_file_atomic(path, text, {}, kRecordFileMode);
  ++counters_.black_boxes;
  return path;
}

void Recorder::finish() {
  if (!options_.dir) return;
  formats::write_rig(options_.rig, formats::rig_path_for(log_path()), {}, kRecordFileMode);
  log_.finish();
  cycles_.finish();
}

}  // namespace zerog::rt
