#pragma once
// Settings of zerog-rt's live telemetry (proto/telemetry.md, "Network") and the Cyclone DDS XML
// configuration built from them, which TelemetryChannel hands to dds_create_domain (so a VM or
// a cell network without multicast works without a CYCLONEDDS_URI file). Start-up only.
#include <string>
#include <vector>

#include "zerog/status.hpp"

namespace zerog::telemetry {

/// The largest DDS domain id with Cyclone's default port mapping (DDSI 9.6.1.1: port ≤ 65535).
inline constexpr int kMaxDomainId = 232;

struct TelemetryConfig {
  int domain_id = 0;
  /// Network interface to use (e.g. "lo", "eth1"); empty: Cyclone picks one.
  std::string interface;
  /// Unicast discovery peers (addresses or host names, e.g. "127.0.0.1"); needed when
  /// multicast is off.
  std::vector<std::string> peers;
  bool allow_multicast = true;
  /// Prepended to every topic name ("zerog/" → "zerog/wrench", …).
  std::string topic_prefix = "zerog/";
  /// Health is published on every change and at least this often (s).
  double health_period_s = 1.0;
  /// The robot's nominal cycle (s): timing's jitter is the measured period minus this.
  double nominal_period_s = 0.004;
  /// How long the publisher thread sleeps when its queue is empty (s).
  double poll_period_s = 0.001;

  // ROS 2 topics (proto/telemetry.md, "ROS 2 topics"): ROS 2's message types on `rt/` DDS
  // topics, beside the zerog/ ones, written by the same publisher thread from the same record.
  /// Publish them.
  bool ros2 = true;
  /// ROS namespace of the topics ("/zerog" → ROS /zerog/wrench → DDS rt/zerog/wrench).
  std::string ros_namespace = "/zerog";
  /// header.frame_id of what is in the robot's base frame (poses, twists).
  std::string base_frame = "base_link";
  /// header.frame_id of the wrenches (the F/T sensor frame S).
  std::string sensor_frame = "ft_sensor";
  /// header.frame_id of the IMU sample (frame I).
  std::string imu_frame = "imu_link";
  /// sensor_msgs/JointState names of A1..A6 (the robot's URDF names: the robot file's
  /// `ros_name`s; ROS-Industrial's KUKA descriptions call them joint_a1..joint_a6).
  std::vector<std::string> joint_names = {"joint_a1", "joint_a2", "joint_a3",
                                          "joint_a4", "joint_a5", "joint_a6"};
};

/// ok() if `config` can be used; otherwise invalid_setting naming the TelemetryConfig field
/// (setting() "domain_id", "peers", …; message() "300 is outside 0..232").
Status check_config(const TelemetryConfig& config);

/// The Cyclone DDS XML configuration (<CycloneDDS><Domain>…) for `config`. Call check_config
/// first: names with XML special characters are refused there, not escaped here.
std::string cyclone_xml(const TelemetryConfig& config);

}  // namespace zerog::telemetry
