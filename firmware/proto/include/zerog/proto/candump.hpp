#pragma once
// Parser for can-utils log files, the format `candump -L` writes (and `canplayer` reads):
//
//     (1700000000.123456) can0 123#DEADBEEF
//     (1700000000.123789) can0 123#R          remote frame (optionally `123#R4`: length 4)
//     (1700000000.124000) can1 12345678#0102  extended id (8 hex digits)
//     (1700000000.125000) can0 123#DE.AD.BE.EF T    optional '.' separators; `R`/`T` (rx/tx)
//
// Only this format is accepted (not candump's default columns, not CAN FD `##`). An 8-digit id
// with bit 29 set is an error frame, as in can-utils' parse_canframe(). Blank lines are skipped.
//
// HOST SIDE: uses std::string and std::vector; not real-time safe.
#include <cstdint>
#include <iosfwd>
#include <string>
#include <string_view>
#include <vector>

#include "zerog/proto/can_frame.hpp"

namespace zerog::proto {

struct CandumpRecord {
  std::int64_t timestamp_ns = 0;  ///< seconds.fraction from the log, in ns (1–9 digits accepted)
  std::string interface;          ///< e.g. "can0"
  CanFrame frame;                 ///< flags set as SocketCAN would (extended, remote, error)
  char direction = '\0';          ///< 'R' or 'T' when the log says so (candump -x), else '\0'
};

struct CandumpError {
  int line = 0;    ///< 1-based
  int column = 0;  ///< 1-based byte column of the offending character
  std::string reason;
  /// "line L, column C: reason"
  std::string message() const;
};

enum class CandumpLineKind : std::uint8_t { record, blank, error };

/// Parses one line (without or with its trailing "\n"/"\r\n"). On error fills `error` (with
/// `line_number` as its line) and leaves `out` unspecified.
CandumpLineKind parse_candump_line(std::string_view line, int line_number, CandumpRecord& out,
                                   CandumpError& error);

/// Parses a whole log, keeping only the frames `filter` passes. Stops at the first error: returns
/// false with `error` filled. `records` holds the frames before the error.
bool parse_candump(std::string_view text, const CanFilter& filter,
                   std::vector<CandumpRecord>& records, CandumpError& error);
/// The same, reading from a stream.
bool parse_candump(std::istream& in, const CanFilter& filter, std::vector<CandumpRecord>& records,
                   CandumpError& error);

/// Formats one record back into the log format (upper-case hex, as candump does).
std::string format_candump_line(const CandumpRecord& record);

}  // namespace zerog::proto
