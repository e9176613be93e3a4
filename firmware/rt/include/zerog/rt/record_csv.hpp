#pragma once
// The CSV form of loop::CycleRecord (every field; proto/loop.md, "Record CSV"): used for
// `cycles.csv` of a recording and for the black-box dumps. Host-side formatting (allocates):
// called from the recorder thread, never from the cycle.
#include <string>

#include "zerog/loop/cycle.hpp"

namespace zerog::rt {

/// Appends the header line (column names, comma separated, '\n').
void append_record_header(std::string& out);
/// Appends one row: numbers in C locale, shortest text that reads back exactly; state, fault
/// and model status by name; flags as decimal integers (bits in loop::CycleFlags and
/// control::LimitFlags).
void append_record_row(const loop::CycleRecord& record, std::string& out);
/// Number of columns of the header and of every row.
int record_column_count();

}  // namespace zerog::rt
