// The scenario file of zerog-emu (proto/emulator.md): a full file read back, the defaults, and
// every kind of mistake reported with file, line, column, key and reason.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <numbers>
#include <string>

#include "zerog/emu/robot.hpp"
#include "zerog/emu/scenario.hpp"
#include "zerog/formats/log.hpp"

namespace zerog::emu {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
const std::filesystem::path kFile = "scenario.toml";

const char* const kFull = R"(# a full scenario
[robot]
cycle_ms = 4
servo_bandwidth_hz = 6.5
physics_rate_hz = 4000
start_joints_deg = [10, -80, 95, 5, 40, -20]

[payload]
seed = 42
effects = ["cable", "-rotational_inertia"]
set = { "gravity.mass" = 80.0, noise = { force = 0.5 } }

[ft]
counts_per_force = 40000
counts_per_torque = 1500000
base_id = 0x21

[[push]]
start_s = 2.0
duration_s = 0.25
force_world_N = [0, 40, 0]

[[push]]
start_s = 5.0
duration_s = 1.0
force_world_N = [10, 0, -5]
torque_world_Nm = [0, 0, 2.5]
point_sensor_m = [0.3, 0, 0.25]
profile = "constant"

[[fault]]
kind = "robot_drop"
start_s = 1.0
cycles = 5

[[fault]]
kind = "robot_late"
start_s = 1.5
cycles = 2
delay_ms = 3.0

[[fault]]
kind = "ft_slow"
start_s = 3.0
duration_s = 0.5
response_delay_ms = 2

[[fault]]
kind = "imu_unplug"
start_s = 4.0
)";

// The error message of parsing `text`, or "" if it parsed.
std::string error_of(const std::string& text) {
  try {
    parse_scenario(text, kFile);
  } catch (const formats::InputError& e) {
    return e.what();
  }
  return "";
}

void expect_error(const std::string& text, const std::string& where, const std::string& why) {
  const std::string e = error_of(text);
  EXPECT_NE(e.find("scenario.toml:" + where + ": "), std::string::npos) << e << "\n--\n" << text;
  EXPECT_NE(e.find(why), std::string::npos) << e << "\n--\n" << text;
}

TEST(Scenario, FullFile) {
  const Scenario s = parse_scenario(kFull, kFile);
  EXPECT_EQ(s.robot.cycle_ms, 4);
  EXPECT_DOUBLE_EQ(s.cycle_s(), 0.004);
  EXPECT_DOUBLE_EQ(s.robot.servo_bandwidth_hz, 6.5);
  EXPECT_DOUBLE_EQ(s.robot.physics_rate_hz, 4000.0);
  EXPECT_NEAR(s.robot.start_joints_rad[0], 10 * kDeg, 1e-15);
  EXPECT_NEAR(s.robot.start_joints_rad[5], -20 * kDeg, 1e-15);
  EXPECT_EQ(s.sim.seed, 42u);
  EXPECT_TRUE(s.sim.effects.has(model::Effect::cable));
  EXPECT_FALSE(s.sim.effects.has(model::Effect::rotational_inertia));
  EXPECT_DOUBLE_EQ(s.sim.payload.mass_kg, 80.0);
  EXPECT_DOUBLE_EQ(s.sim.noise.force_N, 0.5);
  // The rest is the seed's default configuration.
  const sim::SimConfig d = sim::default_sim_config(42);
  EXPECT_EQ(s.sim.params.block(model::Effect::bias)[0], d.params.block(model::Effect::bias)[0]);
  EXPECT_EQ(s.ft.counts_per_force, 40000u);
  EXPECT_EQ(s.ft.counts_per_torque, 1500000u);
  EXPECT_EQ(s.ft.base_id, 0x21);

  ASSERT_EQ(s.pushes.size(), 2u);
  EXPECT_EQ(s.pushes[0].profile, PushProfile::half_sine);
  EXPECT_FALSE(s.pushes[0].point_sensor_m.has_value());
  EXPECT_EQ(s.pushes[0].force_world_N, Eigen::Vector3d(0, 40, 0));
  EXPECT_EQ(s.pushes[0].torque_world_Nm, Eigen::Vector3d::Zero());
  EXPECT_EQ(s.pushes[1].profile, PushProfile::constant);
  EXPECT_EQ(*s.pushes[1].point_sensor_m, Eigen::Vector3d(0.3, 0, 0.25));
  EXPECT_EQ(s.pushes[1].torque_world_Nm, Eigen::Vector3d(0, 0, 2.5));

  ASSERT_EQ(s.faults.size(), 4u);
  EXPECT_EQ(s.faults[0].kind, FaultKind::robot_drop);
  EXPECT_EQ(s.faults[0].cycles, 5);
  EXPECT_EQ(robot_fault_cycles(s.faults[0], s.cycle_s()),
            std::make_pair(std::int64_t{250}, std::int64_t{254}));
  EXPECT_DOUBLE_EQ(s.faults[1].delay_ms, 3.0);
  EXPECT_EQ(s.faults[2].kind, FaultKind::ft_slow);
  EXPECT_DOUBLE_EQ(s.faults[2].response_delay_ms, 2.0);
  EXPECT_DOUBLE_EQ(s.faults[2].duration_s, 0.5);
  EXPECT_EQ(s.faults[3].kind, FaultKind::imu_unplug);
  EXPECT_DOUBLE_EQ(s.faults[3].duration_s, 0.0);  // stays unplugged
}

TEST(Scenario, EmptyFileGivesTheDefaults) {
  const Scenario s = parse_scenario("", kFile);
  EXPECT_EQ(s.robot.cycle_ms, 12);
  EXPECT_DOUBLE_EQ(s.robot.servo_bandwidth_hz, 8.0);
  EXPECT_DOUBLE_EQ(s.robot.physics_rate_hz, 2000.0);
  EXPECT_EQ(s.robot.start_joints_rad, default_start_joints());
  EXPECT_EQ(s.sim.seed, 1u);
  EXPECT_EQ(s.sim.effects, sim::kDefaultSimEffects);
  EXPECT_TRUE(s.pushes.empty());
  EXPECT_TRUE(s.faults.empty());
}

TEST(Scenario, ReadsAFile) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "zerog_emu_scenario";
  std::filesystem::create_directories(dir);
  const std::filesystem::path file = dir / "s.toml";
  std::ofstream(file) << "[robot]\ncycle_ms = 4\n";
  EXPECT_EQ(read_scenario(file).robot.cycle_ms, 4);
  EXPECT_EQ(read_scenario(file).source, file);
  std::ofstream(file) << "[robot]\ncycle_ms = 5\n";
  try {
    read_scenario(file);
    FAIL();
  } catch (const formats::InputError& e) {
    EXPECT_EQ(e.file(), file);
    EXPECT_EQ(e.line(), 2);
  }
  std::filesystem::remove_all(dir);
  EXPECT_THROW(read_scenario(file), std::exception);
}

TEST(Scenario, MistakesNameTheKeyAndWhere) {
  expect_error("[robot]\ncycle_ms = 8\n", "2:12", "'robot.cycle_ms' must be 4 or 12");
  expect_error("[robot]\ncycle_ms = \"12\"\n", "2:12", "'robot.cycle_ms' must be an integer");
  expect_error("[robot]\ncycle = 12\n", "2:1", "unknown key 'robot.cycle'");
  expect_error("[robots]\n", "1:2", "unknown key 'robots'");
  expect_error("[robot]\nservo_bandwidth_hz = 0\n", "2:22",
               "'robot.servo_bandwidth_hz' must be in (0, 200]");
  expect_error("[robot]\nphysics_rate_hz = 100\n", "2:19",
               "'robot.physics_rate_hz' must be in [500, 20000]");
  expect_error("[robot]\nstart_joints_deg = [0, -90, 90, 0, 130, 0]\n", "2:36",
               "A5 = 130 deg is outside its range [-125, 125] deg");
  expect_error("[robot]\nstart_joints_deg = [0, -90, 90]\n", "2:20",
               "'robot.start_joints_deg' must be a list of 6 numbers");
  expect_error("[payload]\nseed = -1\n", "2:8", "'payload.seed' must be an integer in [0,");
  expect_error("[payload]\neffects = [\"cable\", \"wind\"]\n", "2:21",
               "unknown simulator effect 'wind'");
  expect_error("[payload]\neffects = \"cable\"\n", "2:11", "'payload.effects' must be a list");
  expect_error("[payload]\nset = { \"gravity.mas\" = 1 }\n", "2:9",
               "'payload.set.gravity.mas': unknown --set key");
  expect_error("[payload]\nset = { \"gravity.mass\" = \"1\" }\n", "2:26",
               "'payload.set.gravity.mass' must be a number");
  expect_error("[ft]\ncounts_per_force = 0\n", "2:20",
               "'ft.counts_per_force' must be an integer in [1,");
  expect_error("[[push]]\nstart_s = 1\nduration_s = 0.2\n", "1:1",
               "missing required key 'push[1].force_world_N'");
  expect_error("[[push]]\nstart_s = 1\nduration_s = 0\nforce_world_N = [1, 2, 3]\n", "3:14",
               "'push[1].duration_s' must be in (0, 60]");
  expect_error("[[push]]\nstart_s = 1\nduration_s = 1\nforce_world_N = [1, 2]\n", "4:17",
               "'push[1].force_world_N' must be a list of 3 numbers");
  expect_error("[[push]]\nstart_s = 1\nduration_s = 1\nforce_world_N = [9000, 0, 0]\n", "4:17",
               "'push[1].force_world_N' has magnitude 9000 N");
  expect_error(
      "[[push]]\nstart_s = 1\nduration_s = 1\nforce_world_N = [1, 0, 0]\nprofile = \"ramp\"\n",
      "5:11", "'push[1].profile' must be \"half_sine\" or \"constant\"");
  expect_error("push = 3\n", "1:8", "'push' must be an array of tables");
  expect_error("[[fault]]\nkind = \"robot_explode\"\nstart_s = 1\n", "2:8",
               "not a fault kind (robot_drop, robot_late");
  expect_error("[[fault]]\nkind = \"ft_silent\"\nstart_s = 1\ncycles = 3\n", "4:10",
               "'fault[1].cycles' does not apply to kind 'ft_silent'");
  expect_error("[[fault]]\nkind = \"robot_drop\"\nstart_s = 1\n", "1:1",
               "missing required key 'fault[1].cycles'");
  expect_error("[[fault]]\nkind = \"robot_drop\"\nstart_s = 1\ncycles = 2\nduration_s = 1\n",
               "5:14", "'fault[1].duration_s' does not apply to kind 'robot_drop'");
  expect_error("[[fault]]\nkind = \"robot_late\"\nstart_s = 1\ncycles = 2\n", "1:1",
               "missing required key 'fault[1].delay_ms'");
  expect_error("[[fault]]\nkind = \"robot_drop\"\nstart_s = 1\ncycles = 2\ndelay_ms = 3\n", "5:12",
               "'fault[1].delay_ms' does not apply");
  expect_error("[[fault]]\nkind = \"ft_slow\"\nstart_s = 1\nduration_s = 1\n", "1:1",
               "missing required key 'fault[1].response_delay_ms'");
  expect_error(
      "[[fault]]\nkind = \"imu_crc\"\nstart_s = 1\nduration_s = 2\n"
      "[[fault]]\nkind = \"imu_gaps\"\nstart_s = 2.5\nduration_s = 1\n",
      "7:11", "'fault[2]' (imu_gaps) overlaps 'fault[1]' (imu_crc)");
  expect_error(
      "[[fault]]\nkind = \"robot_drop\"\nstart_s = 0.012\ncycles = 3\n"
      "[[fault]]\nkind = \"robot_duplicate\"\nstart_s = 0.036\ncycles = 1\n",
      "7:11", "faults of the same robot must not overlap");
  expect_error("[robot\n", "1:7", "TOML syntax");
  // Different devices may overlap; a robot fault right after another may follow.
  EXPECT_EQ(error_of("[[fault]]\nkind = \"imu_crc\"\nstart_s = 1\nduration_s = 2\n"
                     "[[fault]]\nkind = \"ft_silent\"\nstart_s = 1.5\nduration_s = 1\n"
                     "[[fault]]\nkind = \"robot_drop\"\nstart_s = 0.012\ncycles = 3\n"
                     "[[fault]]\nkind = \"robot_duplicate\"\nstart_s = 0.048\ncycles = 1\n"),
            "");
}

TEST(Scenario, FaultKindsAreListed) {
  int robot = 0;
  for (const FaultKindInfo& i : fault_kind_infos()) {
    EXPECT_EQ(&info(i.kind), &i);
    robot += i.robot;
    EXPECT_GT(std::string(i.description).size(), 10u);
  }
  EXPECT_EQ(robot, 6);
}

}  // namespace
}  // namespace zerog::emu
