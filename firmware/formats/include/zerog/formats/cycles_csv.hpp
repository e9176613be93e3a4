#pragma once
// The CSV form of loop::CycleRecord (every field; proto/loop.md, "Record CSV"): `cycles.csv` of
// a recording and the black-box dumps, written by zerog-rt's recorder and read back by
// zerog-telemetry-replay (host/tools). Writer and reader live together so that they cannot drift
// apart. Formatting allocates: called from the recorder thread, never from the cycle.
#include <filesystem>
#include <string>
#include <vector>

#include "zerog/loop/cycle_record.hpp"

namespace zerog::formats {

/// Appends the header line (column names, comma separated, '\n').
void append_record_header(std::string& out);
/// Appends one row: numbers in C locale, shortest text that reads back exactly; state, fault
/// and model status by name; flags as decimal integers (bits in loop::CycleFlags and
/// control::LimitFlags). The record's reply (SI) is written in the wire's units, as the robot
/// got it: rkorr_* in mm and degrees, akorr_* in degrees (proto::rsi::reply_from_correction, the
/// RSI border's function; the cycle itself never converts). temp_C is the temperature the model
/// was fed (°C; an unknown one, NaN, as an empty cell), temp_measured 1 when it was the F/T
/// sensor's reading. Not written: temperature_age_s (from the frames' receive times, the wall
/// clock: a lockstep run would not repeat byte for byte) and the pose check.
void append_record_row(const loop::CycleRecord& record, std::string& out);
/// Number of columns of the header and of every row.
int record_column_count();

/// Reads a cycles.csv (columns found by their header names) back into records. Throws
/// std::runtime_error naming the file (and line) for an unreadable file, a missing column, too
/// few cells, a cell that is not a number or an unknown state, fault or model status name.
/// The reply comes back in SI (proto::rsi::correction_from_reply: equal up to rounding; an
/// RKorr of zeros reads as Kind::none). The temperature columns are optional: files written
/// before them (or an empty temp_C) read as temperature_C NaN (unknown), not measured.
std::vector<loop::CycleRecord> read_cycles_csv(const std::filesystem::path& path);

}  // namespace zerog::formats
