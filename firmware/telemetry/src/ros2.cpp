#include "zerog/telemetry/ros2.hpp"

#include <charconv>
#include <cmath>
#include <cstddef>
#include <cstdio>

namespace zerog::telemetry {

namespace {

// dds_write only reads the sample: the casts drop const for the generated C types.
char* c_str(const std::string& s) { return const_cast<char*>(s.c_str()); }

char kEmpty[] = "";

template <typename Source>
void set_vector(geometry_msgs_msg_dds__Vector3_& v, const Source& s, int first = 0) {
  v.x_ = s[first];
  v.y_ = s[first + 1];
  v.z_ = s[first + 2];
}

void set_wrench(RosWrenchStamped& m, const RosTime& stamp, char* frame,
                const std::array<double, 6>& w) {
  m.header_.stamp_ = stamp;
  m.header_.frame_id_ = frame;
  set_vector(m.wrench_.force_, w, 0);
  set_vector(m.wrench_.torque_, w, 3);
}

void set_pose(RosPoseStamped& m, const RosTime& stamp, char* frame, const Eigen::Vector3d& p,
              const Eigen::Quaterniond& q) {
  m.header_.stamp_ = stamp;
  m.header_.frame_id_ = frame;
  m.pose_.position_.x_ = p.x();
  m.pose_.position_.y_ = p.y();
  m.pose_.position_.z_ = p.z();
  m.pose_.orientation_.x_ = q.x();
  m.pose_.orientation_.y_ = q.y();
  m.pose_.orientation_.z_ = q.z();
  m.pose_.orientation_.w_ = q.w();
}

// The shortest text that reads back to the same double (as cycles.csv writes t_s).
std::string number(double v) {
  char buffer[32];
  const auto r = std::to_chars(buffer, buffer + sizeof buffer, v);
  return std::string(buffer, r.ptr);
}

std::string joined(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& s : items) out += (out.empty() ? "" : ",") + s;
  return out;
}

}  // namespace

std::string ros_dds_topic(const std::string& ros_namespace, const char* name) {
  std::string topic = "rt" + ros_namespace;
  if (topic.back() != '/') topic += '/';
  return topic + name;
}

RosTime ros_time(double t_s) noexcept {
  const auto ns = static_cast<std::int64_t>(std::floor(t_s * 1e9 + 0.5));
  RosTime t{};
  t.sec_ = static_cast<std::int32_t>(ns / 1000000000);
  t.nanosec_ = static_cast<std::uint32_t>(ns % 1000000000);
  return t;
}

Ros2Frames::Ros2Frames(const TelemetryConfig& config)
    : base(config.base_frame),
      sensor(config.sensor_frame),
      imu(config.imu_frame),
      joint_names(config.joint_names) {
  for (const std::string& n : joint_names) joint_name_ptrs.push_back(c_str(n));
}

void to_ros2(const loop::CycleRecord& r, const control::BodyParams& body, const Ros2Frames& frames,
             Ros2CycleMessages& out) noexcept {
  const RosTime stamp = ros_time(r.t_s);
  char* const sensor = c_str(frames.sensor);
  char* const base = c_str(frames.base);
  set_wrench(out.wrench, stamp, sensor, r.wrench_measured);
  set_wrench(out.wrench_at_eval, stamp, sensor, r.wrench_at_eval);
  set_wrench(out.wrench_predicted, stamp, sensor, r.predicted);
  set_wrench(out.wrench_contact, stamp, sensor, r.contact);

  RosImu& imu = out.imu;
  imu.header_.stamp_ = stamp;
  imu.header_.frame_id_ = c_str(frames.imu);
  // No orientation estimate: sensor_msgs/Imu says so with element 0 of its covariance = -1.
  imu.orientation_ = {0.0, 0.0, 0.0, 1.0};
  imu.orientation_covariance_[0] = -1.0;
  set_vector(imu.angular_velocity_, r.rate_imu);
  set_vector(imu.linear_acceleration_, r.specific_force_imu);  // a − g: +g up at rest, as ROS

  RosJointState& joints = out.joints;
  joints.header_.stamp_ = stamp;
  joints.header_.frame_id_ = kEmpty;
  out.joint_positions = r.joints_rad;
  const auto n = static_cast<std::uint32_t>(frames.joint_name_ptrs.size());
  joints.name_._maximum = joints.name_._length = n;
  joints.name_._buffer = const_cast<char**>(frames.joint_name_ptrs.data());
  joints.name_._release = false;
  joints.position_._maximum = joints.position_._length = n;
  joints.position_._buffer = out.joint_positions.data();
  joints.position_._release = false;
  joints.velocity_ = {};
  joints.effort_ = {};

  set_pose(out.sensor_pose, stamp, base, r.p_base_sensor_m, r.q_base_sensor);
  set_pose(out.body_pose, stamp, base, r.body.p_world_m, r.body.q_world_body);

  const control::VirtualBody virtual_body(body, r.body);
  RosTwistStamped& twist = out.body_twist;
  twist.header_.stamp_ = stamp;
  twist.header_.frame_id_ = base;
  set_vector(twist.twist_.linear_, r.body.v_world_mps);
  set_vector(twist.twist_.angular_, virtual_body.omega_world());
}

Ros2Diagnostics ros2_diagnostics(const HealthSample& h, const ModelIdentityInfo& model) {
  Ros2Diagnostics d;
  d.t_s = h.t_s;
  Ros2Diagnostics::Status& s = d.health;
  s.name = "zerog-rt: health";
  s.hardware_id = model.rig_name;
  const char* state = state_code_name(h.state);
  const char* fault = fault_code_name(h.fault);
  s.message = std::string("state ") + state + ", fault " + fault;
  s.level = h.state == 3 ? 2 : (h.telemetry_drops != 0 || h.write_errors != 0) ? 1 : 0;
  const auto u = [&s](const char* key, std::uint64_t v) {
    s.values.emplace_back(key, std::to_string(v));
  };
  u("health_seq", h.health_seq);
  u("cycle", h.cycle);
  s.values.emplace_back("t_s", number(h.t_s));
  s.values.emplace_back("state", state);
  s.values.emplace_back("fault", fault);
  u("flags", h.flags);
  u("records_offered", h.records_offered);
  u("records_published", h.records_published);
  u("telemetry_drops", h.telemetry_drops);
  u("write_errors", h.write_errors);
  u("robot_lost", h.robot_lost);
  u("datagrams_lost", h.datagrams_lost);
  u("ipoc_gaps", h.ipoc_gaps);
  u("ft_held_cycles", h.ft_held_cycles);
  u("imu_held_cycles", h.imu_held_cycles);
  u("replies_failed", h.replies_failed);
  u("record_drops", h.record_drops);
  u("commands_refused", h.commands_refused);
  u("transitions", h.transitions);
  u("poses_from_joints", h.poses_from_joints);
  u("pose_disagreements", h.pose_disagreements);
  u("poses_missing", h.poses_missing);

  Ros2Diagnostics::Status& m = d.model;
  m.name = "zerog-rt: model";
  m.hardware_id = model.rig_name;
  m.message = model.deploy_file;
  auto& v = m.values;
  v.emplace_back("rig_name", model.rig_name);
  v.emplace_back("robot", model.robot);
  v.emplace_back("effects", joined(model.effects));
  v.emplace_back("has_network", model.has_network ? "true" : "false");
  std::vector<std::string> width;
  for (std::int32_t w : model.network_width) width.push_back(std::to_string(w));
  v.emplace_back("network_width", joined(width));
  v.emplace_back("network_activations", joined(model.network_activations));
  v.emplace_back("network_features", joined(model.network_features));
  v.emplace_back("network_outputs", joined(model.network_outputs));
  v.emplace_back("weight_bits", std::to_string(model.weight_bits));
  v.emplace_back("deploy_file", model.deploy_file);
  char crc[16];
  std::snprintf(crc, sizeof crc, "0x%08x", static_cast<unsigned>(model.deploy_crc32));
  v.emplace_back("deploy_crc32", crc);
  v.emplace_back("provenance_json", model.provenance_json);
  return d;
}

RosDiagnosticArray diagnostics_message(const Ros2Diagnostics& d, Ros2DiagnosticsStorage& storage) {
  const Ros2Diagnostics::Status* parts[2] = {&d.health, &d.model};
  storage.status.assign(2, {});
  storage.values.clear();
  storage.values.reserve(d.health.values.size() + d.model.values.size());  // no reallocation
  for (std::size_t i = 0; i < 2; ++i) {
    const Ros2Diagnostics::Status& in = *parts[i];
    diagnostic_msgs_msg_dds__DiagnosticStatus_& out = storage.status[i];
    out.level_ = in.level;
    out.name_ = c_str(in.name);
    out.message_ = c_str(in.message);
    out.hardware_id_ = c_str(in.hardware_id);
    out.values_._maximum = out.values_._length = static_cast<std::uint32_t>(in.values.size());
    out.values_._buffer = storage.values.data() + storage.values.size();
    out.values_._release = false;
    for (const auto& [key, value] : in.values) storage.values.push_back({c_str(key), c_str(value)});
  }
  RosDiagnosticArray a{};
  a.header_.stamp_ = ros_time(d.t_s);
  a.header_.frame_id_ = kEmpty;
  a.status_._maximum = a.status_._length = 2;
  a.status_._buffer = storage.status.data();
  a.status_._release = false;
  return a;
}

}  // namespace zerog::telemetry
