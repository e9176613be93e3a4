// The F/T-only floor (issue 28, item 4; host/ident/include/zerog/ident/ft_floor.hpp): the white
// noise of a logged wrench row from the log itself, without a truth model.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "zerog/ident/ft_floor.hpp"

namespace zerog::ident {
namespace {

using ::testing::HasSubstr;

// Rows at 12 ms: dwells of 2 s at rest (a slow drift and a 0.1 Hz wave on the load) between
// 1-s moves (the sensor turns), white noise σ_F on the force and σ_M on the torque axes, and a
// few steps (a touch) in the dwells.
formats::Log dwell_log(double sigma_force, double sigma_torque, std::uint64_t seed,
                       int dwells = 60) {
  formats::Log log;
  log.rig.sample_period_s = 0.012;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  double angle = 0.0;
  std::size_t row = 0;
  for (int d = 0; d < dwells; ++d) {
    for (int phase = 0; phase < 2; ++phase) {
      const int rows = phase == 0 ? 167 : 83;
      for (int r = 0; r < rows; ++r, ++row) {
        formats::Sample s;
        s.t_s = 0.012 * static_cast<double>(row);
        if (phase == 1) angle += 0.01;  // moving: the sensor turns
        s.q_base_sensor = Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()));
        const double slow = 3.0 + 0.002 * s.t_s + 0.5 * std::sin(2.0 * M_PI * 0.1 * s.t_s);
        for (int k = 0; k < 3; ++k) {
          s.force_sensor_N[k] = 100.0 * std::cos(angle + k) + slow + sigma_force * n01(rng);
          s.torque_sensor_Nm[k] = 10.0 * std::sin(angle + k) + 0.1 * slow + sigma_torque * n01(rng);
        }
        if (phase == 0 && r == 80 && d % 10 == 0) s.force_sensor_N[0] += 20.0;  // a touch
        log.samples.push_back(s);
      }
    }
  }
  return log;
}

TEST(FtFloor, IsTheWhiteNoiseOfARowOnThreeSeeds) {
  for (const std::uint64_t seed : {1u, 2u, 3u}) {
    const Dataset data = make_dataset(dwell_log(0.25, 0.03, seed));
    const FtFloor f = ft_floor(data);
    ASSERT_TRUE(f.known) << f.note;
    EXPECT_GT(f.differences, 8000u);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(f.sigma[k], 0.25, 0.25 * 0.05) << "seed " << seed;
    for (int k = 3; k < 6; ++k) EXPECT_NEAR(f.sigma[k], 0.03, 0.03 * 0.05) << "seed " << seed;
    EXPECT_NEAR(f.force_rms, 0.25, 0.25 * 0.05);
    EXPECT_NEAR(f.torque_rms, 0.03, 0.03 * 0.05);
    // The moving rows are left out: their load changes by far more than the noise.
    std::size_t moving = 0;
    for (std::uint8_t m : data.moving) moving += m;
    EXPECT_GT(moving, 3000u);
  }
  // Twice the noise reads twice.
  const FtFloor twice = ft_floor(make_dataset(dwell_log(0.5, 0.06, 4)));
  EXPECT_NEAR(twice.force_rms, 0.5, 0.5 * 0.05);
  // The ratio of an error to it, at rest and moving, in text and JSON.
  const ErrorVsFloor e{twice.force_rms, twice.torque_rms, 2.0 * twice.force_rms,
                       2.0 * twice.torque_rms};
  const std::string text = format_ft_floor(twice, &e);
  EXPECT_THAT(text, HasSubstr("F/T-only floor"));
  EXPECT_THAT(text, HasSubstr("at rest 1.00x (force) / 1.00x (torque), moving 2.00x / 2.00x"))
      << text;
  const nlohmann::json j = to_json(twice, &e);
  EXPECT_NEAR(j["ratio"]["force_moving"].get<double>(), 2.0, 0.1);
}

TEST(FtFloor, SaysWhyItIsNotKnown) {
  // No rest: every row moves.
  formats::Log moving = dwell_log(0.25, 0.03, 1, 1);
  moving.samples.erase(moving.samples.begin(), moving.samples.begin() + 167);
  const FtFloor none = ft_floor(make_dataset(moving));
  EXPECT_FALSE(none.known);
  EXPECT_THAT(none.note, HasSubstr("record a few seconds with the robot still"));
  EXPECT_THAT(format_ft_floor(none, nullptr), HasSubstr("F/T-only floor: not known"));
  // A static table: rows are poses, not a time series.
  formats::Log table = dwell_log(0.25, 0.03, 1, 1);
  table.columns.static_rows = true;
  for (std::size_t i = 0; i < table.samples.size(); ++i)
    table.samples[i].t_s = static_cast<double>(i);
  const FtFloor t = ft_floor(make_dataset(table));
  EXPECT_FALSE(t.known);
  EXPECT_THAT(t.note, HasSubstr("static table"));
}

}  // namespace
}  // namespace zerog::ident
