#include "zerog/rt/config.hpp"

#include <arpa/inet.h>

#include <toml++/toml.h>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <sstream>
#include <string_view>
#include <vector>

#include "zerog/rtio/serial_port.hpp"

namespace zerog::rt {

namespace fs = std::filesystem;

namespace {

std::string location(const fs::path& file, int line, int column) {
  std::string out = file.string();
  if (line > 0) {
    out += ":" + std::to_string(line);
    if (column > 0) out += ":" + std::to_string(column);
  }
  return out;
}

std::string number_text(double v) {
  char buffer[32];
  const auto [end, ec] = std::to_chars(buffer, buffer + sizeof buffer, v);
  return ec == std::errc{} ? std::string(buffer, end) : std::string("?");
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diagonal = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

// One table of the file with the keys it may have. Every accessor throws ConfigError at the
// offending key or value, naming the dotted key.
class Table {
 public:
  Table(const fs::path& file, const toml::table* table, std::string prefix,
        toml::source_region where, std::initializer_list<std::string_view> known)
      : file_(file), table_(table), prefix_(std::move(prefix)), where_(where), known_(known) {
    if (table_ == nullptr) return;
    for (const auto& entry : *table_) {
      const toml::key& key = entry.first;
      const std::string_view k = key.str();
      if (std::find(known_.begin(), known_.end(), k) != known_.end()) continue;
      std::string why = "unknown key";
      std::string_view best;
      std::size_t best_distance = 3;
      for (std::string_view candidate : known_) {
        const std::size_t d = edit_distance(k, candidate);
        if (d < best_distance) {
          best_distance = d;
          best = candidate;
        }
      }
      if (!best.empty()) why += " (did you mean '" + name(best) + "'?)";
      why += "; the keys of " +
             (prefix_.empty() ? std::string("the file") : "[" + section() + "]") +
             " are listed in proto/rt_config.md";
      fail(name(k), key.source(), why);
    }
  }

  bool present() const { return table_ != nullptr; }
  std::string name(std::string_view key) const { return prefix_ + std::string(key); }
  std::string section() const {
    return prefix_.empty() ? "" : prefix_.substr(0, prefix_.size() - 1);
  }

  [[noreturn]] void fail(const std::string& key, const toml::source_region& where,
                         const std::string& why) const {
    throw ConfigError(file_, key, static_cast<int>(where.begin.line),
                      static_cast<int>(where.begin.column), why);
  }

  const toml::node* find(std::string_view key) const {
    return table_ == nullptr ? nullptr : table_->get(key);
  }

  const toml::node& require(std::string_view key) const {
    const toml::node* node = find(key);
    if (node == nullptr) {
      fail(name(key), where_,
           table_ == nullptr ? "missing: the file has no [" + section() + "] table"
                             : "missing required key in [" + section() + "]");
    }
    return *node;
  }

  /// A sub-table (a TOML table), or an absent one (nullptr inside) when it is not there.
  Table table(std::string_view key, std::initializer_list<std::string_view> known) const {
    const toml::node* node = find(key);
    if (node != nullptr && !node->is_table())
      fail(name(key), node->source(), "must be a table ([" + name(key) + "])");
    const toml::table* t = node != nullptr ? node->as_table() : nullptr;
    return Table(file_, t, name(key) + ".", t != nullptr ? t->source() : where_, known);
  }

  std::string string(std::string_view key) const {
    const toml::node& node = require(key);
    if (!node.is_string()) fail(name(key), node.source(), "must be a string");
    return std::string(*node.value<std::string_view>());
  }
  std::string string(std::string_view key, const std::string& fallback) const {
    return find(key) == nullptr ? fallback : string(key);
  }

  bool boolean(std::string_view key, bool fallback) const {
    const toml::node* node = find(key);
    if (node == nullptr) return fallback;
    if (!node->is_boolean()) fail(name(key), node->source(), "must be true or false");
    return *node->value<bool>();
  }

  std::int64_t integer(std::string_view key, std::int64_t lowest, std::int64_t highest) const {
    const toml::node& node = require(key);
    if (!node.is_integer()) fail(name(key), node.source(), "must be an integer");
    const std::int64_t v = *node.value<std::int64_t>();
    if (v < lowest || v > highest) {
      fail(name(key), node.source(),
           "must be in " + std::to_string(lowest) + ".." + std::to_string(highest) + ", is " +
               std::to_string(v));
    }
    return v;
  }
  std::int64_t integer(std::string_view key, std::int64_t lowest, std::int64_t highest,
                       std::int64_t fallback) const {
    return find(key) == nullptr ? fallback : integer(key, lowest, highest);
  }

  double number(const toml::node& node, const std::string& key) const {
    if (!node.is_number()) fail(key, node.source(), "must be a number");
    const double v = *node.value<double>();
    if (!std::isfinite(v)) fail(key, node.source(), "must be finite");
    return v;
  }

  /// A number in [lowest, highest] (an end is excluded when its flag says so).
  double number(std::string_view key, double lowest, bool lowest_excluded, double highest,
                bool highest_excluded) const {
    const toml::node& node = require(key);
    const double v = number(node, name(key));
    const bool low = v < lowest || (lowest_excluded && v == lowest);
    const bool high = v > highest || (highest_excluded && v == highest);
    if (low || high) {
      std::string range;
      if (std::isinf(highest)) {
        range = std::string(lowest_excluded ? "> " : ">= ") + number_text(lowest);
      } else {
        range = std::string("in ") + (lowest_excluded ? "(" : "[") + number_text(lowest) + ", " +
                number_text(highest) + (highest_excluded ? ")" : "]");
      }
      fail(name(key), node.source(), "must be " + range + ", is " + number_text(v));
    }
    return v;
  }
  double number(std::string_view key, double lowest, bool lowest_excluded, double highest,
                bool highest_excluded, double fallback) const {
    return find(key) == nullptr ? fallback
                                : number(key, lowest, lowest_excluded, highest, highest_excluded);
  }
  double positive(std::string_view key, double fallback) const {
    return number(key, 0.0, true, HUGE_VAL, false, fallback);
  }

  std::vector<double> numbers(std::string_view key, std::size_t count) const {
    const toml::node& node = require(key);
    const toml::array* array = node.as_array();
    if (array == nullptr || array->size() != count) {
      fail(name(key), node.source(), "must be a list of " + std::to_string(count) + " numbers");
    }
    std::vector<double> out;
    for (std::size_t i = 0; i < array->size(); ++i) {
      out.push_back(number(*array->get(i), name(key) + "[" + std::to_string(i) + "]"));
    }
    return out;
  }
  Eigen::Vector3d vector3(std::string_view key, const Eigen::Vector3d& fallback) const {
    if (find(key) == nullptr) return fallback;
    const std::vector<double> v = numbers(key, 3);
    return {v[0], v[1], v[2]};
  }

  /// A path; relative ones are taken from the configuration file's folder.
  fs::path path(std::string_view key) const {
    const std::string text = string(key);
    if (text.empty()) fail(name(key), require(key).source(), "must not be empty");
    const fs::path p(text);
    return p.is_absolute() ? p : file_.parent_path() / p;
  }

  const toml::source_region& where() const { return where_; }

 private:
  const fs::path& file_;
  const toml::table* table_;
  std::string prefix_;
  toml::source_region where_;
  std::vector<std::string_view> known_;
};

void check_ipv4(const Table& t, std::string_view key, const std::string& value) {
  in_addr address{};
  if (::inet_pton(AF_INET, value.c_str(), &address) != 1) {
    t.fail(t.name(key), t.require(key).source(),
           "must be an IPv4 address in dotted-quad form (e.g. \"192.168.1.10\"), is \"" + value +
               "\"");
  }
}

}  // namespace

ConfigError::ConfigError(fs::path file, std::string key, int line, int column,
                         const std::string& why)
    : std::runtime_error(location(file, line, column) + ": " + (key.empty() ? "" : key + ": ") +
                         why),
      file_(std::move(file)),
      key_(std::move(key)),
      line_(line),
      column_(column) {}

RtConfig parse_config(const std::string& text, const fs::path& path) {
  toml::table root;
  try {
    root = toml::parse(text, path.string());
  } catch (const toml::parse_error& e) {
    throw ConfigError(path, "", static_cast<int>(e.source().begin.line),
                      static_cast<int>(e.source().begin.column),
                      "TOML syntax: " + std::string(e.description()));
  }
  RtConfig c;
  c.file = path;
  toml::source_region top;
  top.begin = {1, 1};
  const Table file(path, &root, "", top,
                   {"model", "rig", "robot", "ft", "imu", "body", "limits", "watchdog", "filter",
                    "realtime", "collection", "record"});

  const Table model = file.table("model", {"file", "temperature_C"});
  c.model_file = model.path("file");
  c.temperature_C = model.number("temperature_C", -50.0, false, 150.0, false, 25.0);

  const Table rig = file.table("rig", {"file"});
  c.rig_file = rig.path("file");

  const Table robot = file.table("robot", {"bind_address", "bind_port", "address", "port",
                                           "sensor_type", "cycle_ms", "receive_timeout_ms"});
  c.robot.bind_address = robot.string("bind_address", c.robot.bind_address);
  if (robot.find("bind_address") != nullptr)
    check_ipv4(robot, "bind_address", c.robot.bind_address);
  c.robot.bind_port = static_cast<std::uint16_t>(robot.integer("bind_port", 0, 65535, 49152));
  c.robot.address = robot.string("address", c.robot.address);
  if (robot.find("address") != nullptr) check_ipv4(robot, "address", c.robot.address);
  c.robot.port = static_cast<std::uint16_t>(robot.integer("port", 0, 65535, 0));
  c.robot.sensor_type = robot.string("sensor_type", c.robot.sensor_type);
  {
    const std::string& type = c.robot.sensor_type;
    const bool ok =
        !type.empty() && type.size() <= 32 && std::all_of(type.begin(), type.end(), [](char ch) {
          return std::isalnum(static_cast<unsigned char>(ch)) != 0 || ch == '_' || ch == '.' ||
                 ch == '-';
        });
    if (!ok) {
      robot.fail(robot.name("sensor_type"), robot.require("sensor_type").source(),
                 "must be 1..32 characters of [A-Za-z0-9_.-] (the Type of the robot's RSI "
                 "sensor object), is \"" +
                     type + "\"");
    }
  }
  {
    const std::int64_t ms = robot.integer("cycle_ms", 1, 1000);
    if (ms != 4 && ms != 12) {
      robot.fail(robot.name("cycle_ms"), robot.require("cycle_ms").source(),
                 "must be 4 or 12 (the RSI interpolation cycles), is " + std::to_string(ms));
    }
    c.robot.cycle_ms = static_cast<int>(ms);
  }
  c.robot.receive_timeout_ms =
      robot.number("receive_timeout_ms", 0.0, true, 1000.0, false, 1.5 * c.robot.cycle_ms);

  const Table ft =
      file.table("ft", {"interface", "base_id", "calibration", "rate_hz", "sample_timeout_ms"});
  c.ft.interface = ft.string("interface");
  if (c.ft.interface.empty() || c.ft.interface.size() > 15) {
    ft.fail(ft.name("interface"), ft.require("interface").source(),
            "must be a network interface name of 1..15 characters (e.g. \"can0\")");
  }
  c.ft.base_id = static_cast<int>(ft.integer("base_id", 0, 127, 0x20));
  c.ft.calibration = static_cast<int>(ft.integer("calibration", 0, 15, 0));
  c.ft.rate_hz = ft.number("rate_hz", 0.0, true, 2000.0, false, 500.0);
  c.ft.sample_timeout_ms = ft.number("sample_timeout_ms", 0.0, true, 1000.0 / c.ft.rate_hz, false,
                                     std::min(2.0, 1000.0 / c.ft.rate_hz));

  const Table imu = file.table("imu", {"device", "baud", "identifier", "accel_range_g"});
  c.imu.device = imu.string("device");
  if (c.imu.device.empty()) {
    imu.fail(imu.name("device"), imu.require("device").source(), "must name a tty");
  }
  c.imu.baud = static_cast<std::uint32_t>(imu.integer("baud", 1200, 4000000, 921600));
  if (rtio::baud_to_speed(c.imu.baud) == 0) {
    imu.fail(
        imu.name("baud"), imu.require("baud").source(),
        "must be a standard serial rate (e.g. 460800, 921600), is " + std::to_string(c.imu.baud));
  }
  c.imu.identifier = static_cast<int>(imu.integer("identifier", 0, 255, 0x93));
  c.imu.accel_range_g = static_cast<int>(imu.integer("accel_range_g", 5, 80, 10));
  if (c.imu.accel_range_g != 5 && c.imu.accel_range_g != 10 && c.imu.accel_range_g != 30 &&
      c.imu.accel_range_g != 80) {
    imu.fail(imu.name("accel_range_g"), imu.require("accel_range_g").source(),
             "must be 5, 10, 30 or 80 (the STIM300's accelerometer range), is " +
                 std::to_string(c.imu.accel_range_g));
  }

  const Table body = file.table("body", {"mass_kg", "inertia_kgm2", "com_sensor_m"});
  c.body.mass_kg = body.number("mass_kg", 0.0, true, 10000.0, false);
  {
    const toml::node& node = body.require("inertia_kgm2");
    const toml::array* rows = node.as_array();
    if (rows == nullptr || rows->size() != 3) {
      body.fail(body.name("inertia_kgm2"), node.source(),
                "must be a 3×3 array of numbers (kg·m², about the centre of mass, body axes = "
                "sensor axes), e.g. [[4, 0, 0], [0, 5, 0], [0, 0, 6]]");
    }
    Eigen::Matrix3d I;
    for (int r = 0; r < 3; ++r) {
      const toml::array* row = rows->get(static_cast<std::size_t>(r))->as_array();
      const std::string row_key = body.name("inertia_kgm2") + "[" + std::to_string(r) + "]";
      if (row == nullptr || row->size() != 3) {
        body.fail(row_key, rows->get(static_cast<std::size_t>(r))->source(),
                  "must be a row of 3 numbers");
      }
      for (int k = 0; k < 3; ++k) {
        I(r, k) = body.number(*row->get(static_cast<std::size_t>(k)),
                              row_key + "[" + std::to_string(k) + "]");
      }
    }
    if ((I - I.transpose()).norm() > 1e-9 * I.norm()) {
      body.fail(body.name("inertia_kgm2"), node.source(), "must be symmetric");
    }
    const double smallest = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(I).eigenvalues()[0];
    if (!(smallest > 0.0)) {
      body.fail(
          body.name("inertia_kgm2"), node.source(),
          "must be positive definite (smallest eigenvalue " + number_text(smallest) + " kg·m²)");
    }
    c.body.inertia_body_kgm2 = I;
  }
  c.com_sensor_m = body.vector3("com_sensor_m", Eigen::Vector3d::Zero());

  const Table limits = file.table(
      "limits", {"force_deadband_N", "torque_deadband_Nm", "contact_confirm_cycles",
                 "contact_release_fraction", "max_contact_force_N", "max_contact_torque_Nm",
                 "max_speed_mps", "max_angular_speed_radps", "max_accel_mps2",
                 "max_angular_accel_radps2", "workspace_min_m", "workspace_max_m"});
  control::MotionLimits& l = c.limits;
  l.force_deadband_N =
      limits.number("force_deadband_N", 0.0, false, HUGE_VAL, false, l.force_deadband_N);
  l.torque_deadband_Nm =
      limits.number("torque_deadband_Nm", 0.0, false, HUGE_VAL, false, l.torque_deadband_Nm);
  l.contact_confirm_cycles =
      static_cast<int>(limits.integer("contact_confirm_cycles", 1, 100, l.contact_confirm_cycles));
  l.contact_release_fraction =
      limits.number("contact_release_fraction", 0.0, false, 1.0, false, l.contact_release_fraction);
  l.max_contact_force_N = limits.positive("max_contact_force_N", l.max_contact_force_N);
  l.max_contact_torque_Nm = limits.positive("max_contact_torque_Nm", l.max_contact_torque_Nm);
  l.max_speed_mps = limits.positive("max_speed_mps", l.max_speed_mps);
  l.max_angular_speed_radps = limits.positive("max_angular_speed_radps", l.max_angular_speed_radps);
  l.max_accel_mps2 = limits.positive("max_accel_mps2", l.max_accel_mps2);
  l.max_angular_accel_radps2 =
      limits.positive("max_angular_accel_radps2", l.max_angular_accel_radps2);
  l.workspace_min_m = limits.vector3("workspace_min_m", l.workspace_min_m);
  l.workspace_max_m = limits.vector3("workspace_max_m", l.workspace_max_m);
  if (l.force_deadband_N >= l.max_contact_force_N) {
    limits.fail(limits.name("force_deadband_N"),
                limits.find("force_deadband_N") != nullptr
                    ? limits.find("force_deadband_N")->source()
                    : limits.where(),
                "must be below max_contact_force_N (" + number_text(l.max_contact_force_N) + " N)");
  }
  if (l.torque_deadband_Nm >= l.max_contact_torque_Nm) {
    limits.fail(
        limits.name("torque_deadband_Nm"),
        limits.find("torque_deadband_Nm") != nullptr ? limits.find("torque_deadband_Nm")->source()
                                                     : limits.where(),
        "must be below max_contact_torque_Nm (" + number_text(l.max_contact_torque_Nm) + " N·m)");
  }
  for (int k = 0; k < 3; ++k) {
    if (!(l.workspace_min_m[k] < l.workspace_max_m[k])) {
      const char* key =
          limits.find("workspace_max_m") != nullptr ? "workspace_max_m" : "workspace_min_m";
      limits.fail(limits.name(key),
                  limits.find(key) != nullptr ? limits.find(key)->source() : limits.where(),
                  std::string("workspace_min_m must be below workspace_max_m on every axis (") +
                      "xyz"[k] + ": " + number_text(l.workspace_min_m[k]) + " m, " +
                      number_text(l.workspace_max_m[k]) + " m)");
    }
  }

  const Table watchdog =
      file.table("watchdog", {"ft_fault_cycles", "imu_fault_cycles", "robot_fault_cycles",
                              "robot_late_cycles", "model_fault_cycles"});
  loop::WatchdogConfig& w = c.watchdog;
  w.ft_fault_cycles =
      static_cast<int>(watchdog.integer("ft_fault_cycles", 1, 1000, w.ft_fault_cycles));
  w.imu_fault_cycles =
      static_cast<int>(watchdog.integer("imu_fault_cycles", 1, 1000, w.imu_fault_cycles));
  w.robot_fault_cycles =
      static_cast<int>(watchdog.integer("robot_fault_cycles", 1, 1000, w.robot_fault_cycles));
  w.robot_late_cycles =
      static_cast<int>(watchdog.integer("robot_late_cycles", 1, 1000, w.robot_late_cycles));
  w.model_fault_cycles =
      static_cast<int>(watchdog.integer("model_fault_cycles", 1, 1000, w.model_fault_cycles));

  const Table filter = file.table("filter", {"angular_accel_order"});
  c.angular_accel_order = static_cast<int>(filter.integer("angular_accel_order", 2, 4, 4));
  if (c.angular_accel_order == 3) {
    filter.fail(filter.name("angular_accel_order"), filter.require("angular_accel_order").source(),
                "must be 4 (5-point difference, 2 rows late) or 2 (3-point, 1 row late), is 3");
  }

  const Table realtime = file.table("realtime", {"lock_memory", "priority", "cpu"});
  c.realtime.lock_memory = realtime.boolean("lock_memory", true);
  c.realtime.priority = static_cast<int>(realtime.integer("priority", 0, 99, 80));
  c.realtime.cpu = static_cast<int>(realtime.integer("cpu", -1, 1023, -1));

  const Table collection =
      file.table("collection", {"speed_fraction", "dwell_s", "max_axis_step_rad",
                                "approach_speed_radps", "approach_accel_radps2"});
  CollectionSection& col = c.collection;
  col.speed_fraction = collection.number("speed_fraction", 0.0, true, 1.0, false, 0.3);
  col.dwell_s = collection.number("dwell_s", 0.0, false, 3600.0, false, 2.0);
  col.max_axis_step_rad = collection.number("max_axis_step_rad", 0.0, true, 0.1, false, 0.01);
  col.approach_speed_radps = collection.number("approach_speed_radps", 0.0, true, 2.0, false, 0.2);
  col.approach_accel_radps2 =
      collection.number("approach_accel_radps2", 0.0, true, 10.0, false, 0.5);

  const Table record = file.table("record", {"dir"});
  if (record.find("dir") != nullptr) c.record_dir = record.path("dir");
  return c;
}

RtConfig read_config(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw ConfigError(path, "", 0, 0,
                      "cannot open the configuration file for reading (" +
                          std::string(std::error_code(errno, std::generic_category()).message()) +
                          ")");
  }
  std::ostringstream text;
  text << in.rdbuf();
  return parse_config(text.str(), path);
}

loop::CycleConfig cycle_config(const RtConfig& c) {
  loop::CycleConfig out;
  out.period_s = c.robot.cycle_s();
  out.ipoc_unit_s = 0.001;
  out.angular_accel_order = c.angular_accel_order;
  out.temperature_C = c.temperature_C;
  out.watchdog = c.watchdog;
  out.body = c.body;
  out.limits = c.limits;
  out.p_sensor_com_m = c.com_sensor_m;
  out.max_axis_step_rad = c.collection.max_axis_step_rad;
  out.approach_speed_radps = c.collection.approach_speed_radps;
  out.approach_accel_radps2 = c.collection.approach_accel_radps2;
  return out;
}

}  // namespace zerog::rt
