#pragma once
// `zerog import --bag`: a ROS 2 bag (sqlite3 or MCAP) → plain CSV files and an import mapping,
// written by host/io/bag_to_csv.py (PyPI's rosbags, in the project's .venv; no ROS installation)
// into a temporary directory that zerog import then reads like any mapping
// (proto/ros2_bags.md). HOST SIDE.
#include <filesystem>
#include <string>

namespace zerog::cli {

struct BagTopics {
  std::string bag;          ///< the bag directory (or its .db3 / .mcap file)
  std::string wrench;       ///< geometry_msgs/msg/WrenchStamped (required: the log's rows)
  std::string imu;          ///< sensor_msgs/msg/Imu ("" = none)
  std::string joints;       ///< sensor_msgs/msg/JointState ("" = none)
  std::string temperature;  ///< sensor_msgs/msg/Temperature, °C → temp_C ("" = none)
  std::string joint_names;  ///< the robot's joints by name, its order ("" = the robot's names)
  std::string tf;           ///< "BASE:SENSOR" from /tf and /tf_static ("" = no pose)
  std::string rig;          ///< the rig file: what the bag does not say ("" = none)
  std::string robot;        ///< a robot file, if the rig names none ("" = the rig's)
  std::string flange;       ///< the TF frame of the flange ("" = the robot's ros_flange, tool0)
};

/// The converted bag: the CSV files and mapping.toml in a directory that is removed again when
/// this object goes (unless it was given: `keep_dir`).
class BagConversion {
 public:
  /// Runs the converter. The python is $ZEROG_PYTHON, else the project's .venv/bin/python; the
  /// script $ZEROG_BAG_SCRIPT, else the installed or the source tree's bag_to_csv.py. Throws
  /// std::runtime_error with the converter's message (bag, topic, why), or, when the venv or
  /// rosbags is missing, telling the user to run scripts/install-deps.sh.
  BagConversion(const BagTopics& topics, const std::filesystem::path& keep_dir = {});
  ~BagConversion();
  BagConversion(const BagConversion&) = delete;
  BagConversion& operator=(const BagConversion&) = delete;

  const std::filesystem::path& mapping() const { return mapping_; }
  const std::filesystem::path& dir() const { return dir_; }

 private:
  std::filesystem::path dir_, mapping_;
  bool remove_ = true;
};

}  // namespace zerog::cli
