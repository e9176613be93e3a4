#pragma once
// Internal to zerog::io: strict TOML reading (unknown keys are errors, every error names the file,
// line and column), shared by read_rig and the importer's mapping file.
#include <toml++/toml.h>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "csv_scan.hpp"
#include "zerog/io/log.hpp"

namespace zerog::io::detail {

/// Throws InputError at the start of `where` (line 1, column 1 if the region is unknown).
[[noreturn]] void throw_at(const std::filesystem::path& file, const toml::source_region& where,
                           const std::string& why);

/// Parses a TOML file; syntax errors become InputError with the TOML line and column.
toml::table parse_toml_file(const std::filesystem::path& file);

inline std::string number_text(double v) {
  std::string s;
  append_number(s, v, 0);
  return s;
}

/// One TOML table with its allowed keys; unknown keys are rejected on construction. Every
/// accessor throws InputError at the offending key or value.
class TomlTable {
 public:
  TomlTable(const toml::table& table, const std::filesystem::path& file, std::string prefix,
            std::vector<std::string_view> known)
      : table_(table), file_(file), prefix_(std::move(prefix)) {
    for (const auto& [key, node] : table) {
      bool ok = false;
      for (std::string_view k : known) ok = ok || key.str() == k;
      if (ok) continue;
      std::string why = "unknown key '" + prefix_ + std::string(key.str()) + "'";
      const std::string_view near = closest_name(key.str(), known);
      if (!near.empty()) why += " (did you mean '" + prefix_ + std::string(near) + "'?)";
      throw_at(file_, key.source(), why);
    }
  }

  const toml::node* find(std::string_view key) const { return table_.get(key); }

  const toml::node& require(std::string_view key) const {
    const toml::node* node = find(key);
    if (node == nullptr)
      throw_at(file_, table_.source(), "missing required key '" + name(key) + "'");
    return *node;
  }

  std::string string(std::string_view key) const {
    const toml::node& node = require(key);
    if (!node.is_string()) throw_at(file_, node.source(), "'" + name(key) + "' must be a string");
    return std::string(*node.value<std::string_view>());
  }

  std::int64_t integer(std::string_view key) const {
    const toml::node& node = require(key);
    if (!node.is_integer())
      throw_at(file_, node.source(), "'" + name(key) + "' must be an integer");
    return *node.value<std::int64_t>();
  }

  double number(const toml::node& node, std::string_view key) const {
    if (!node.is_number()) throw_at(file_, node.source(), "'" + name(key) + "' must be a number");
    const double v = *node.value<double>();
    if (!std::isfinite(v)) throw_at(file_, node.source(), "'" + name(key) + "' must be finite");
    return v;
  }

  double number(std::string_view key, double lowest, bool exclusive) const {
    const toml::node& node = require(key);
    return checked(node, key, lowest, exclusive);
  }

  double optional_number(std::string_view key, double fallback, double lowest,
                         bool exclusive) const {
    const toml::node* node = find(key);
    return node == nullptr ? fallback : checked(*node, key, lowest, exclusive);
  }

  std::vector<double> numbers(std::string_view key, std::size_t count) const {
    const toml::node& node = require(key);
    const toml::array* array = node.as_array();
    if (array == nullptr || array->size() != count) {
      throw_at(file_, node.source(),
               "'" + name(key) + "' must be a list of " + std::to_string(count) + " numbers");
    }
    std::vector<double> out;
    for (const toml::node& element : *array) out.push_back(number(element, key));
    return out;
  }

  const toml::table& table(std::string_view key) const {
    const toml::node& node = require(key);
    if (!node.is_table()) throw_at(file_, node.source(), "'" + name(key) + "' must be a table");
    return *node.as_table();
  }

  /// Optional string; `fallback` if absent.
  std::string optional_string(std::string_view key, const std::string& fallback) const {
    return find(key) == nullptr ? fallback : string(key);
  }

  /// A list of strings; `count` = 0 accepts any non-empty length.
  std::vector<std::string> strings(std::string_view key, std::size_t count) const {
    const toml::node& node = require(key);
    const toml::array* array = node.as_array();
    const bool ok = array != nullptr && (count == 0 ? !array->empty() : array->size() == count);
    if (ok) {
      std::vector<std::string> out;
      for (const toml::node& element : *array) {
        if (!element.is_string()) break;
        out.emplace_back(*element.value<std::string_view>());
      }
      if (out.size() == array->size()) return out;
    }
    throw_at(
        file_, node.source(),
        "'" + name(key) + "' must be a list of " +
            (count == 0 ? std::string("column names") : std::to_string(count) + " column names"));
  }

  /// The key's name with this table's prefix, for messages ("files.ft.force").
  std::string name(std::string_view key) const { return prefix_ + std::string(key); }
  const toml::table& node() const { return table_; }
  const std::filesystem::path& file() const { return file_; }

 private:
  double checked(const toml::node& node, std::string_view key, double lowest,
                 bool exclusive) const {
    const double v = number(node, key);
    if (v < lowest || (exclusive && v == lowest)) {
      throw_at(file_, node.source(),
               "'" + name(key) + "' must be " + (exclusive ? "> " : ">= ") + number_text(lowest) +
                   ", is " + number_text(v));
    }
    return v;
  }

  const toml::table& table_;
  const std::filesystem::path& file_;
  std::string prefix_;
};

/// Reads a rig from a TOML table. `embedded` (the [rig] table of an import mapping): the keys
/// `format` and `version` are optional and `sample_period_s` may be absent — `*has_period` tells.
/// `key_prefix` is prepended to key names in messages (e.g. "rig.").
Rig rig_from_toml(const toml::table& table, const std::filesystem::path& file, bool embedded,
                  const std::string& key_prefix, bool* has_period);

}  // namespace zerog::io::detail
