#pragma once
// The recorder thread's work (proto/rt_config.md, "Recording"): every CycleRecord becomes a row
// of `cycles.csv` (all fields, zerog/formats/cycles_csv.hpp) and, when it is a new robot cycle with
// sensor data, a row of the log `run.csv` (proto/log_format.md, with `run.rig.toml`), so that
// `zerog fit`, `compare` and `diagnose` read the run. Both files grow as `<name>.partial` and are
// renamed at finish(): no half-written file ever carries the final name. Black-box dumps are
// written atomically. Not real-time safe (allocates, writes files); never called from the cycle.
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include "zerog/formats/log.hpp"
#include "zerog/loop/cycle.hpp"

namespace zerog::rt {

/// zerog-rt's files (recordings, black boxes, the summary): owner read/write, group read (the
/// service's group, for the operators), nobody else, whatever the process umask. Folders it
/// creates: 0750.
inline constexpr unsigned kRecordFileMode = 0640;
inline constexpr unsigned kRecordDirMode = 0750;

struct RecorderOptions {
  std::optional<std::filesystem::path> dir;  ///< --record DIR (created if missing); none: no files
  std::filesystem::path blackbox_dir = ".";  ///< black-box dumps when there is no record dir
  formats::Rig rig;                          ///< written beside the log (sample period = cycle)
  /// The log gets temp_C, the F/T sensor's temperature ([ft] thermistor conversion configured);
  /// rows before its first reading, or while it is stale (loop::kTemperatureStale), are skipped
  /// (counted skipped_no_temperature).
  bool temperature = false;
};

struct RecorderCounters {
  std::uint64_t records = 0;                 ///< records taken (= rows of cycles.csv)
  std::uint64_t log_rows = 0;                ///< rows of run.csv
  std::uint64_t skipped_stale = 0;           ///< duplicate/reordered IPOC: no new log row
  std::uint64_t skipped_no_samples = 0;      ///< before the first F/T and IMU sample arrived
  std::uint64_t skipped_no_temperature = 0;  ///< with temp_C: no (fresh) temperature
  std::uint64_t rejected = 0;                ///< rows the log writer refused (non-finite value)
  std::uint64_t black_boxes = 0;             ///< black-box dumps written
};

/// A file written as `<target>.partial`, renamed to `target` by finish(). Buffered.
class PartialFile {
 public:
  PartialFile() = default;
  ~PartialFile();  ///< closes; an unfinished file keeps its .partial name
  PartialFile(const PartialFile&) = delete;
  PartialFile& operator=(const PartialFile&) = delete;

  /// Creates `<target>.partial` (refuses when `target` exists). Throws std::runtime_error.
  void open(const std::filesystem::path& target);
  bool is_open() const { return fd_ >= 0; }
  /// Appends (flushes every 1 MiB). Throws std::runtime_error on a write error.
  void append(const std::string& text);
  /// Flushes, fsyncs, closes and renames to the target. Throws std::runtime_error.
  void finish();
  const std::filesystem::path& target() const { return target_; }

 private:
  void flush();
  int fd_ = -1;
  std::filesystem::path target_;
  std::filesystem::path partial_;
  std::string buffer_;
};

class Recorder {
 public:
  /// Creates the record folder and opens the partial files. Throws std::runtime_error naming the
  /// path and why (e.g. a recording already there).
  explicit Recorder(RecorderOptions options);

  /// Takes one record: a cycles.csv row, and a log row when it is a new cycle with data.
  /// Throws std::runtime_error on a write error (the caller stops recording and reports it).
  void add(const loop::CycleRecord& record);
  /// Writes `blackbox-<cycle>.csv` (comment line, header, the frozen records oldest first) into
  /// the record folder (or blackbox_dir), atomically; returns its path. Throws on failure.
  std::filesystem::path dump_black_box(const loop::Cycle::Box& box);
  /// Renames the partial files into place: the rig first, then the log, then cycles.csv.
  void finish();

  bool recording() const { return options_.dir.has_value(); }
  const RecorderCounters& counters() const { return counters_; }
  std::filesystem::path log_path() const;     ///< DIR/run.csv
  std::filesystem::path cycles_path() const;  ///< DIR/cycles.csv

 private:
  RecorderOptions options_;
  RecorderCounters counters_;
  PartialFile log_;
  PartialFile cycles_;
  formats::LogCsvWriter log_writer_{formats::Columns{.joints = true,
                                                     .specific_force = true,
                                                     .angular_rate = true,
                                                     .temperature = options_.temperature}};
  std::string row_;
  bool seen_ft_ = false, seen_imu_ = false;
};

}  // namespace zerog::rt
