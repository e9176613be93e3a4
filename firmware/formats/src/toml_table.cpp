#include "zerog/formats/toml_table.hpp"

#include <algorithm>
#include <utility>

#include "zerog/formats/detail/csv_scan.hpp"

namespace zerog::formats {

namespace fs = std::filesystem;

namespace {

int line_of(const toml::source_region& where) {
  return where.begin.line > 0 ? static_cast<int>(where.begin.line) : 1;
}
int column_of(const toml::source_region& where) {
  return where.begin.line > 0 ? static_cast<int>(where.begin.column) : 1;
}

}  // namespace

TomlError::TomlError(fs::path file, int line, int column, std::string key, std::string reason,
                     const std::string& message)
    : InputError(std::move(file), line, column, message),
      key_(std::move(key)),
      reason_(std::move(reason)) {}

void throw_at(const fs::path& file, const toml::source_region& where, const std::string& why) {
  throw InputError(file, line_of(where), column_of(where), why);
}

toml::table parse_toml(std::string_view text, const fs::path& file) {
  try {
    return toml::parse(text, file.string());
  } catch (const toml::parse_error& e) {
    const std::string why = "TOML syntax: " + std::string(e.description());
    throw TomlError(file, line_of(e.source()), column_of(e.source()), "", why, why);
  }
}

toml::table parse_toml_file(const fs::path& file) {
  return parse_toml(detail::read_whole_file(file), file);
}

std::string number_text(double v) {
  std::string s;
  detail::append_number(s, v, 0);
  return s;
}

bool NumberRange::contains(double v) const {
  const bool low = v < lowest || (lowest_excluded && v == lowest);
  const bool high = v > highest || (highest_excluded && v == highest);
  return !low && !high;
}

std::string NumberRange::text() const {
  const bool low = std::isfinite(lowest);
  const bool high = std::isfinite(highest);
  if (low && high) {
    return std::string("in ") + (lowest_excluded ? "(" : "[") + number_text(lowest) + ", " +
           number_text(highest) + (highest_excluded ? ")" : "]");
  }
  if (low) return std::string(lowest_excluded ? "> " : ">= ") + number_text(lowest);
  if (high) return std::string(highest_excluded ? "< " : "<= ") + number_text(highest);
  return "";
}

// ---------------------------------------------------------------------------------------------

TomlTable::TomlTable(fs::path file, std::string prefix, toml::source_region where,
                     std::string keys_doc)
    : file_(std::move(file)),
      prefix_(std::move(prefix)),
      where_(where),
      keys_doc_(std::move(keys_doc)) {}

TomlTable::TomlTable(const toml::table& table, fs::path file, std::string prefix,
                     const std::vector<std::string_view>& known, std::string_view keys_doc)
    : TomlTable(std::move(file), std::move(prefix), table.source(), std::string(keys_doc)) {
  table_ = &table;
  for (const auto& [key, node] : table) {
    const std::string_view k = key.str();
    if (std::find(known.begin(), known.end(), k) != known.end()) continue;
    std::string tail;
    const std::string_view near = detail::closest_name(k, known);
    if (!near.empty()) tail += " (did you mean '" + name(near) + "'?)";
    if (!keys_doc_.empty()) tail += "; the keys of " + section() + " are listed in " + keys_doc_;
    fail(name(k), key.source(), "unknown key" + tail, "unknown key '" + name(k) + "'" + tail);
  }
}

std::string TomlTable::section() const {
  return prefix_.empty() ? std::string("the file")
                         : "[" + prefix_.substr(0, prefix_.size() - 1) + "]";
}

void TomlTable::fail(const std::string& dotted_key, const toml::source_region& where,
                     const std::string& reason, const std::string& message) const {
  throw TomlError(file_, line_of(where), column_of(where), dotted_key, reason, message);
}

void TomlTable::fail(std::string_view key, const toml::source_region& where,
                     const std::string& reason) const {
  fail(name(key), where, reason, "'" + name(key) + "' " + reason);
}

void TomlTable::fail(std::string_view key, const std::string& reason) const {
  fail(key, where(key), reason);
}

const toml::source_region& TomlTable::where(std::string_view key) const {
  const toml::node* node = find(key);
  return node != nullptr ? node->source() : where_;
}

const toml::node* TomlTable::find(std::string_view key) const {
  return table_ == nullptr ? nullptr : table_->get(key);
}

const toml::node& TomlTable::require(std::string_view key) const {
  const toml::node* node = find(key);
  if (node != nullptr) return *node;
  const std::string key_text = "missing required key '" + name(key) + "'";
  if (table_ == nullptr) {
    const std::string why = "the file has no " + section() + " table";
    fail(name(key), where_, "missing: " + why, key_text + ": " + why);
  }
  fail(name(key), where_,
       prefix_.empty() ? std::string("missing required key")
                       : "missing required key in " + section(),
       key_text);
}

TomlTable TomlTable::sub_table(std::string_view key,
                               const std::vector<std::string_view>& known) const {
  const toml::node* node = find(key);
  if (node == nullptr) return TomlTable(file_, name(key) + ".", where_, keys_doc_);
  if (!node->is_table()) fail(key, node->source(), "must be a table");
  return TomlTable(*node->as_table(), file_, name(key) + ".", known, keys_doc_);
}

const toml::table& TomlTable::table(std::string_view key) const {
  const toml::node& node = require(key);
  if (!node.is_table()) fail(key, node.source(), "must be a table");
  return *node.as_table();
}

std::string TomlTable::string(std::string_view key) const {
  const toml::node& node = require(key);
  if (!node.is_string()) fail(key, node.source(), "must be a string");
  return std::string(*node.value<std::string_view>());
}

std::string TomlTable::optional_string(std::string_view key, const std::string& fallback) const {
  return find(key) == nullptr ? fallback : string(key);
}

std::vector<std::string> TomlTable::strings(std::string_view key, std::size_t count) const {
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
  fail(key, node.source(),
       "must be a list of " +
           (count == 0 ? std::string("column names") : std::to_string(count) + " column names"));
}

fs::path TomlTable::path(std::string_view key) const {
  const std::string text = string(key);
  if (text.empty()) fail(key, "must not be empty");
  const fs::path p(text);
  return p.is_absolute() ? p : file_.parent_path() / p;
}

bool TomlTable::boolean(std::string_view key) const {
  const toml::node& node = require(key);
  if (!node.is_boolean()) fail(key, node.source(), "must be true or false");
  return *node.value<bool>();
}

bool TomlTable::optional_boolean(std::string_view key, bool fallback) const {
  return find(key) == nullptr ? fallback : boolean(key);
}

std::int64_t TomlTable::integer(std::string_view key) const {
  const toml::node& node = require(key);
  if (!node.is_integer()) fail(key, node.source(), "must be an integer");
  return *node.value<std::int64_t>();
}

std::int64_t TomlTable::integer(std::string_view key, std::int64_t lowest,
                                std::int64_t highest) const {
  const std::int64_t v = integer(key);
  if (v < lowest || v > highest) {
    fail(key, "must be an integer in [" + std::to_string(lowest) + ", " + std::to_string(highest) +
                  "], is " + std::to_string(v));
  }
  return v;
}

std::int64_t TomlTable::optional_integer(std::string_view key, std::int64_t fallback,
                                         std::int64_t lowest, std::int64_t highest) const {
  return find(key) == nullptr ? fallback : integer(key, lowest, highest);
}

double TomlTable::number(const toml::node& node, std::string_view key) const {
  if (!node.is_number()) fail(key, node.source(), "must be a number");
  const double v = *node.value<double>();
  if (!std::isfinite(v)) fail(key, node.source(), "must be finite");
  return v;
}

double TomlTable::number(std::string_view key, const NumberRange& range) const {
  const toml::node& node = require(key);
  const double v = number(node, key);
  if (!range.contains(v))
    fail(key, node.source(), "must be " + range.text() + ", is " + number_text(v));
  return v;
}

double TomlTable::number(std::string_view key, double lowest, bool exclusive) const {
  return number(key, NumberRange{lowest, exclusive});
}

double TomlTable::optional_number(std::string_view key, double fallback,
                                  const NumberRange& range) const {
  return find(key) == nullptr ? fallback : number(key, range);
}

std::vector<double> TomlTable::numbers(std::string_view key, std::size_t count) const {
  const toml::node& node = require(key);
  const toml::array* array = node.as_array();
  if (array == nullptr || array->size() != count)
    fail(key, node.source(), "must be a list of " + std::to_string(count) + " numbers");
  std::vector<double> out;
  for (std::size_t i = 0; i < count; ++i)
    out.push_back(number(*array->get(i), std::string(key) + "[" + std::to_string(i) + "]"));
  return out;
}

Eigen::Vector3d TomlTable::vector3(std::string_view key) const {
  const std::vector<double> v = numbers(key, 3);
  return {v[0], v[1], v[2]};
}

Eigen::Vector3d TomlTable::optional_vector3(std::string_view key,
                                            const Eigen::Vector3d& fallback) const {
  return find(key) == nullptr ? fallback : vector3(key);
}

Eigen::Matrix3d TomlTable::matrix3(std::string_view key, std::string_view explain) const {
  const toml::node& node = require(key);
  const toml::array* rows = node.as_array();
  if (rows == nullptr || rows->size() != 3)
    fail(key, node.source(), "must be a 3×3 array of numbers" + std::string(explain));
  Eigen::Matrix3d m;
  for (std::size_t r = 0; r < 3; ++r) {
    const std::string row_key = std::string(key) + "[" + std::to_string(r) + "]";
    const toml::array* row = rows->get(r)->as_array();
    if (row == nullptr || row->size() != 3)
      fail(row_key, rows->get(r)->source(), "must be a row of 3 numbers");
    for (std::size_t c = 0; c < 3; ++c) {
      m(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) =
          number(*row->get(c), row_key + "[" + std::to_string(c) + "]");
    }
  }
  return m;
}

}  // namespace zerog::formats
