#pragma once
// Strict reading of zerog's TOML files: the rig (proto/log_format.md), the import mapping
// (proto/import_mapping.md), zerog-emu's scenario (proto/emulator.md) and zerog-rt's
// configuration (proto/rt_config.md). Unknown keys are errors (with the closest known key as a
// suggestion), every value is checked for its type and range, and every error names the file,
// the line and column, the dotted key and why. Start-up and host code only: allocates and
// throws; not real-time safe.
#include <toml++/toml.h>

#include <Eigen/Core>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "zerog/formats/log.hpp"

namespace zerog::formats {

/// A bad key or value in a TOML file. what() reads `FILE:LINE:COLUMN: 'KEY' why`, e.g.
/// `r.rig.toml:5:19: 'sample_period_s' must be > 0, is 0`; key() and reason() keep the dotted key
/// and the reason apart, for programs that word it `KEY: why` (zerog-rt's ConfigError). A
/// position the TOML parser does not know is reported as 1:1.
class TomlError : public InputError {
 public:
  TomlError(std::filesystem::path file, int line, int column, std::string key, std::string reason,
            const std::string& message);
  /// The dotted key, e.g. "robot.cycle_ms" or "body.inertia_kgm2[2]"; "" for the file as a whole
  /// (TOML syntax).
  const std::string& key() const { return key_; }
  /// Why, without the key: "must be an integer", "unknown key (did you mean 'robot.cycle_ms'?)".
  const std::string& reason() const { return reason_; }

 private:
  std::string key_;
  std::string reason_;
};

/// Throws InputError(file, line, column of the start of `where`, why); 1:1 if the position is
/// unknown. For messages that are not about one key (TomlTable::fail is).
[[noreturn]] void throw_at(const std::filesystem::path& file, const toml::source_region& where,
                           const std::string& why);

/// Parses TOML text; a syntax error becomes TomlError (key "", reason "TOML syntax: …") at the
/// parser's line and column. `file` names the text in messages.
toml::table parse_toml(std::string_view text, const std::filesystem::path& file);
/// Reads and parses a TOML file: InputError if it cannot be read, TomlError for its syntax.
toml::table parse_toml_file(const std::filesystem::path& file);

/// `v` as the shortest text that reads back exactly, independent of the locale ("0.012", "500").
std::string number_text(double v);

/// The numbers a value may take: [lowest, highest], either end excluded when its flag says so;
/// an infinite end is no limit. Default: any finite number.
struct NumberRange {
  double lowest = -HUGE_VAL;
  bool lowest_excluded = false;
  double highest = HUGE_VAL;
  bool highest_excluded = false;

  bool contains(double v) const;
  /// "> 0", ">= 0", "< 1", "<= 1", "in (0, 2000]", or "" when there is no limit.
  std::string text() const;
};

/// One table of a TOML file and the keys it may have. Constructing it rejects unknown keys; each
/// accessor checks the value's type and range. Every error throws TomlError at the offending key
/// or value (at the table's position for a missing key), naming the dotted key
/// (`prefix` + key). A table may be absent (sub_table of a key that is not there): then every
/// key is absent, and a required one is reported as missing with its table.
class TomlTable {
 public:
  /// `table` read with its keys named `prefix` + key in messages ("" for the file's top level,
  /// "robot." for [robot], "push[1]." for the first [[push]]). Any key not in `known` is an
  /// error; `keys_doc` (e.g. "proto/rt_config.md"), if given, is named in that error as the list
  /// of the keys, and is passed on to sub-tables. `table` must outlive this object.
  TomlTable(const toml::table& table, std::filesystem::path file, std::string prefix,
            const std::vector<std::string_view>& known, std::string_view keys_doc = {});

  /// False for a sub-table that is not in the file.
  bool present() const { return table_ != nullptr; }
  /// The value of `key`, or nullptr if it is not there.
  const toml::node* find(std::string_view key) const;
  /// The value of `key`; a missing key is an error at the table's position.
  const toml::node& require(std::string_view key) const;

  /// The table under `key` with its allowed keys; absent (present() false) if `key` is not
  /// there, an error if it is not a table.
  TomlTable sub_table(std::string_view key, const std::vector<std::string_view>& known) const;
  /// The table under `key`, required.
  const toml::table& table(std::string_view key) const;

  std::string string(std::string_view key) const;
  /// The string under `key`, or `fallback` if it is not there.
  std::string optional_string(std::string_view key, const std::string& fallback) const;
  /// A list of `count` strings (column names); `count` = 0 accepts any non-empty length.
  std::vector<std::string> strings(std::string_view key, std::size_t count) const;
  /// A non-empty path; a relative one is taken from the TOML file's folder.
  std::filesystem::path path(std::string_view key) const;

  bool boolean(std::string_view key) const;
  bool optional_boolean(std::string_view key, bool fallback) const;

  std::int64_t integer(std::string_view key) const;
  /// An integer in [lowest, highest].
  std::int64_t integer(std::string_view key, std::int64_t lowest, std::int64_t highest) const;
  std::int64_t optional_integer(std::string_view key, std::int64_t fallback, std::int64_t lowest,
                                std::int64_t highest) const;

  /// `node` (the value of `key` or an element of it) as a finite number.
  double number(const toml::node& node, std::string_view key) const;
  /// A finite number in `range`.
  double number(std::string_view key, const NumberRange& range) const;
  /// A finite number >= `lowest` (> `lowest` if `exclusive`).
  double number(std::string_view key, double lowest, bool exclusive) const;
  double optional_number(std::string_view key, double fallback,
                         const NumberRange& range = {}) const;

  /// A list of `count` finite numbers; a bad element is named `key[i]`.
  std::vector<double> numbers(std::string_view key, std::size_t count) const;
  /// A list of 3 finite numbers.
  Eigen::Vector3d vector3(std::string_view key) const;
  Eigen::Vector3d optional_vector3(std::string_view key, const Eigen::Vector3d& fallback) const;
  /// A 3×3 array of finite numbers, row by row ([[a, b, c], [d, e, f], [g, h, i]]); a bad row
  /// is named `key[r]`, a bad element `key[r][c]`. `explain` is appended to the shape error
  /// (units, an example).
  Eigen::Matrix3d matrix3(std::string_view key, std::string_view explain = {}) const;

  /// The dotted name of `key` in messages: prefix + key ("files.ft.force").
  std::string name(std::string_view key) const { return prefix_ + std::string(key); }
  const std::filesystem::path& file() const { return file_; }
  /// Where the table starts (for an absent one: where its parent starts).
  const toml::source_region& where() const { return where_; }
  /// Where `key`'s value is, or where the table starts if `key` is not there.
  const toml::source_region& where(std::string_view key) const;

  /// Throws TomlError at `where` for `key` (named with the prefix): "'KEY' reason".
  [[noreturn]] void fail(std::string_view key, const toml::source_region& where,
                         const std::string& reason) const;
  /// The same at where(key).
  [[noreturn]] void fail(std::string_view key, const std::string& reason) const;

 private:
  TomlTable(std::filesystem::path file, std::string prefix, toml::source_region where,
            std::string keys_doc);
  /// "[robot]", or "the file" at the top level.
  std::string section() const;
  [[noreturn]] void fail(const std::string& dotted_key, const toml::source_region& where,
                         const std::string& reason, const std::string& message) const;

  const toml::table* table_ = nullptr;
  std::filesystem::path file_;
  std::string prefix_;
  toml::source_region where_;
  std::string keys_doc_;
};

}  // namespace zerog::formats
