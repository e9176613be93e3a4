#include "zerog/formats/detail/csv_scan.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <system_error>

#include "zerog/formats/log.hpp"

namespace zerog::formats::detail {

std::string read_whole_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path, 0, 0, std::string("cannot open: ") + std::strerror(errno));
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  std::string text;
  if (!ec) text.reserve(static_cast<std::size_t>(size));
  text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  if (in.bad()) throw InputError(path, 0, 0, "read error");
  return text;
}

int char_column(std::string_view line, std::size_t offset) {
  int column = 1;
  const std::size_t end = std::min(offset, line.size());
  for (std::size_t i = 0; i < end; ++i) {
    if ((static_cast<unsigned char>(line[i]) & 0xC0u) != 0x80u) ++column;
  }
  return column;
}

bool LineCursor::next(std::string_view& line) {
  if (pos_ >= text_.size()) return false;
  const std::size_t nl = text_.find('\n', pos_);
  const std::size_t end = nl == std::string_view::npos ? text_.size() : nl;
  line = text_.substr(pos_, end - pos_);
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  pos_ = nl == std::string_view::npos ? text_.size() : nl + 1;
  ++number_;
  return true;
}

namespace {
bool is_blank_char(char c) { return c == ' ' || c == '\t'; }
}  // namespace

void split_cells(std::string_view line, char delimiter, std::vector<Cell>& cells) {
  cells.clear();
  if (delimiter == ' ') {
    std::size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && is_blank_char(line[i])) ++i;
      if (i >= line.size()) break;
      const std::size_t start = i;
      while (i < line.size() && !is_blank_char(line[i])) ++i;
      cells.push_back({line.substr(start, i - start), start});
    }
    return;
  }
  std::size_t start = 0;
  for (;;) {
    const std::size_t d = line.find(delimiter, start);
    if (d == std::string_view::npos) {
      cells.push_back({line.substr(start), start});
      return;
    }
    cells.push_back({line.substr(start, d - start), start});
    start = d + 1;
  }
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && is_blank_char(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_blank_char(s.back())) s.remove_suffix(1);
  return s;
}

bool is_blank(std::string_view line) { return trim(line).empty(); }

NumberStatus parse_number(std::string_view cell, double& value, char decimal_point) {
  std::string_view s = trim(cell);
  if (s.empty()) return NumberStatus::empty;
  if (s.front() == '+' && s.size() > 1 && s[1] != '-' && s[1] != '+') s.remove_prefix(1);
  char buffer[64];
  if (decimal_point != '.') {
    if (s.size() >= sizeof buffer) return NumberStatus::not_a_number;
    for (std::size_t i = 0; i < s.size(); ++i) {
      const char c = s[i];
      if (c == '.') return NumberStatus::not_a_number;  // a point in a decimal-comma file
      buffer[i] = c == decimal_point ? '.' : c;
    }
    s = std::string_view(buffer, s.size());
  }
  const char* end = s.data() + s.size();
  const auto [ptr, ec] = std::from_chars(s.data(), end, value, std::chars_format::general);
  if (ec == std::errc::result_out_of_range) return NumberStatus::out_of_range;
  if (ec != std::errc() || ptr != end) return NumberStatus::not_a_number;
  if (!std::isfinite(value)) return NumberStatus::not_finite;
  return NumberStatus::ok;
}

void append_number(std::string& out, double v, int digits) {
  char buffer[64];
  const auto result = digits > 0 ? std::to_chars(buffer, buffer + sizeof buffer, v,
                                                 std::chars_format::general, digits)
                                 : std::to_chars(buffer, buffer + sizeof buffer, v);
  out.append(buffer, result.ptr);
}

namespace {
char lower(char c) { return static_cast<char>(std::tolower(static_cast<unsigned char>(c))); }

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      const std::size_t cost = lower(a[i - 1]) == lower(b[j - 1]) ? 0 : 1;
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + cost});
      diagonal = above;
    }
  }
  return row[b.size()];
}
}  // namespace

std::string_view closest_name(std::string_view name, const std::vector<std::string_view>& known) {
  std::string_view best;
  std::size_t best_distance = 3;
  for (std::string_view k : known) {
    const std::size_t d = edit_distance(name, k);
    if (d < best_distance && d < std::max<std::size_t>(k.size(), 2) / 2 + 1) {
      best = k;
      best_distance = d;
    }
  }
  return best;
}

std::string shorten(std::string_view text, std::size_t max) {
  if (text.size() <= max) return std::string(text);
  std::size_t cut = max;
  while (cut > 0 && (static_cast<unsigned char>(text[cut]) & 0xC0u) == 0x80u) --cut;
  return std::string(text.substr(0, cut)) + "…";
}

std::string number_error(NumberStatus status, std::string_view cell_text, std::string_view column) {
  const std::string col = "column '" + std::string(column) + "'";
  const std::string cell = "'" + shorten(trim(cell_text)) + "'";
  switch (status) {
    case NumberStatus::empty:
      return "empty cell in " + col;
    case NumberStatus::not_finite:
      return "NaN/inf " + cell + " in " + col + " is not allowed";
    case NumberStatus::out_of_range:
      return "number " + cell + " in " + col + " is out of range";
    default:
      return "not a number: " + cell + " in " + col;
  }
}

}  // namespace zerog::formats::detail
