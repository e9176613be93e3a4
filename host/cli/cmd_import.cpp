// `zerog import`: the user's own recordings → a zerog log (proto/import_mapping.md).
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "bag_import.hpp"
#include "commands.hpp"
#include "zerog/formats/log.hpp"
#include "zerog/io/import.hpp"

namespace zerog::cli {

namespace {

struct ImportOptions {
  std::string mapping;
  std::string out;
  std::string rig;
  bool dry_run = false;
  BagTopics bag;        // --bag: a ROS 2 bag instead of a mapping (bag_import.hpp)
  std::string bag_csv;  // keep the bag's CSV files and mapping here
};

void run_import(const ImportOptions& o) {
  if (o.out.empty() && !o.dry_run) throw CLI::RequiredError("--out (or --dry-run)");
  if (o.mapping.empty() == o.bag.bag.empty()) throw CLI::ValidationError("give --mapping or --bag");
  // A bag's rig is the mapping's [rig] table: --rig with what the bag's TF and stamps say.
  std::optional<std::filesystem::path> rig;
  if (!o.rig.empty() && o.bag.bag.empty()) rig = o.rig;
  std::optional<BagConversion> bag;
  if (!o.bag.bag.empty()) {
    BagTopics topics = o.bag;
    topics.rig = o.rig;
    bag.emplace(topics, o.bag_csv);
  }
  io::ImportResult result;
  try {
    result = io::import_recordings(bag ? bag->mapping() : std::filesystem::path(o.mapping), rig);
  } catch (const std::runtime_error& e) {
    if (!bag) throw;
    // The files named in the message were made from the bag (and go with it).
    throw std::runtime_error(
        std::string(e.what()) + "\n(in the files made from the bag " + o.bag.bag +
        ": --bag-csv DIR keeps them" +
        (o.bag.tf.empty() && o.bag.joints.empty()
             ? "; the sensor's pose comes from --tf BASE:SENSOR, or from --joints with a robot"
             : "") +
        ")");
  }
  if (bag) result.inputs.push_back(o.bag.bag);
  if (!o.dry_run) formats::write_log(result.log, o.out, result.inputs);
  std::fputs(result.report.summary().c_str(), stdout);
  if (o.dry_run) {
    std::printf("dry run: nothing written\n");
  } else {
    std::printf("wrote %s and %s (%zu rows)\n", o.out.c_str(),
                formats::rig_path_for(o.out).string().c_str(), result.log.samples.size());
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
      ->check(CLI::ExistingFile);
  BagTopics& b = options->bag;
  auto* bag = cmd->add_option("--bag", b.bag,
                              "or: a ROS 2 bag (sqlite3 or MCAP directory), read with PyPI's "
                              "rosbags (proto/ros2_bags.md)");
  cmd->add_option("--wrench", b.wrench, "--bag: geometry_msgs/msg/WrenchStamped topic")->needs(bag);
  cmd->add_option("--imu", b.imu, "--bag: sensor_msgs/msg/Imu topic")->needs(bag);
  cmd->add_option("--joints", b.joints, "--bag: sensor_msgs/msg/JointState topic")->needs(bag);
  cmd->add_option("--temperature", b.temperature,
                  "--bag: sensor_msgs/msg/Temperature topic (the F/T sensor's, °C: temp_C)")
      ->needs(bag);
  cmd->add_option("--joint-names", b.joint_names,
                  "--bag: the robot's joints by their JointState names, comma-separated, in the "
                  "robot's order (default: the robot file's ros_name or name of each joint)")
      ->needs(bag);
  cmd->add_option("--robot", b.robot,
                  "--bag: robot file (calib/robots/) for the joints, if the rig names none")
      ->needs(bag)
      ->check(CLI::ExistingFile);
  cmd->add_option("--flange", b.flange,
                  "--bag: the TF frame of the robot's flange, for the sensor's mounting from "
                  "/tf_static (default: the robot file's ros_flange, else tool0)")
      ->needs(bag);
  cmd->add_option("--tf", b.tf, "--bag: BASE:SENSOR, the sensor's pose from /tf and /tf_static")
      ->needs(bag);
  cmd->add_option("--bag-csv", options->bag_csv,
                  "--bag: keep the CSV files and mapping.toml made from the bag in this directory")
      ->needs(bag);
  bag->excludes(cmd->get_option("--mapping"));
  cmd->add_option("-o,--out", options->out,
                  "output log NAME.csv; its rig NAME.rig.toml is written beside it. Both are "
                  "written atomically and never over an input file");
  cmd->add_option("--rig", options->rig,
                  "rig file (NAME.rig.toml) to use instead of the mapping's [rig] table or "
                  "rig_file; with --bag, what the bag does not say (its TF gives the mountings)")
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
      "  zerog import --mapping calib/import_example/mapping.toml --out run.csv\n"
      "\n"
      "A ROS 2 bag (needs rosbags in .venv: scripts/install-deps.sh):\n"
      "  zerog import --bag run_bag --wrench /ft --imu /imu --joints /joint_states \\\n"
      "      --robot calib/robots/kr210_r2700.robot.toml --out run.csv");
  cmd->callback([options] {
    if (!options->bag.bag.empty() && options->bag.wrench.empty())
      throw CLI::RequiredError("--wrench (the WrenchStamped topic of --bag)");
    run_import(*options);
  });
}

}  // namespace zerog::cli
