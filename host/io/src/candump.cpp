#include "zerog/io/candump.hpp"

#include <cstdio>
#include <istream>
#include <limits>
#include <string>

namespace zerog::io {

namespace {

using proto::CanFilter;
using proto::CanFrame;
using proto::kCanErrorFlag;
using proto::kCanExtendedFlag;
using proto::kCanExtendedIdMask;
using proto::kCanMaxDataLength;
using proto::kCanRemoteFlag;
using proto::kCanStandardIdMask;

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
constexpr int kCanFdMaxDataLength = 64;

// Cursor over one line that records the first error.
struct Cursor {
  std::string_view s;
  std::size_t pos = 0;
  int line = 0;
  CandumpError* error = nullptr;

  bool at_end() const { return pos >= s.size(); }
  char peek(std::size_t ahead = 0) const { return pos + ahead >= s.size() ? '\0' : s[pos + ahead]; }
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
  std::string_view token() const {
    std::size_t end = pos;
    while (end < s.size() && !is_space(s[end])) ++end;
    return s.substr(pos, end - pos);
  }
};

// Reads exactly `n` decimal digits.
bool read_digits(Cursor& c, int n, int& value, const char* what) {
  value = 0;
  for (int i = 0; i < n; ++i) {
    if (!is_digit(c.peek())) return c.fail(c.pos, std::string("expected the date's ") + what);
    value = value * 10 + (c.peek() - '0');
    ++c.pos;
  }
  return true;
}

// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's days_from_civil).
std::int64_t days_from_civil(std::int64_t y, int m, int d) {
  y -= m <= 2;
  const std::int64_t era = (y >= 0 ? y : y - 399) / 400;
  const std::int64_t yoe = y - era * 400;
  const std::int64_t doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const std::int64_t doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + doe - 719468;
}

// "YYYY-MM-DD HH:MM:SS" (-tA), the cursor on the year; seconds since 1970 read as UTC.
bool parse_date(Cursor& c, std::int64_t& seconds) {
  const std::size_t start = c.pos;
  int year = 0, month = 0, day = 0, hour = 0, minute = 0, second = 0;
  if (!read_digits(c, 4, year, "year (YYYY)") || !c.expect('-', "'-' in the date") ||
      !read_digits(c, 2, month, "month (MM)") || !c.expect('-', "'-' in the date") ||
      !read_digits(c, 2, day, "day (DD)") || !c.expect(' ', "' ' between date and time") ||
      !read_digits(c, 2, hour, "hour (hh)") || !c.expect(':', "':' in the time") ||
      !read_digits(c, 2, minute, "minute (mm)") || !c.expect(':', "':' in the time") ||
      !read_digits(c, 2, second, "second (ss)"))
    return false;
  if (year < 1970 || month < 1 || month > 12 || day < 1 || day > 31 || hour > 23 || minute > 59 ||
      second > 60)
    return c.fail(start, "date or time out of range (YYYY-MM-DD hh:mm:ss from 1970)");
  seconds = days_from_civil(year, month, day) * 86400 + hour * 3600 + minute * 60 + second;
  return true;
}

// "(seconds.fraction)" or "(YYYY-MM-DD hh:mm:ss.fraction)".
bool parse_timestamp(Cursor& c, std::int64_t& ns, CandumpStamp& stamp) {
  if (!c.expect('(', "'(' opening the timestamp")) return false;
  std::int64_t seconds = 0;
  const std::size_t seconds_start = c.pos;
  if (is_digit(c.peek()) && is_digit(c.peek(1)) && is_digit(c.peek(2)) && is_digit(c.peek(3)) &&
      c.peek(4) == '-') {
    if (!parse_date(c, seconds)) return false;
    if (seconds > kMaxSeconds)  // nanoseconds since 1970 must fit int64
      return c.fail(seconds_start, "date after the year 2262 (nanoseconds since 1970 overflow)");
    stamp = CandumpStamp::date;
  } else {
    int digits = 0;
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
    stamp = CandumpStamp::seconds;
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

// Checks an identifier of `digits` hex digits read from `id_start`; sets the flags.
bool finish_id(Cursor& c, std::size_t id_start, int digits, std::uint32_t raw, std::uint32_t& id) {
  if (digits != 3 && digits != 8) {
    return c.fail(id_start, "CAN id must have 3 (standard) or 8 (extended) hex digits");
  }
  id = raw;
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
  return true;
}

bool valid_fd_length(int len) {
  return len <= 8 || len == 12 || len == 16 || len == 20 || len == 24 || len == 32 || len == 48 ||
         len == 64;
}

// The log-file frame "ID#DATA", "ID#R[len]" or "ID##FDATA".
bool parse_log_frame(Cursor& c, CandumpRecord& out) {
  CanFrame& frame = out.frame;
  const std::size_t id_start = c.pos;
  std::uint32_t raw = 0;
  int digits = 0;
  while (!c.at_end() && c.peek() != '#') {
    const int v = hex_value(c.peek());
    if (v < 0) return c.fail(c.pos, "CAN id: expected a hex digit or '#'");
    if (++digits > 8) break;
    raw = (raw << 4) | static_cast<std::uint32_t>(v);
    ++c.pos;
  }
  std::uint32_t id = 0;
  if (!finish_id(c, id_start, digits, raw, id)) return false;
  if (!c.expect('#', "'#' after the CAN id")) return false;
  frame = CanFrame{};
  frame.id = id;
  if (c.peek() == '#') {  // CAN FD: flags nibble, then the data (payload checked, not kept)
    ++c.pos;
    if (id & kCanErrorFlag) return c.fail(c.pos - 1, "an error frame cannot be a CAN FD frame");
    if (hex_value(c.peek()) < 0) return c.fail(c.pos, "CAN FD: expected the flags (one hex digit)");
    ++c.pos;
    out.fd = true;
    int len = 0;
    while (!c.at_end() && !is_space(c.peek())) {
      if (c.peek() == '.') ++c.pos;
      const int hi = hex_value(c.peek());
      if (hi < 0) return c.fail(c.pos, "data: expected a hex digit");
      if (hex_value(c.peek(1)) < 0)
        return c.fail(c.pos + 1, "data: odd number of hex digits or a non-hex character");
      if (len == kCanFdMaxDataLength) return c.fail(c.pos, "more than 64 CAN FD data bytes");
      ++len;
      c.pos += 2;
    }
    if (!valid_fd_length(len))
      return c.fail(id_start, "CAN FD data length " + std::to_string(len) +
                                  " is not one of 0-8, 12, 16, 20, 24, 32, 48, 64");
    out.fd_length = static_cast<std::uint8_t>(len);
    return true;
  }
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
    const int lo = hex_value(c.peek(1));
    if (lo < 0) return c.fail(c.pos + 1, "data: odd number of hex digits or a non-hex character");
    if (frame.len == kCanMaxDataLength) return c.fail(c.pos, "more than 8 data bytes");
    frame.data[frame.len++] = static_cast<std::uint8_t>(hi << 4 | lo);
    c.pos += 2;
  }
  return true;
}

// After "ID#…": an optional direction (-x), then the end.
bool finish_log_line(Cursor& c, CandumpRecord& out) {
  out.direction = '\0';
  if (c.skip_spaces() > 0 && !c.at_end()) {
    if (c.peek() != 'R' && c.peek() != 'T') {
      return c.fail(c.pos, "expected 'R' or 'T' (direction) or the end of the line");
    }
    out.direction = c.peek();
    ++c.pos;
    c.skip_spaces();
  }
  if (!c.at_end()) return c.fail(c.pos, "unexpected characters after the frame");
  return true;
}

// The default columns after the interface: [RX|TX B|- E|-]  ID  [len]  data [ASCII|ERRORFRAME].
bool parse_columns_frame(Cursor& c, CandumpRecord& out) {
  out.direction = '\0';
  const std::string_view dir = c.token();
  if (dir == "RX" || dir == "TX") {  // -x: direction, then BRS and ESI of CAN FD
    out.direction = dir[0] == 'R' ? 'R' : 'T';
    c.pos += 2;
    for (const char* flag : {"B", "E"}) {
      if (c.skip_spaces() == 0) return c.fail(c.pos, "expected a space after the -x field");
      if (c.peek() != '-' && c.peek() != flag[0])
        return c.fail(c.pos, std::string("expected '-' or '") + flag + "' (candump -x flags)");
      ++c.pos;
    }
    if (c.skip_spaces() == 0) return c.fail(c.pos, "expected a space after the -x flags");
  }
  CanFrame& frame = out.frame;
  frame = CanFrame{};
  const std::size_t id_start = c.pos;
  std::uint32_t raw = 0;
  int digits = 0;
  while (hex_value(c.peek()) >= 0) {
    if (++digits > 8) break;
    raw = (raw << 4) | static_cast<std::uint32_t>(hex_value(c.peek()));
    ++c.pos;
  }
  if (digits == 0 || (digits <= 8 && !c.at_end() && !is_space(c.peek()) && c.peek() != '#'))
    return c.fail(c.pos, "CAN id: expected a hex digit");
  if (!finish_id(c, id_start, digits, raw, frame.id)) return false;
  if (c.peek() == '#') return c.fail(c.pos, "'#' after the id of a default-format line");
  if (c.skip_spaces() == 0)
    return c.fail(c.pos, c.at_end() ? "line ends; expected the length ([n])"
                                    : "CAN id: expected a hex digit or a space");
  if (c.peek() == '{')
    return c.fail(c.pos, "raw DLC '{…}' (candump -8) is not supported: record without -8");
  if (!c.expect('[', "'[' opening the data length")) return false;
  const std::size_t len_start = c.pos;
  int len = 0, len_digits = 0;
  while (is_digit(c.peek()) && len_digits < 3)
    len = len * 10 + (c.peek() - '0'), ++c.pos, ++len_digits;
  if (len_digits == 0) return c.fail(c.pos, "expected the data length (digits)");
  if (len_digits == 1) {  // classical CAN: " [%d] "
    if (len > kCanMaxDataLength) return c.fail(len_start, "CAN data length above 8");
  } else if (len_digits == 2) {  // CAN FD: "[%02d] "
    if (!valid_fd_length(len))
      return c.fail(len_start, "CAN FD data length " + std::to_string(len) +
                                   " is not one of 0-8, 12, 16, 20, 24, 32, 48, 64");
    if (frame.error()) return c.fail(id_start, "an error frame cannot be a CAN FD frame");
    out.fd = true;
    out.fd_length = static_cast<std::uint8_t>(len);
  } else {
    return c.fail(len_start, "data length: 1 digit (CAN) or 2 (CAN FD) expected");
  }
  if (!c.expect(']', "']' closing the data length")) return false;
  if (!out.fd) {
    const std::size_t before = c.pos;
    c.skip_spaces();
    if (c.token() == "remote") {
      if (frame.error()) return c.fail(c.pos, "an error frame cannot be a remote frame");
      c.pos += 6;
      if (c.skip_spaces() == 0 || c.token() != "request")
        return c.fail(c.pos, "expected 'remote request'");
      c.pos += 7;
      frame.id |= kCanRemoteFlag;
      frame.len = static_cast<std::uint8_t>(len);
      c.skip_spaces();
      if (!c.at_end()) return c.fail(c.pos, "unexpected characters after 'remote request'");
      return true;
    }
    c.pos = before;
  }
  for (int i = 0; i < len; ++i) {
    if (c.skip_spaces() == 0)
      return c.fail(c.pos, c.at_end()
                               ? "line ends before all " + std::to_string(len) + " data bytes"
                               : std::string("expected a space before the data byte"));
    const int hi = hex_value(c.peek());
    const int lo = hex_value(c.peek(1));
    if (c.peek() == '`' || c.peek(2) == '`')
      return c.fail(c.peek() == '`' ? c.pos : c.pos + 2,
                    "swapped byte order (candump -S) is not supported");
    if (hi < 0 || lo < 0 || (!c.at_end() && c.pos + 2 < c.s.size() && !is_space(c.peek(2))))
      return c.fail(c.pos,
                    "data: expected two hex digits (candump -i binary output is not "
                    "supported)");
    if (!out.fd) frame.data[frame.len++] = static_cast<std::uint8_t>(hi << 4 | lo);
    c.pos += 2;
  }
  c.skip_spaces();
  if (c.at_end()) return true;
  const std::size_t rest = c.pos;
  if (frame.error() && c.s.substr(rest) == "ERRORFRAME") return true;
  if (!out.fd && !frame.error() && c.peek() == '\'' && c.s.size() - rest >= 2 && c.s.back() == '\'')
    return true;  // -a: the printable bytes between quotes
  return c.fail(rest, "unexpected characters after the data");
}

}  // namespace

const char* to_string(CandumpClock clock) {
  switch (clock) {
    case CandumpClock::automatic:
      return "auto";
    case CandumpClock::absolute:
      return "absolute";
    case CandumpClock::zero:
      return "zero";
    case CandumpClock::delta:
      return "delta";
    case CandumpClock::date:
      return "date";
    case CandumpClock::none:
      return "none";
  }
  return "?";
}

bool parse_candump_clock(std::string_view text, CandumpClock& out) {
  for (CandumpClock c : {CandumpClock::automatic, CandumpClock::absolute, CandumpClock::zero,
                         CandumpClock::delta, CandumpClock::date, CandumpClock::none}) {
    if (text == to_string(c)) {
      out = c;
      return true;
    }
  }
  return false;
}

std::string CandumpError::message() const {
  return "line " + std::to_string(line) + ", column " + std::to_string(column) + ": " + reason;
}

CandumpLineKind parse_candump_line(std::string_view line, int line_number, CandumpRecord& out,
                                   CandumpError& error) {
  while (!line.empty() && (line.back() == '\n' || line.back() == '\r')) line.remove_suffix(1);
  Cursor c{line, 0, line_number, &error};
  c.skip_spaces();
  if (c.at_end()) return CandumpLineKind::blank;
  out.timestamp_ns = 0;
  out.fd = false;
  out.fd_length = 0;
  out.stamp = CandumpStamp::none;
  if (c.peek() == '(') {
    if (!parse_timestamp(c, out.timestamp_ns, out.stamp)) return CandumpLineKind::error;
    if (c.skip_spaces() == 0) {
      c.fail(c.pos, "expected a space after the timestamp");
      return CandumpLineKind::error;
    }
  }
  const std::size_t name_start = c.pos;
  if (out.stamp == CandumpStamp::none && is_digit(c.peek()) &&
      c.token().find_first_not_of("0123456789.") == std::string_view::npos &&
      c.token().find('.') != std::string_view::npos) {
    c.fail(c.pos, "expected '(' opening the timestamp");  // "1.5 can0 …": a time without '('
    return CandumpLineKind::error;
  }
  while (!c.at_end() && !is_space(c.peek())) ++c.pos;
  if (c.pos - name_start > kMaxInterfaceLength) {
    c.fail(name_start, "interface name longer than 15 characters");
    return CandumpLineKind::error;
  }
  out.interface.assign(line.substr(name_start, c.pos - name_start));
  if (c.skip_spaces() == 0 || c.at_end()) {
    c.fail(c.pos, "expected a space and a frame (ID#DATA, or ID  [len]  data) after the interface");
    return CandumpLineKind::error;
  }
  // The log-file form has "ID#…" here; the default columns "ID  [len]" or "RX - -  ID  [len]".
  if (c.token().find('#') != std::string_view::npos) {
    out.form = CandumpForm::log;
    if (out.stamp == CandumpStamp::date) {
      c.fail(0, "a log-file line (ID#DATA) with a date timestamp: candump -L writes seconds");
      return CandumpLineKind::error;
    }
    if (!parse_log_frame(c, out) || !finish_log_line(c, out)) return CandumpLineKind::error;
    return CandumpLineKind::record;
  }
  out.form = CandumpForm::columns;
  if (!parse_columns_frame(c, out)) return CandumpLineKind::error;
  return CandumpLineKind::record;
}

namespace {

const char* describe(CandumpForm form, CandumpStamp stamp) {
  if (form == CandumpForm::log)
    return stamp == CandumpStamp::none ? "log-file form (ID#DATA) without timestamps"
                                       : "log-file form (candump -L)";
  switch (stamp) {
    case CandumpStamp::none:
      return "candump's default output without timestamps";
    case CandumpStamp::seconds:
      return "candump's default output with -ta/-tz/-td timestamps";
    case CandumpStamp::date:
      return "candump's default output with -tA (date) timestamps";
  }
  return "?";
}

template <typename NextLine>
bool parse_lines(NextLine&& next_line, const CanFilter& filter, std::vector<CandumpRecord>& records,
                 CandumpError& error, CandumpLogInfo* info_out, CandumpClock clock) {
  CandumpLogInfo info;
  CandumpRecord record;
  std::string_view line;
  int first_line = 0;
  CandumpForm form = CandumpForm::log;
  CandumpStamp stamp = CandumpStamp::none;
  std::int64_t first_ns = 0, previous_ns = 0, sum_ns = 0;
  int previous_line = 0;
  bool sum_overflow = false;  // the -td sum left int64 (so the log is not -td)
  std::string decrease;       // where the printed times first go down
  const std::size_t first_kept = records.size();
  std::vector<std::int64_t> sums;  // the running sum (-td) at each kept record
  for (int number = 1; next_line(line); ++number) {
    switch (parse_candump_line(line, number, record, error)) {
      case CandumpLineKind::error:
        return false;
      case CandumpLineKind::blank:
        break;
      case CandumpLineKind::record:
        if (first_line == 0) {
          first_line = number;
          form = record.form;
          stamp = record.stamp;
          first_ns = record.timestamp_ns;
        } else if (record.form != form || record.stamp != stamp) {
          error = {number, 1,
                   std::string("this line is in ") + describe(record.form, record.stamp) +
                       ", but line " + std::to_string(first_line) + " is in " +
                       describe(form, stamp) + ": a log must be in one form"};
          return false;
        } else if (decrease.empty() && (record.timestamp_ns < previous_ns ||
                                        (record.timestamp_ns == previous_ns && info.frames >= 2))) {
          // -tz grows from frame to frame (a CAN frame takes over 40 us on the wire); -td goes
          // down or, in a steady stream, repeats (the first two may both print 0).
          decrease = "line " + std::to_string(number) +
                     (record.timestamp_ns < previous_ns ? " goes below line " : " repeats line ") +
                     std::to_string(previous_line);
        }
        // Summed only in case the clock is -td: absolute times (-ta) would overflow the sum.
        if (first_line != number && !sum_overflow &&
            __builtin_add_overflow(sum_ns, record.timestamp_ns, &sum_ns))
          sum_overflow = true;
        previous_ns = record.timestamp_ns;
        previous_line = number;
        ++info.frames;
        if (record.fd) ++info.fd_frames;
        if (filter.matches(record.frame)) {
          records.push_back(record);
          sums.push_back(sum_ns);
        }
        break;
    }
  }
  info.form = form;
  // The clock: given (checked against the log) or decided from it.
  auto refuse = [&](const std::string& why) {
    error = {first_line, 1, why};
    return false;
  };
  if (first_line == 0) {
    info.clock = clock == CandumpClock::automatic ? CandumpClock::none : clock;
  } else if (stamp == CandumpStamp::none) {
    if (clock != CandumpClock::automatic && clock != CandumpClock::none)
      return refuse(std::string("the log has no timestamps; cannot read them as ") +
                    to_string(clock));
    info.clock = CandumpClock::none;
    info.clock_reason = describe(form, stamp);
  } else if (stamp == CandumpStamp::date) {
    if (clock != CandumpClock::automatic && clock != CandumpClock::date)
      return refuse(std::string("the log has -tA dates; cannot read them as ") + to_string(clock));
    info.clock = CandumpClock::date;
    info.clock_reason = "-tA: local date and time, read as UTC";
  } else if (clock == CandumpClock::date || clock == CandumpClock::none) {
    // Appended rather than added: GCC 12's -Warray-bounds misfires on string&& + const char* here.
    std::string why = "the log has (seconds.fraction) timestamps; cannot read them as ";
    why += to_string(clock);
    return refuse(why);
  } else if (form == CandumpForm::log && clock == CandumpClock::delta) {
    return refuse("candump -L never writes deltas: read it as absolute (or zero)");
  } else if (clock != CandumpClock::automatic) {
    info.clock = clock;
    info.clock_reason = "given";
  } else if (form == CandumpForm::log) {
    info.clock = CandumpClock::absolute;
    info.clock_reason = "-L: seconds since 1970 (or since the first frame with -tz)";
  } else if (first_ns != 0) {
    info.clock = CandumpClock::absolute;
    info.clock_reason = "-ta: the first time is not 0";
  } else if (!decrease.empty()) {
    info.clock = CandumpClock::delta;
    info.clock_reason = "-td: starts at 0 and " + decrease;
  } else {
    info.clock = CandumpClock::zero;
    info.clock_reason =
        "-tz: starts at 0 and never goes down (a -td log that only grows would "
        "look the same: give the clock as delta then)";
  }
  if (info.clock == CandumpClock::delta) {
    if (sum_overflow)
      return refuse("read as -td deltas, the times add up beyond 292 years: not a -td log");
    for (std::size_t i = first_kept; i < records.size(); ++i)
      records[i].timestamp_ns = sums[i - first_kept];
  }
  if (info_out) *info_out = info;
  return true;
}

}  // namespace

bool parse_candump(std::string_view text, const CanFilter& filter,
                   std::vector<CandumpRecord>& records, CandumpError& error, CandumpLogInfo* info,
                   CandumpClock clock) {
  std::size_t pos = 0;
  auto next_line = [&](std::string_view& line) {
    if (pos >= text.size()) return false;
    std::size_t end = text.find('\n', pos);
    if (end == std::string_view::npos) end = text.size();
    line = text.substr(pos, end - pos);
    pos = end + 1;
    return true;
  };
  return parse_lines(next_line, filter, records, error, info, clock);
}

bool parse_candump(std::istream& in, const CanFilter& filter, std::vector<CandumpRecord>& records,
                   CandumpError& error, CandumpLogInfo* info, CandumpClock clock) {
  std::string buffer;
  auto next_line = [&](std::string_view& line) {
    if (!std::getline(in, buffer)) return false;
    line = buffer;
    return true;
  };
  return parse_lines(next_line, filter, records, error, info, clock);
}

namespace {

std::string id_text(const CanFrame& f, const char* standard, const char* extended) {
  char id[16];
  if (f.error() || f.extended()) {
    std::snprintf(id, sizeof id, extended,
                  f.error() ? f.id & ~kCanRemoteFlag & ~kCanExtendedFlag : f.raw_id());
  } else {
    std::snprintf(id, sizeof id, standard, f.raw_id());
  }
  return id;
}

}  // namespace

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
  line += id_text(f, "%03X#", "%08X#");
  if (record.fd) {
    line += "#0";
  } else if (f.remote()) {
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

std::string format_candump_columns(const CandumpRecord& record, CandumpClock clock) {
  const long long us = static_cast<long long>(record.timestamp_ns / 1000);
  char head[64] = "";
  switch (clock) {
    case CandumpClock::absolute:
      std::snprintf(head, sizeof head, "(%010lld.%06lld) ", us / 1'000'000, us % 1'000'000);
      break;
    case CandumpClock::zero:
    case CandumpClock::delta:
      std::snprintf(head, sizeof head, "(%03lld.%06lld) ", us / 1'000'000, us % 1'000'000);
      break;
    case CandumpClock::date: {
      long long z = us / 1'000'000 / 86400 + 719468;  // H. Hinnant's civil_from_days
      const long long sod = us / 1'000'000 % 86400;
      const long long era = (z >= 0 ? z : z - 146096) / 146097;
      const long long doe = z - era * 146097;
      const long long yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
      const long long doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
      const long long mp = (5 * doy + 2) / 153;
      const long long d = doy - (153 * mp + 2) / 5 + 1;
      const long long m = mp < 10 ? mp + 3 : mp - 9;
      const long long y = yoe + era * 400 + (m <= 2);
      std::snprintf(head, sizeof head, "(%04lld-%02lld-%02lld %02lld:%02lld:%02lld.%06lld) ", y, m,
                    d, sod / 3600, sod / 60 % 60, sod % 60, us % 1'000'000);
      break;
    }
    case CandumpClock::automatic:
    case CandumpClock::none:
      break;
  }
  // candump.c: " " [timestamp] " " interface ["  RX - -"] "  " then lib.c's long frame.
  std::string line = std::string(" ") + head + " " + record.interface;
  if (record.direction != '\0') line += record.direction == 'T' ? "  TX - -" : "  RX - -";
  line += "  ";
  const CanFrame& f = record.frame;
  line += id_text(f, "%03X  ", "%08X  ");
  char len[16];
  std::snprintf(len, sizeof len, " [%u] ", static_cast<unsigned>(f.len));
  line += len;
  if (f.remote()) return line + " remote request";
  char byte[8];
  for (std::uint8_t i = 0; i < f.len && i < kCanMaxDataLength; ++i) {
    std::snprintf(byte, sizeof byte, " %02X", f.data[i]);
    line += byte;
  }
  if (f.error()) line += std::string(3 * (8 - f.len) + 3, ' ') + "ERRORFRAME";
  return line;
}

}  // namespace zerog::io
