// Kinematics from the robot (proto/import_mapping.md "kinematics", proto/robot_kinematics.md):
// the IMU columns derived from the joints or the pose, or fused with the IMU
// (import_kinematics.cpp), once the series are merged into the log's rows.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "import_series.hpp"
#include "zerog/robot/forward_kinematics.hpp"

namespace zerog::io::importer {

std::string quantity_file(const Mapping& m, const std::array<int, kQuantityCount>& source,
                          Quantity q);
robot::RobotModel robot_for_joints(const Mapping& m, const fs::path& mapping_path,
                                   const formats::Log& log,
                                   const std::array<int, kQuantityCount>& source,
                                   const std::string& use);
void derive_from_robot(const Mapping& m, const fs::path& mapping_path,
                       const std::vector<Series>& series,
                       const std::array<int, kQuantityCount>& source, ImportResult& result);
void fuse_joints_and_imu(const Mapping& m, const fs::path& mapping_path,
                         const std::vector<Series>& series,
                         const std::array<int, kQuantityCount>& source, ImportResult& result);

}  // namespace zerog::io::importer
