#pragma once
// Parser for the text can-utils' candump writes, in every form it has (checked against
// can-utils' candump.c and lib.c: sprint_timestamp(), sprint_canframe(),
// snprintf_long_canframe()):
//
//   log file (`candump -L`, `-l`; what canplayer reads):
//     (1700000000.123456) can0 123#DEADBEEF
//     (1700000000.123789) can0 123#R          remote frame (optionally `123#R4`: length 4)
//     (1700000000.124000) can1 12345678#0102  extended id (8 hex digits)
//     (1700000000.125000) can0 123#DE.AD.BE.EF T    optional '.' separators; `R`/`T` (rx/tx, -x)
//     (1700000000.126000) can0 123##1DEAD     CAN FD (flags nibble, then up to 64 bytes)
//   default screen output (`candump can0`), columns:
//       can0  123   [4]  DE AD BE EF         no timestamp: the log has no time at all
//       can0  123   [0]  remote request
//       can0  12345678   [2]  01 02          extended id; standard ids may be indented by 5
//       can0  123  [12]  00 11 … BB          CAN FD ([NN]: two digits, up to [64])
//       can0  20000004   [8]  00 04 00 00 00 00 00 00   ERRORFRAME
//    (1700000000.123456)  can0  123   [4]  DE AD BE EF            -ta (absolute, s since 1970)
//    (000.000123)  can0  123   [4]  DE AD BE EF                   -tz (since the first frame)
//    (000.000123)  can0  123   [4]  DE AD BE EF                   -td (since the previous frame)
//    (2023-11-14 22:13:20.123456)  can0  123   [4]  DE AD BE EF   -tA (local date and time)
//      can0  RX - -  123   [4]  DE AD BE EF   -x (direction, then BRS/ESI)
//   The ASCII column of -a (`'....'`) is accepted and ignored. Not accepted (named when seen):
//   -i (binary), -S (swapped bytes), -8 (`{B}` raw DLC), -e (error text lines), CAN XL.
//
// A log is one form throughout: parse_candump() refuses a line in another form than the log's
// first record. -tz and -td print the same "(SSS.ffffff)"; CandumpClock::automatic tells them
// apart over the whole log: both start at 0; a -tz log grows with every frame (a CAN frame takes
// over 40 us on the wire), a -td log goes down or repeats a value somewhere (a steady stream
// prints the same delta again). Give the clock explicitly for a -td log whose deltas only grow,
// or a -tz log of several buses with equal stamps. -tA is local time without a zone: it is read as
// if UTC (differences are exact except across a daylight-saving change).
//
// An 8-digit id with bit 29 set is an error frame, as in can-utils' parse_canframe(). Blank lines
// are skipped. CAN FD frames are checked (length, hex) and kept with `fd` set, but their payload
// is not: `frame` holds the id and flags with len 0 (zerog's sensors speak classical CAN).
//
// HOST SIDE (zerog::io, for `zerog decode-can`; the names stay in zerog::proto with the CAN
// frame they produce): uses std::string and std::vector; not real-time safe.
#include <cstdint>
#include <iosfwd>
#include <string>
#include <string_view>
#include <vector>

#include "zerog/proto/can_frame.hpp"

namespace zerog::io {

/// The line form: candump's log-file form (`-L`) or its default columns.
enum class CandumpForm : std::uint8_t { log, columns };
/// What a line's timestamp looks like.
enum class CandumpStamp : std::uint8_t {
  none,     ///< no timestamp (the default output without -t)
  seconds,  ///< "(1700000000.123456)" (-L, -ta) or "(000.000123)" (-tz, -td)
  date,     ///< "(2023-11-14 22:13:20.123456)" (-tA)
};
/// What a log's timestamps mean.
enum class CandumpClock : std::uint8_t {
  automatic,  ///< decide from the log (see the header comment)
  absolute,   ///< seconds since 1970 (-L, -ta)
  zero,       ///< seconds since the first frame (-tz)
  delta,      ///< seconds since the previous frame (-td): summed on reading
  date,       ///< local date and time (-tA), read as UTC
  none,       ///< no time in the log
};
const char* to_string(CandumpClock clock);
/// Reads "auto", "absolute", "zero", "delta", "date", "none"; false on anything else.
bool parse_candump_clock(std::string_view text, CandumpClock& out);

struct CandumpRecord {
  /// Nanoseconds. Per line as printed (a -td line: since the previous frame; -tA: the date as
  /// UTC); after parse_candump(), on the log's clock (-td summed). 0 without timestamps.
  std::int64_t timestamp_ns = 0;
  std::string interface;       ///< e.g. "can0"
  proto::CanFrame frame;       ///< flags set as SocketCAN would (extended, remote, error)
  char direction = '\0';       ///< 'R' or 'T' when the log says so (candump -x), else '\0'
  bool fd = false;             ///< a CAN FD frame: `frame` holds id and flags, no payload
  std::uint8_t fd_length = 0;  ///< its data length (0–64)
  CandumpForm form = CandumpForm::log;
  CandumpStamp stamp = CandumpStamp::seconds;
};

struct CandumpError {
  int line = 0;    ///< 1-based
  int column = 0;  ///< 1-based byte column of the offending character
  std::string reason;
  /// "line L, column C: reason"
  std::string message() const;
};

enum class CandumpLineKind : std::uint8_t { record, blank, error };

/// Parses one line (without or with its trailing "\n"/"\r\n") in any of the forms above. On
/// error fills `error` (with `line_number` as its line) and leaves `out` unspecified.
CandumpLineKind parse_candump_line(std::string_view line, int line_number, CandumpRecord& out,
                                   CandumpError& error);

/// What parse_candump() found out about a log.
struct CandumpLogInfo {
  CandumpForm form = CandumpForm::log;
  CandumpClock clock = CandumpClock::none;  ///< resolved (never automatic once records exist)
  std::size_t frames = 0;                   ///< every frame, before the filter
  std::size_t fd_frames = 0;                ///< CAN FD frames among them
  /// Why `clock` was chosen, in words (e.g. "-td: line 7 goes below line 6").
  std::string clock_reason;
};

/// Parses a whole log, keeping only the frames `filter` passes, with timestamps on the log's
/// clock (`clock`, or decided from the log). Stops at the first error: returns false with
/// `error` filled. `records` holds the frames before the error (timestamps then as printed).
bool parse_candump(std::string_view text, const proto::CanFilter& filter,
                   std::vector<CandumpRecord>& records, CandumpError& error,
                   CandumpLogInfo* info = nullptr, CandumpClock clock = CandumpClock::automatic);
/// The same, reading from a stream.
bool parse_candump(std::istream& in, const proto::CanFilter& filter,
                   std::vector<CandumpRecord>& records, CandumpError& error,
                   CandumpLogInfo* info = nullptr, CandumpClock clock = CandumpClock::automatic);

/// Formats one record into the log-file form (upper-case hex, as candump -L does). A CAN FD
/// record formats with zero bytes of payload (the payload is not kept).
std::string format_candump_line(const CandumpRecord& record);

/// Formats one classical CAN record in candump's default columns with the timestamp of
/// `clock` (absolute: "(%010llu.%06llu) ", zero/delta: "(%03llu.%06llu) " of `timestamp_ns` as
/// given, date: its UTC date, none: nothing), as `candump [-t…] can0` prints it to a terminal.
/// For tests and fixtures.
std::string format_candump_columns(const CandumpRecord& record, CandumpClock clock);

}  // namespace zerog::io
