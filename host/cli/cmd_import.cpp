// `zerog import`: the user's own recordings → a zerog log (proto/import_mapping.md).
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "commands.hpp"
#include "zerog/io/import.hpp"
#include "zerog/io/log.hpp"

namespace zerog::cli {

namespace {

struct ImportOptions {
  std::string mapping;
  std::string out;
  std::string rig;
  bool dry_run = false;
};

void run_import(const ImportOptions& o) {
  if (o.out.empty() && !o.dry_run) throw CLI::RequiredError("--out (or --dry-run)");
  std::optional<std::filesystem::path> rig;
  if (!o.rig.empty()) rig = o.rig;
  const io::ImportResult result = io::import_recordings(o.mapping, rig);
  if (!o.dry_run) io::write_log(result.log, o.out, result.inputs);
  std::fputs(result.report.summary().c_str(), stdout);
  if (o.dry_run) {
    std::printf("dry run: nothing written\n");
  } else {
    std::printf("wrote %s and %s (%zu rows)\n", o.out.c_str(),
                io::rig_path_for(o.out).string().c_str(), result.log.samples.size());
  }
}

}  // namespace

void add_import_command(CLI::App& app) {
  auto options = std::make_shared<ImportOptions>();
  CLI::App* cmd = app.add_subcommand(
      "import",
      "Turn your own recordings (delimited text files, any rates and units) into a zerog log");
  cmd->add_option("-m,--mapping", options->mapping,
                  "mapping file (TOML), format in proto/import_mapping.md")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_option("-o,--out", options->out,
                  "output log NAME.csv; its rig NAME.rig.toml is written beside it. Both are "
                  "written atomically and never over an input file");
  cmd->add_option("--rig", options->rig,
                  "rig file (NAME.rig.toml) to use instead of the mapping's [rig] table or "
                  "rig_file")
      ->check(CLI::ExistingFile);
  cmd->add_flag("--dry-run", options->dry_run,
                "read, check and merge everything and print the summary, but write nothing");
  cmd->footer(
      "A TOML mapping file names the input files (delimited text with a header row; one or\n"
      "several, recorded at different rates), the columns to take from each and their units\n"
      "(g or m/s^2, deg or rad, mm or m, s/ms/us), and the orientation as a quaternion, a\n"
      "rotation matrix r11..r33 or KUKA A/B/C angles. All files are merged by time onto the\n"
      "rows of one master file (linear interpolation, slerp for orientations). Master rows\n"
      "outside another file's time span are dropped and counted in the summary. Errors name\n"
      "the file, line and column. Format: proto/import_mapping.md.\n"
      "\n"
      "Example (calib/import_example/):\n"
      "  zerog import --mapping calib/import_example/mapping.toml --out run.csv");
  cmd->callback([options] { run_import(*options); });
}

}  // namespace zerog::cli
