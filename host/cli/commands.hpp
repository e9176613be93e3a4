#pragma once
// Each `zerog` subcommand registers itself on the top-level CLI11 app.
#include <CLI/CLI.hpp>

namespace zerog::cli {

void add_import_command(CLI::App& app);       // cmd_import.cpp
void add_design_command(CLI::App& app);       // cmd_design.cpp
void add_sim_command(CLI::App& app);          // cmd_sim.cpp
void add_ident_commands(CLI::App& app);       // cmd_ident.cpp: fit, compare, diagnose, ladder
void add_report_command(CLI::App& app);       // cmd_report.cpp
void add_decode_can_command(CLI::App& app);   // cmd_decode_can.cpp
void add_decode_rsi_command(CLI::App& app);   // cmd_decode_rsi.cpp
void add_learn_commands(CLI::App& app);       // cmd_learn.cpp: train, results
void add_export_command(CLI::App& app);       // cmd_export.cpp
void add_watch_command(CLI::App& app);        // cmd_watch.cpp: live telemetry (DDS)
void add_gate_command(CLI::App& app);         // cmd_gate.cpp: the contact gate from the noise
void add_export_mcap_command(CLI::App& app);  // cmd_export_mcap.cpp: a recording as MCAP
void add_servo_command(CLI::App& app);        // cmd_servo.cpp: the servo model from a recording

}  // namespace zerog::cli
