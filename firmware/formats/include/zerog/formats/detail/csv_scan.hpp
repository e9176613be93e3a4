#pragma once
// Internal to the formats (namespace zerog::formats::detail): scanning of numeric CSV text shared
// by the log reader (zerog::formats) and the importer (host/io). Hand-written on purpose: the files
// are numeric only, and every error must name the exact line and character column of the offending
// cell; whole-file reading plus in-place std::from_chars parsing keeps 100k rows × 25 columns well
// under a second.
#include <cstddef>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace zerog::formats::detail {

/// The whole file as bytes. Throws InputError(path, 0, 0, …) if it cannot be read.
std::string read_whole_file(const std::filesystem::path& path);

/// 1-based character (UTF-8 code point) column of byte `offset` in `line`.
int char_column(std::string_view line, std::size_t offset);

/// Iterates the lines of a buffer (1-based numbers); strips a trailing '\r'.
class LineCursor {
 public:
  explicit LineCursor(std::string_view text) : text_(text) {}
  bool next(std::string_view& line);
  int number() const { return number_; }  ///< number of the line last returned

 private:
  std::string_view text_;
  std::size_t pos_ = 0;
  int number_ = 0;
};

struct Cell {
  std::string_view text;  ///< raw cell text, untrimmed
  std::size_t offset;     ///< byte offset of the cell start within its line
};

/// Splits `line` into cells. `delimiter` ' ' means runs of blanks (spaces or tabs), with leading
/// and trailing blanks ignored; any other character separates cells one to one.
void split_cells(std::string_view line, char delimiter, std::vector<Cell>& cells);

/// `s` without leading and trailing spaces and tabs.
std::string_view trim(std::string_view s);
/// True if `line` is empty or blanks only.
bool is_blank(std::string_view line);

enum class NumberStatus { ok, empty, not_a_number, not_finite, out_of_range };

/// Parses a whole cell as a finite double (C locale; surrounding blanks and one leading '+'
/// allowed). `decimal_point` ',' accepts a decimal comma instead of the point.
NumberStatus parse_number(std::string_view cell, double& value, char decimal_point = '.');

/// Appends `v` as text independent of the locale: `digits` significant digits, like
/// printf("%.{digits}g"); digits = 0 means the shortest text that reads back exactly.
void append_number(std::string& out, double v, int digits);

/// The entry of `known` closest to `name` by edit distance (at most 2 edits, or a difference
/// in case only), or empty if none is close.
std::string_view closest_name(std::string_view name, const std::vector<std::string_view>& known);

/// `text` shortened to at most `max` characters for messages.
std::string shorten(std::string_view text, std::size_t max = 40);

/// The message for a cell that did not parse (status != ok), naming the cell and its column.
std::string number_error(NumberStatus status, std::string_view cell_text, std::string_view column);

}  // namespace zerog::formats::detail
