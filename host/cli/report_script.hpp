#pragma once
// Runs host/report/make_report.py (matplotlib) with Debian's python3; its interactive page
// with the project's .venv python (plotly), named to it in $ZEROG_PYTHON.
#include <string>
#include <vector>

namespace zerog::cli {

/// Runs the report script with `args`; throws std::runtime_error if it fails.
void run_report_script(const std::vector<std::string>& args);

}  // namespace zerog::cli
