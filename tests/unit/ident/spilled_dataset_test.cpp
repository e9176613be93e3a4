// Spilled datasets (issue 16, spill.hpp): a Dataset whose columns live in a memory-mapped spill
// file fits to the same bits as one on the heap, and the passes over it release what they walked
// (each ResidentWindow keeps at most about two windows of rows unreleased), so that a log of any
// length fits in bounded memory. The spill is forced on a small log (threshold 0, a window of
// 256 rows); nothing here reads the resident size (it depends on the kernel): the checks are on
// what the passes released and how far behind their front.
#include <gtest/gtest.h>

#include <bit>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>

#include "zerog/ident/dataset.hpp"
#include "zerog/ident/fit.hpp"
#include "zerog/ident/spill.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::ident {
namespace {

using model::Effect;

// The spill settings for the test's scope (whatever the environment says), restored after.
class SpillSettings {
 public:
  SpillSettings(std::size_t min_bytes, std::size_t window_rows) : saved_(spill::settings()) {
    spill::settings().min_bytes = min_bytes;
    spill::settings().window_rows = window_rows;
  }
  ~SpillSettings() { spill::settings() = saved_; }
  SpillSettings(const SpillSettings&) = delete;
  SpillSettings& operator=(const SpillSettings&) = delete;

 private:
  spill::Settings saved_;
};

// A random-path run with every library effect, cut to `seconds` (12 ms rows).
formats::Log library_log(double seconds) {
  sim::SimConfig cfg = sim::default_sim_config(7);
  cfg.effects =
      sim::parse_sim_effects("all,-joint6_friction,-swivel_viscous,-hose_drag,-dress_pack_bend");
  cfg.duration_limit_s = seconds;
  sim::DesignOptions d;
  d.kind = sim::DesignKind::random;
  d.points = 40;
  d.workspace.floor_z_m = cfg.floor_z_m;
  return sim::RigSimulator(cfg, sim::make_design(d).points_rad).run().log;
}

std::uint64_t bits(double v) { return std::bit_cast<std::uint64_t>(v); }

// Every value the fit reports, bit for bit.
void expect_same_fit(const FitResult& got, const FitResult& want) {
  ASSERT_EQ(got.usable, want.usable);
  EXPECT_EQ(got.iterations, want.iterations);
  EXPECT_EQ(got.samples, want.samples);
  EXPECT_EQ(got.termination, want.termination);
  EXPECT_EQ(bits(got.bic), bits(want.bic));
  for (int k = 0; k < 6; ++k) {
    EXPECT_EQ(bits(got.sigma[k]), bits(want.sigma[k])) << "sigma " << k;
    EXPECT_EQ(bits(got.residual_rms[k]), bits(want.residual_rms[k])) << "rms " << k;
  }
  ASSERT_EQ(got.std.has_value(), want.std.has_value());
  for (Effect e : model::kAllEffects) {
    if (!want.params.effects.has(e)) continue;
    for (int i = 0; i < model::info(e).num_params; ++i) {
      EXPECT_EQ(bits(got.params.block(e)[i]), bits(want.params.block(e)[i])) << param_label(e, i);
      if (want.std) {
        EXPECT_EQ(bits((*got.std)[model::index(e)][i]), bits((*want.std)[model::index(e)][i]))
            << "std of " << param_label(e, i);
      }
    }
  }
  ASSERT_EQ(got.warnings.size(), want.warnings.size());
  for (std::size_t w = 0; w < want.warnings.size(); ++w)
    EXPECT_EQ(got.warnings[w].message, want.warnings[w].message);
}

TEST(SpilledDataset, SmallLogsStayOnTheHeap) {
  const SpillSettings defaults(spill::Settings{}.min_bytes, spill::Settings{}.window_rows);
  const Dataset data = make_dataset(library_log(20.0));
  EXPECT_FALSE(spill::spilled(data.t_s.data()));
  EXPECT_FALSE(spill::spilled(data.imu.data()));
}

TEST(SpilledDataset, FitsToTheSameBitsAndReleasesWhatItWalked) {
  constexpr std::size_t kWindow = 256;
  const formats::Log log = library_log(90.0);
  const Dataset heap = [&] {
    const SpillSettings on_heap(SIZE_MAX, kWindow);
    return make_dataset(log);
  }();
  ASSERT_FALSE(heap.spilled());
  ASSERT_GT(heap.size(), 20 * kWindow);
  const SpillSettings forced(0, kWindow);
  const std::size_t released_before = spill::stats().released_bytes;
  spill::stats().peak_window_rows = 0;
  const Dataset disk = make_dataset(log);
  for (const void* column :
       {static_cast<const void*>(disk.t_s.data()),
        static_cast<const void*>(disk.q_base_sensor.data()),
        static_cast<const void*>(disk.joints_rad.data()), static_cast<const void*>(disk.imu.data()),
        static_cast<const void*>(disk.measured.data()),
        static_cast<const void*>(disk.moving.data()),
        static_cast<const void*>(disk.p_base_sensor_m.data())})
    EXPECT_TRUE(spill::spilled(column));
  // Building released the rows behind it.
  EXPECT_GE(spill::stats().released_bytes - released_before, disk.bytes() / 2);

  for (const bool default_model : {true, false}) {
    SCOPED_TRACE(default_model ? "default model" : "full list");
    FitOptions o;
    if (default_model) {
      o.effects = model::kDefaultModel;
    } else {
      for (Effect e : model::kAllEffects) o.effects.add(e);
    }
    const FitResult want = fit(heap, o);
    const std::size_t released = spill::stats().released_bytes;
    const std::size_t walks = spill::stats().walks;
    spill::stats().peak_window_rows = 0;
    const FitResult got = fit(disk, o);
    expect_same_fit(got, want);
    std::printf("[ spill    ] %zu walks, %zu B released (%.2f x the columns), %d iterations\n",
                spill::stats().walks - walks, spill::stats().released_bytes - released,
                static_cast<double>(spill::stats().released_bytes - released) /
                    static_cast<double>(disk.bytes()),
                got.iterations);
    // Every pass released its rows (a fit walks the log several times), never more than about
    // two windows behind its front.
    EXPECT_GE(spill::stats().released_bytes - released, 3 * disk.bytes());
    // The solver's passes walk the rows too (NormalBlocks::walk): at least one walk for each of
    // its iterations, beyond the few passes around the solve.
    EXPECT_GT(spill::stats().walks - walks, static_cast<std::size_t>(got.iterations) + 3);
    EXPECT_GT(spill::stats().peak_window_rows.load(), 0u);
    EXPECT_LE(spill::stats().peak_window_rows.load(), 2 * kWindow + 1);
  }
}

// A spilled dataset in a static made before the first spill (so destroyed at exit after anything
// the spill made later) is unmapped, not passed to the heap: ctest runs each case in a process of
// its own, where this one is the first to spill.
TEST(SpilledDataset, AStaticDatasetIsFreedAtExit) {
  static std::optional<Dataset> held;
  const SpillSettings forced(0, 64);
  held.emplace(make_dataset(library_log(5.0)));
  EXPECT_TRUE(held->spilled());
}

TEST(SpilledDataset, ReadsBackWhatItReleased) {
  const formats::Log log = library_log(30.0);
  const Dataset heap = [&] {
    const SpillSettings on_heap(SIZE_MAX, 64);
    return make_dataset(log);
  }();
  const SpillSettings forced(0, 64);
  const Dataset disk = make_dataset(log);
  disk.release_rows(0, disk.size());
  ASSERT_EQ(disk.size(), heap.size());
  for (std::size_t i = 0; i < heap.size(); ++i) {
    ASSERT_EQ(bits(disk.t_s[i]), bits(heap.t_s[i])) << i;
    for (int k = 0; k < 9; ++k) ASSERT_EQ(bits(disk.imu[i * 9 + k]), bits(heap.imu[i * 9 + k]));
    ASSERT_TRUE(disk.measured[i] == heap.measured[i]) << i;
    ASSERT_EQ(disk.moving[i], heap.moving[i]) << i;
  }
}

TEST(SpilledDataset, AFullDirectoryIsAClearError) {
  // /proc is not writable: creating the file fails, and the message names the directory and the
  // bytes (a full disk fails the same way at posix_fallocate, ENOSPC).
  const char* before = std::getenv("ZEROG_SPILL_DIR");
  const std::string saved = before ? before : "";
  ::setenv("ZEROG_SPILL_DIR", "/proc", 1);
  const SpillSettings forced(0, 64);
  try {
    (void)make_dataset(library_log(5.0));
    ADD_FAILURE() << "expected an error";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("/proc"), std::string::npos) << what;
    EXPECT_NE(what.find("bytes"), std::string::npos) << what;
    EXPECT_NE(what.find("ZEROG_SPILL_DIR"), std::string::npos) << what;
  }
  if (before)
    ::setenv("ZEROG_SPILL_DIR", saved.c_str(), 1);
  else
    ::unsetenv("ZEROG_SPILL_DIR");
}

}  // namespace
}  // namespace zerog::ident
