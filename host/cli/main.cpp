// zerog — host tools: simulate a rig, import recordings, fit and diagnose the force model.
#include <cstdio>
#include <exception>

#include "commands.hpp"
#include "zerog/formats/log.hpp"

int main(int argc, char** argv) {
  CLI::App app{"zerog: force model of a payload on a wrist F/T sensor; fit, compare, diagnose"};
  app.require_subcommand(1);
  app.set_version_flag("--version", "zerog 0.1.0");
  zerog::cli::add_import_command(app);
  zerog::cli::add_design_command(app);
  zerog::cli::add_sim_command(app);
  zerog::cli::add_ident_commands(app);
  zerog::cli::add_report_command(app);
  zerog::cli::add_decode_can_command(app);
  zerog::cli::add_decode_rsi_command(app);
  zerog::cli::add_learn_commands(app);
  zerog::cli::add_export_command(app);
  zerog::cli::add_watch_command(app);
  zerog::cli::add_gate_command(app);
  zerog::cli::add_servo_command(app);
  zerog::cli::add_export_mcap_command(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  } catch (const zerog::formats::InputError& e) {
    std::fprintf(stderr, "zerog: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "zerog: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
