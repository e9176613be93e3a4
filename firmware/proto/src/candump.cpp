#include "zerog/proto/candump.hpp"

#include <cstdio>
#include <istream>
#include <limits>
#include <string>

namespace zerog::proto {

namespace {

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}
bool is_digit(char c) { return c >= '0' && c <= '9'; }
bool is_space(char c) { return c == ' ' || c == '\t'; }

constexpr std::size_t kMaxInterfaceLength = 15;  // IFNAMSIZ - 1
constexpr int kMaxSecondsDigits = 12;  // bounds the digit loop (no overflow while reading)
// The largest seconds whose timestamp in ns (with any fraction) fits std::int64_t: year 2262.
constexpr std::int64_t kMaxSeconds =
    (std::numeric_limits<std::int64_t>::max() - 999'999'999) / 1'000'000'000;

// Cursor over one line that records the first error.
struct Cursor {
  std::string_view s;
  std::size_t pos = 0;
  int line = 0;
  CandumpError* error = nullptr;

  bool at_end() const { return pos >= s.size(); }
  char peek() const { return at_end() ? '\0' : s[pos]; }
  bool fail(std::size_t at, std::string reason) const {
    error->line = line;
    error->column = static_cast<int>(at) + 1;
    error->reason = std::move(reason);
    return false;
  }
  bool expect(char c, const char* what) {
    if (peek() != c) {
      return fail(pos, at_end() ? std::string("line ends; expected ") + what
                                : std::string("expected ") + what);
    }
    ++pos;
    return true;
  }
  std::size_t skip_spaces() {
    const std::size_t start = pos;
    while (!at_end() && is_space(s[pos])) ++pos;
    return pos - start;
  }
};

bool parse_timestamp(Cursor& c, std::int64_t& ns) {
  if (!c.expect('(', "'(' opening the timestamp")) return false;
  std::int64_t seconds = 0;
  int digits = 0;
  const std::size_t seconds_start = c.pos;
  while (is_digit(c.peek())) {
    if (++digits > kMaxSecondsDigits) return c.fail(seconds_start, "timestamp seconds too large");
    seconds = seconds * 10 + (c.peek() - '0');
    ++c.pos;
  }
  if (digits == 0) return c.fail(c.pos, "expected the timestamp's seconds (digits)");
  if (seconds > kMaxSeconds) {
    return c.fail(seconds_start, "timestamp seconds too large (at most " +
                                     std::to_string(kMaxSeconds) + ", in the year 2262)");
  }
  if (!c.expect('.', "'.' in the timestamp")) return false;
  std::int64_t fraction = 0;
  int fraction_digits = 0;
  while (is_digit(c.peek())) {
    if (++fraction_digits > 9) return c.fail(c.pos, "more than 9 fractional digits");
    fraction = fraction * 10 + (c.peek() - '0');
    ++c.pos;
  }
  if (fraction_digits == 0) return c.fail(c.pos, "expected the timestamp's fraction (digits)");
  for (int i = fraction_digits; i < 9; ++i) fraction *= 10;
  if (!c.expect(')', "')' closing the timestamp")) return false;
  ns = seconds * 1'000'000'000 + fraction;
  return true;
}

bool parse_frame(Cursor& c, CanFrame& frame) {
  const std::size_t id_start = c.pos;
  std::uint32_t id = 0;
  int digits = 0;
  while (!c.at_end() && c.peek() != '#') {
    const int v = hex_value(c.peek());
    if (v < 0) return c.fail(c.pos, "CAN id: expected a hex digit or '#'");
    if (++digits > 8) break;
    id = (id << 4) | static_cast<std::uint32_t>(v);
    ++c.pos;
  }
  if (digits != 3 && digits != 8) {
    return c.fail(id_start, "CAN id must have 3 (standard) or 8 (extended) hex digits");
  }
  if (digits == 3) {
    if (id > kCanStandardIdMask) return c.fail(id_start, "standard CAN id above 0x7FF");
  } else if (id & kCanErrorFlag) {
    if (id & (kCanExtendedFlag | kCanRemoteFlag)) {
      return c.fail(id_start, "error frame id with extended/remote flag bits");
    }
  } else {
    if (id > kCanExtendedIdMask) return c.fail(id_start, "extended CAN id above 0x1FFFFFFF");
    id |= kCanExtendedFlag;
  }
  if (!c.expect('#', "'#' after the CAN id")) return false;
  frame = CanFrame{};
  frame.id = id;
  if (c.peek() == '#') return c.fail(c.pos, "CAN FD frames ('##') are not supported");
  if (c.peek() == 'R' || c.peek() == 'r') {
    if (id & kCanErrorFlag) return c.fail(c.pos, "an error frame cannot be a remote frame");
    frame.id |= kCanRemoteFlag;
    ++c.pos;
    if (is_digit(c.peek())) {
      const int len = c.peek() - '0';
      if (len > kCanMaxDataLength) return c.fail(c.pos, "remote frame length above 8");
      frame.len = static_cast<std::uint8_t>(len);
      ++c.pos;
    }
    return true;
  }
  while (!c.at_end() && !is_space(c.peek())) {
    if (c.peek() == '.') {
      if (frame.len == 0) return c.fail(c.pos, "'.' before the first data byte");
      ++c.pos;
    }
    if (c.peek() == '_') return c.fail(c.pos, "len8_dlc suffix ('_') is not supported");
    const int hi = hex_value(c.peek());
    if (hi < 0) return c.fail(c.pos, "data: expected a hex digit");
    const int lo = hex_value(c.pos + 1 < c.s.size() ? c.s[c.pos + 1] : '\0');
    if (lo < 0) return c.fail(c.pos + 1, "data: odd number of hex digits or a non-hex character");
    if (frame.len == kCanMaxDataLength) return c.fail(c.pos, "more than 8 data bytes");
    frame.data[frame.len++] = static_cast<std::uint8_t>(hi << 4 | lo);
    c.pos += 2;
  }
  return true;
}

}  // namespace

std::string CandumpError::message() const {
  return "line " + std::to_string(line) + ", column " + std::to_string(column) + ": " + reason;
}

CandumpLineKind parse_candump_line(std::string_view line, int line_number, CandumpRecord& out,
                                   CandumpError& error) {
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.remove_suffix(1);
  Cursor c{line, 0, line_number, &error};
  c.skip_spaces();
  if (c.at_end()) return CandumpLineKind::blank;
  if (c.pos != 0) {
    c.fail(0, "leading whitespace");
    return CandumpLineKind::error;
  }
  if (!parse_timestamp(c, out.timestamp_ns)) return CandumpLineKind::error;
  if (c.skip_spaces() == 0) {
    c.fail(c.pos, "expected a space after the timestamp");
    return CandumpLineKind::error;
  }
  const std::size_t name_start = c.pos;
  while (!c.at_end() && !is_space(c.peek())) ++c.pos;
  if (c.pos - name_start > kMaxInterfaceLength) {
    c.fail(name_start, "interface name longer than 15 characters");
    return CandumpLineKind::error;
  }
  out.interface.assign(line.substr(name_start, c.pos - name_start));
  if (c.skip_spaces() == 0 || c.at_end()) {
    c.fail(c.pos, "expected a space and a frame (ID#DATA) after the interface");
    return CandumpLineKind::error;
  }
  if (!parse_frame(c, out.frame)) return CandumpLineKind::error;
  out.direction = '\0';
  if (c.skip_spaces() > 0 && !c.at_end()) {
    if (c.peek() != 'R' && c.peek() != 'T') {
      c.fail(c.pos, "expected 'R' or 'T' (direction) or the end of the line");
      return CandumpLineKind::error;
    }
    out.direction = c.peek();
    ++c.pos;
    c.skip_spaces();
  }
  if (!c.at_end()) {
    c.fail(c.pos, "unexpected characters after the frame");
    return CandumpLineKind::error;
  }
  return CandumpLineKind::record;
}

namespace {

template <typename NextLine>
bool parse_lines(NextLine&& next_line, const CanFilter& filter, std::vector<CandumpRecord>& records,
                 CandumpError& error) {
  CandumpRecord record;
  std::string_view line;
  for (int number = 1; next_line(line); ++number) {
    switch (parse_candump_line(line, number, record, error)) {
      case CandumpLineKind::error:
        return false;
      case CandumpLineKind::blank:
        break;
      case CandumpLineKind::record:
        if (filter.matches(record.frame)) records.push_back(record);
        break;
    }
  }
  return true;
}

}  // namespace

bool parse_candump(std::string_view text, const CanFilter& filter,
                   std::vector<CandumpRecord>& records, CandumpError& error) {
  std::size_t pos = 0;
  auto next_line = [&](std::string_view& line) {
    if (pos >= text.size()) return false;
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    line = text.substr(pos, end - pos);
    pos = end + 1;
    return true;
  };
  return parse_lines(next_line, filter, records, error);
}

bool parse_candump(std::istream& in, const CanFilter& filter, std::vector<CandumpRecord>& records,
                   CandumpError& error) {
  std::string buffer;
  auto next_line = [&](std::string_view& line) {
    if (!std::getline(in, buffer)) return false;
    line = buffer;
    return true;
  };
  return parse_lines(next_line, filter, records, error);
}

std::string format_candump_line(const CandumpRecord& record) {
  char head[48];
  const std::int64_t seconds = record.timestamp_ns / 1'000'000'000;
  const std::int64_t ns = record.timestamp_ns % 1'000'000'000;
  if (ns % 1000 == 0) {
    std::snprintf(head, sizeof head, "(%lld.%06lld) ", static_cast<long long>(seconds),
                  static_cast<long long>(ns / 1000));
  } else {
    std::snprintf(head, sizeof head, "(%lld.%09lld) ", static_cast<long long>(seconds),
                  static_cast<long long>(ns));
  }
  std::string line = head;
  line += record.interface;
  line += ' ';
  const CanFrame& f = record.frame;
  char id[16];
  if (f.error() || f.extended()) {
    std::snprintf(id, sizeof id, "%08X#",
                  f.error() ? f.id & ~kCanRemoteFlag & ~kCanExtendedFlag : f.raw_id());
  } else {
    std::snprintf(id, sizeof id, "%03X#", f.raw_id());
  }
  line += id;
  if (f.remote()) {
    line += 'R';
    if (f.len > 0) line += static_cast<char>('0' + f.len);
  } else {
    static constexpr char kHex[] = "0123456789ABCDEF";
    for (std::uint8_t i = 0; i < f.len && i < kCanMaxDataLength; ++i) {
      line += kHex[f.data[i] >> 4];
      line += kHex[f.data[i] & 0xF];
    }
  }
  if (record.direction != '\0') {
    line += ' ';
    line += record.direction;
  }
  return line;
}

}  // namespace zerog::proto
