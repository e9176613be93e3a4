#pragma once
// `zerog import`: turns a user's own recordings — one or several delimited text files, recorded
// at any rates and in common units — into a zerog log (proto/log_format.md). A TOML mapping file
// (proto/import_mapping.md) names the files, their columns and units; all files are merged onto
// the time base of one "master" file by linear interpolation (slerp for orientations). A single
// file without a time column is a static table: every row an independent held pose.
#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "zerog/formats/log.hpp"

namespace zerog::io {

inline constexpr int kImportMappingVersion = 1;

/// What happened to one input file.
struct ImportFileReport {
  std::string name;            ///< the file's name in the mapping ([files.NAME])
  std::filesystem::path path;  ///< resolved path of the data file
  bool master = false;
  std::size_t rows_read = 0;   ///< data rows read
  double t_first_s = 0.0;      ///< first time stamp, s (unit converted, time offset applied)
  double t_last_s = 0.0;       ///< last time stamp, s
  double time_offset_s = 0.0;  ///< offset added to the file's time stamps, s
  // Master rows this file cannot cover (a row may be counted by several files):
  std::size_t master_rows_before = 0;  ///< master time before this file's first sample
  std::size_t master_rows_after = 0;   ///< master time after this file's last sample
  std::size_t master_rows_in_gap = 0;  ///< between two samples further apart than max_gap_s
  /// A static table joined by pose index: master rows whose index this file lacks, and this
  /// file's rows whose index the master lacks (not used).
  std::size_t master_rows_unmatched = 0;
  std::size_t rows_unused = 0;
};

/// The summary of an import: rows in and out per file, rows dropped and why.
struct ImportReport {
  std::vector<ImportFileReport> files;  ///< master first
  std::size_t master_rows = 0;          ///< rows of the master file
  std::size_t rows_out = 0;             ///< rows of the log (master rows covered by every file)
  bool static_rows = false;             ///< no time column: rows are static samples
  std::string pose_index;               ///< static files joined by this column ("" = row by row)
  std::string rig_source;               ///< where the rig came from, for the summary
  /// What the mapped joints fed (the pose, the kinematics) and whether the log holds them (only
  /// with 6 joints: q1_rad..q6_rad), for the summary.
  std::string joints;
  /// Where the IMU columns came from (kinematics = …) and the differentiator, for the summary.
  std::string kinematics;
  /// A few lines of plain text for the console.
  std::string summary() const;
};

struct ImportResult {
  formats::Log log;
  ImportReport report;
  /// Every file the import read (mapping, data files, rig file): never to be overwritten.
  std::vector<std::filesystem::path> inputs;
};

/// Reads the mapping and every file it names, converts units to SI and merges all files onto
/// the master's time base. Master rows outside the time span of another file are dropped and
/// counted in the report. `rig_file`, if given, replaces the mapping's rig.
/// Throws InputError (file, line, column) for any problem in the mapping or the data, and
/// std::runtime_error if no master row survives.
ImportResult import_recordings(const std::filesystem::path& mapping,
                               const std::optional<std::filesystem::path>& rig_file = std::nullopt);

/// import_recordings(), then write_log() of the result to `out_csv` (and its rig sidecar)
/// atomically; refuses to write over any input.
ImportReport import_to_log(const std::filesystem::path& mapping,
                           const std::filesystem::path& out_csv,
                           const std::optional<std::filesystem::path>& rig_file = std::nullopt);

}  // namespace zerog::io
