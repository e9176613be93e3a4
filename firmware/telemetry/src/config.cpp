#include "zerog/telemetry/config.hpp"

#include <cmath>
#include <string_view>

namespace zerog::telemetry {

namespace {

bool has_xml_special(std::string_view s) {
  return s.find_first_of("<>&\"'") != std::string_view::npos;
}

bool blank_or_control(char c) { return static_cast<unsigned char>(c) <= ' '; }

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
