#include "zerog/telemetry/config.hpp"

#include <cmath>
#include <string_view>
#include <utility>

namespace zerog::telemetry {

namespace {

bool has_xml_special(std::string_view s) {
  return s.find_first_of("<>&\"'") != std::string_view::npos;
}

bool blank_or_control(char c) { return static_cast<unsigned char>(c) <= ' '; }

bool ros_name_char(char ch) {
  return (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') ||
         ch == '_' || ch == '/';
}

// ROS 2's rules for names (design article "Topic and Service name mapping to DDS"): letters,
// digits, '_' and '/'; no "//", no trailing '/', no digit after a '/'. A namespace is absolute
// ("/zerog"); a frame id or joint name is a plain name (a leading '/' is ROS 1's habit).
Status check_ros_name(const char* key, const std::string& name, bool ns) {
  const auto bad = [&](const char* why) { return Status::invalid(key, "\"" + name + "\" " + why); };
  if (name.empty()) return ns ? bad("is empty (\"/zerog\", or \"/\" for none)") : bad("is empty");
  if (ns && name.front() != '/') return bad("must start with '/' (an absolute namespace)");
  if (!ns && name.front() == '/') return bad("must not start with '/'");
  for (std::size_t i = 0; i < name.size(); ++i) {
    if (!ros_name_char(name[i])) return bad("may hold only letters, digits, '_' and '/'");
    if (name[i] == '/' && i + 1 < name.size() &&
        (name[i + 1] == '/' || (name[i + 1] >= '0' && name[i + 1] <= '9')))
      return bad("has \"//\" or a digit after '/'");
  }
  if (name.size() > 1 && name.back() == '/') return bad("must not end with '/'");
  return {};
}

}  // namespace

Status check_config(const TelemetryConfig& c) {
  if (c.domain_id < 0 || c.domain_id > kMaxDomainId)
    return Status::invalid("domain_id", std::to_string(c.domain_id) + " is outside 0.." +
                                            std::to_string(kMaxDomainId));
  if (!c.interface.empty()) {
    if (c.interface.size() > 15)
      return Status::invalid("interface", "\"" + c.interface + "\" is longer than 15 characters");
    for (char ch : c.interface)
      if (blank_or_control(ch) || has_xml_special(std::string_view(&ch, 1)) || ch == '/')
        return Status::invalid("interface", "\"" + c.interface + "\" is not an interface name");
  }
  for (const std::string& p : c.peers) {
    if (p.empty()) return Status::invalid("peers", "an empty address");
    for (char ch : p)
      if (blank_or_control(ch) || has_xml_special(std::string_view(&ch, 1)))
        return Status::invalid("peers", "\"" + p + "\" is not an address or host name");
  }
  if (!c.allow_multicast && c.peers.empty())
    return Status::invalid("peers",
                           "multicast is off, so discovery needs at least one unicast peer "
                           "(e.g. 127.0.0.1 for this host)");
  if (c.topic_prefix.empty()) return Status::invalid("topic_prefix", "empty");
  for (char ch : c.topic_prefix) {
    const bool ok = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') ||
                    (ch >= '0' && ch <= '9') || ch == '_' || ch == '/';
    if (!ok)
      return Status::invalid(
          "topic_prefix", "\"" + c.topic_prefix + "\" may hold only letters, digits, '_' and '/'");
  }
  if (c.ros2) {
    if (Status st = check_ros_name("ros_namespace", c.ros_namespace, true); !st.ok()) return st;
    for (const auto& [key, value] :
         {std::pair<const char*, const std::string*>{"base_frame", &c.base_frame},
          {"sensor_frame", &c.sensor_frame},
          {"imu_frame", &c.imu_frame}}) {
      if (Status st = check_ros_name(key, *value, false); !st.ok()) return st;
    }
    if (c.joint_names.size() != 6)
      return Status::invalid("joint_names",
                             std::to_string(c.joint_names.size()) + " names: A1..A6 need 6");
    for (const std::string& n : c.joint_names)
      if (Status st = check_ros_name("joint_names", n, false); !st.ok()) return st;
  }
  if (!std::isfinite(c.health_period_s) || c.health_period_s <= 0.0)
    return Status::invalid("health_period_s", "must be a positive number of seconds");
  if (!std::isfinite(c.nominal_period_s) || c.nominal_period_s <= 0.0)
    return Status::invalid("nominal_period_s", "must be a positive number of seconds");
  if (!std::isfinite(c.poll_period_s) || c.poll_period_s <= 0.0 || c.poll_period_s > 0.1)
    return Status::invalid("poll_period_s", "must lie in (0, 0.1] s");
  return {};
}

std::string cyclone_xml(const TelemetryConfig& c) {
  std::string xml = "<CycloneDDS><Domain id=\"any\"><General>";
  if (!c.interface.empty())
    xml += "<Interfaces><NetworkInterface name=\"" + c.interface + "\"/></Interfaces>";
  xml += c.allow_multicast ? "<AllowMulticast>true</AllowMulticast>"
                           : "<AllowMulticast>false</AllowMulticast>";
  xml += "</General>";
  if (!c.peers.empty()) {
    // Unicast discovery: each participant takes the next free participant index, and peers
    // are probed on the ports of indices 0..MaxAutoParticipantIndex (default 9).
    xml += "<Discovery><ParticipantIndex>auto</ParticipantIndex><Peers>";
    for (const std::string& p : c.peers) xml += "<Peer address=\"" + p + "\"/>";
    xml += "</Peers></Discovery>";
  }
  xml += "</Domain></CycloneDDS>";
  return xml;
}

}  // namespace zerog::telemetry
