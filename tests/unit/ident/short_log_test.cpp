// Short recordings: diagnose chooses held-out blocks that fit the log (at least 8, not below
// 0.5 s), says so in its text and JSON, and refuses only below a real minimum, naming what works.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "zerog/ident/dataset.hpp"
#include "zerog/ident/diagnose.hpp"
#include "zerog/model/effects.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::ident {
namespace {

using ::testing::HasSubstr;

// The first `seconds` of the default simulated run (12 ms rows), `effects` hidden in the truth.
Dataset simulated(double seconds, const char* effects) {
  sim::SimConfig c = sim::default_sim_config(11);
  c.effects = sim::parse_sim_effects(effects);
  c.duration_limit_s = seconds;
  return make_dataset(
      sim::RigSimulator(c, sim::make_design(sim::DesignOptions{}).points_rad).run().log);
}

// Only the times matter to the choice of blocks.
Dataset times_only(double seconds, double period_s) {
  Dataset d;
  for (double t = 0.0; t <= seconds + 1e-9; t += period_s) d.t_s.push_back(t);
  return d;
}

TEST(ShortLog, DiagnoseChoosesEightBlocksForASixSecondLog) {
  const Dataset data = simulated(6.0, "cable");
  const double duration = data.t_s.back() - data.t_s.front();
  ASSERT_GT(duration, 5.9);
  ASSERT_LT(duration, 6.01);
  DiagnoseOptions o;
  o.fit.effects = model::kDefaultModel;
  o.discover = false;
  const Diagnosis d = diagnose(data, o);
  EXPECT_TRUE(d.split.automatic);
  EXPECT_EQ(d.split.blocks, kMinBlocks);
  EXPECT_NEAR(d.split.block_s, duration / kMinBlocks, 1e-6);
  EXPECT_GE(d.split.heldout_samples, kMinSplitSamples);
  EXPECT_GE(d.split.training_samples, kMinSplitSamples);
  // Every 4th of 8 blocks held out: a quarter of the rows, give or take a block's rounding.
  EXPECT_NEAR(static_cast<double>(d.split.heldout_samples) / static_cast<double>(data.size()), 0.25,
              0.02);
  EXPECT_THAT(d.split.text, HasSubstr("chosen for this short log"));
  EXPECT_THAT(format_diagnosis(d),
              HasSubstr("held-out split: blocks of 0.75 s (8 blocks in 6.0 s"));
  const nlohmann::json j = to_json(d);
  EXPECT_EQ(j["split"]["blocks"], kMinBlocks);
  EXPECT_EQ(j["split"]["chosen"], "auto");
  EXPECT_NEAR(j["split"]["block_s"].get<double>(), duration / kMinBlocks, 1e-6);
  EXPECT_FALSE(d.candidates.empty());
}

TEST(ShortLog, AGivenBlockTooLongIsRefusedWithOneThatWorks) {
  const Dataset data = times_only(6.0, 0.012);
  try {
    choose_blocks(data, 60.0);
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("501 samples over 6.0 s"));
    EXPECT_THAT(e.what(), HasSubstr("0 held-out"));
    EXPECT_THAT(e.what(), HasSubstr("use --block "));
  }
  const BlockChoice given = choose_blocks(data, 0.75);
  EXPECT_FALSE(given.automatic);
  EXPECT_EQ(given.block_s, 0.75);
  EXPECT_THAT(given.text, HasSubstr("given with --block"));
}

TEST(ShortLog, BelowTheMinimumItSaysWhatWouldWork) {
  try {
    choose_blocks(times_only(3.0, 0.012), 0.0);
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("at least 8 blocks of at least 0.5 s, i.e. 4 s"));
    EXPECT_THAT(e.what(), HasSubstr("record longer"));
  }
  // Long enough in time, but too few rows at 0.2 s per row: 4 held-out of 21.
  try {
    choose_blocks(times_only(4.0, 0.2), 0.0);
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("at least 100 each"));
  }
}

// A static table (calib/static_table: 15 poses, rows without time) is below the minimum of 100
// held-out and 100 training rows: the message says what works for a table — more poses, or
// `zerog fit` without a held-out split — not "record longer" or --block.
TEST(ShortLog, AStaticTableBelowTheMinimumIsToldToAddPosesOrFit) {
  auto table = [](int rows) {
    Dataset d = times_only(rows - 1.0, 1.0);  // static rows count 0, 1, … (proto/log_format.md)
    d.columns.static_rows = true;
    return d;
  };
  try {
    choose_blocks(table(15), 0.0);
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_THAT(what, HasSubstr("static table of 15 rows (no time)"));
    EXPECT_THAT(what, HasSubstr("every 4th row"));
    EXPECT_THAT(what, HasSubstr("(here 3 and 12)"));
    EXPECT_THAT(what, HasSubstr("about 400 poses"));
    EXPECT_THAT(what, HasSubstr("record more poses"));
    EXPECT_THAT(what, HasSubstr("`zerog fit` on this table"));
    EXPECT_THAT(what, ::testing::Not(HasSubstr("--block")));
    EXPECT_THAT(what, ::testing::Not(HasSubstr("record longer")));
  }
  // As many poses as the message names: the split is made, one row a block.
  const BlockChoice c = choose_blocks(table(400), 0.0);
  EXPECT_EQ(c.blocks, 400);
  EXPECT_GE(c.heldout_samples, kMinSplitSamples);
  EXPECT_GE(c.training_samples, kMinSplitSamples);
}

TEST(ShortLog, LongLogsKeepSixtySecondBlocks) {
  const BlockChoice c = choose_blocks(times_only(610.0, 0.012), 0.0);
  EXPECT_EQ(c.block_s, kDefaultBlockS);
  EXPECT_EQ(c.blocks, 11);
  EXPECT_THAT(c.text, HasSubstr("the default"));
  // 300 s: too short for 8 blocks of 60 s: 8 blocks of 37.5 s.
  const BlockChoice m = choose_blocks(times_only(300.0, 0.012), 0.0);
  EXPECT_NEAR(m.block_s, 37.5, 1e-6);
  EXPECT_EQ(m.blocks, 8);
}

}  // namespace
}  // namespace zerog::ident
