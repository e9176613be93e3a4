// The fit's engines (FitOptions::engine): "block_stats" evaluates each block mean of the
// prediction from the block's sufficient statistics (block_stats.hpp), "samples" evaluates the
// model on every sample (the reference), both solved by Ceres; "normal" evaluates the blocks as
// block_stats does and solves the streamed normal equations itself (normal_equations.hpp). All
// must give the same fit: the same parameters and the same standard deviations, on the
// hidden-effect runs of the simulator.
#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include <unistd.h>

#include "zerog/ident/block_stats.hpp"
#include "zerog/ident/fit.hpp"
#include "zerog/io/effect_file.hpp"
#include "zerog/model/predict.hpp"
#include "zerog/sim/design.hpp"
#include "zerog/sim/simulator.hpp"

namespace zerog::ident {
namespace {

using model::Effect;

model::EffectSet full_list() {
  model::EffectSet all;
  for (Effect e : model::kAllEffects) all.add(e);
  return all;
}

// A random-path run of simulator seed `seed` with every effect of the model library hidden in it
// (none outside it), cut to `seconds`.
Dataset simulated_library_run(std::uint64_t seed, double seconds) {
  sim::SimConfig cfg = sim::default_sim_config(seed);
  cfg.effects = sim::parse_sim_effects(
      "all,-joint6_friction,-swivel_viscous,-hose_drag,"
      "-dress_pack_bend");
  cfg.duration_limit_s = seconds;
  sim::DesignOptions d;
  d.kind = sim::DesignKind::random;
  d.points = 60;
  d.workspace.floor_z_m = cfg.floor_z_m;
  return make_dataset(sim::RigSimulator(cfg, sim::make_design(d).points_rad).run().log);
}

// The fixture: seed 5, cut to 130 s (10,800 rows).
const Dataset& library_run() {
  static const Dataset data = simulated_library_run(5, 130.0);
  return data;
}

// ---- The statistics against the samples, block by block -------------------------------------

// Every block of 8 rows of the log (the first and the last included), the full payload model with
// random parameters, the IMU time offset at fractional and whole shifts of either sign (windows
// that cross the running sums' segments, and that reach the log's ends, where interpolate_uniform
// clamps and the statistics fall back to the samples): value and every derivative equal.
TEST(BlockStats, PayloadMeanEqualsTheMeanOverTheInterpolatedSamples) {
  using J = ceres::Jet<double, 16>;
  const Dataset& data = library_run();
  ASSERT_GT(data.size(), 2u * 4096u + 100u);  // two segment boundaries of the running sums
  const std::size_t m = 8;
  SampleBlocks blocks;
  for (std::size_t b = 0; b + m <= data.size(); b += m) blocks.emplace_back(b, m);
  blocks.emplace_back(data.size() - m, m);  // the very last rows
  blocks.emplace_back(4093, 5);             // odd start and length across a segment boundary

  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (const model::EffectSet& effects :
       {model::EffectSet{Effect::gravity, Effect::linear_inertia, Effect::rotational_inertia,
                         Effect::imu_time_offset, Effect::sensor_rotation},
        model::EffectSet{Effect::gravity, Effect::linear_inertia, Effect::rotational_inertia},
        model::EffectSet{Effect::gravity, Effect::base_tilt, Effect::rotational_inertia,
                         Effect::sensor_rotation}}) {
    const BlockStats stats(data, blocks, effects);
    const BlockStats on_three(data, blocks, effects, 3);  // the same numbers on any thread count
    int differ = 0;
    for (double shift : {0.0, 0.37, -0.81, 3.0, -2.0, 5.49, -7.25}) {
      SCOPED_TRACE("effects " + std::to_string(effects.bits()) + ", shift " +
                   std::to_string(shift) + " rows");
      std::array<std::array<J, model::kMaxEffectParams>, model::kEffectCount> values{};
      model::ParamPointers<J> p{};
      int slot = 0;
      for (Effect e : {Effect::gravity, Effect::base_tilt, Effect::rotational_inertia,
                       Effect::imu_time_offset, Effect::sensor_rotation}) {
        for (int i = 0; i < model::info(e).num_params; ++i) {
          double v = 0.05 * u(rng);
          if (e == Effect::gravity && i == 0) v = 100.0 + 10.0 * u(rng);
          if (e == Effect::rotational_inertia && i < 3) v = 5.0 + u(rng);
          if (e == Effect::imu_time_offset) v = shift * data.dt_s;
          values[model::index(e)][i] = J(v, slot++);
        }
        if (effects.has(e)) p[model::index(e)] = values[model::index(e)].data();
      }
      std::size_t fallbacks = 0;
      double worst = 0.0, worst_d = 0.0;
      for (std::size_t b = 0; b < blocks.size(); ++b) {
        const auto [first, count] = blocks[b];
        const model::Wrench<J> ref = payload_mean_by_samples<J>(data, effects, p, first, count);
        const model::Wrench<J> got = stats.payload_mean<J>(effects, p, b);
        const model::Wrench<J> three = on_three.payload_mean<J>(effects, p, b);
        for (int k = 0; k < 6; ++k) {
          differ +=
              std::bit_cast<std::uint64_t>(three[k].a) != std::bit_cast<std::uint64_t>(got[k].a);
          for (int d = 0; d < 16; ++d)
            differ += std::bit_cast<std::uint64_t>(three[k].v[d]) !=
                      std::bit_cast<std::uint64_t>(got[k].v[d]);
        }
        const BlockSensorMeans& s1 = stats.sensor_means(b);
        const BlockSensorMeans& s3 = on_three.sensor_means(b);
        differ += s1.measured != s3.measured || s1.inputs.t_rel_s != s3.inputs.t_rel_s ||
                  s1.inputs.temperature_C != s3.inputs.temperature_C ||
                  s1.inputs.cable_features != s3.inputs.cable_features;
        model::PayloadMeans<J> means;
        const J* tau = effects.has(Effect::imu_time_offset)
                           ? p[model::index(Effect::imu_time_offset)]
                           : nullptr;
        if (!stats.payload_means<J>(b, tau, means)) ++fallbacks;
        double scale = 1e-300, dscale = 1e-300;
        for (int k = 0; k < 6; ++k) {
          scale = std::max(scale, std::abs(ref[k].a));
          dscale = std::max(dscale, ref[k].v.cwiseAbs().maxCoeff());
        }
        for (int k = 0; k < 6; ++k) {
          worst = std::max(worst, std::abs(got[k].a - ref[k].a) / scale);
          worst_d = std::max(worst_d, (got[k].v - ref[k].v).cwiseAbs().maxCoeff() / dscale);
        }
      }
      EXPECT_LT(worst, 1e-12);
      EXPECT_LT(worst_d, 1e-12);
      std::printf(
          "[ stats    ] effects %4u shift %6.2f: value %.1e, derivatives %.1e, %zu blocks "
          "by samples\n",
          effects.bits(), shift, worst, worst_d, fallbacks);
      // Only the blocks whose shifted window reaches an end of the log fall back to the samples
      // (with the time offset in the model at least one: the first or the last block).
      if (effects.has(Effect::imu_time_offset)) {
        EXPECT_GE(fallbacks, 1u);
        EXPECT_LE(fallbacks, 3u + static_cast<std::size_t>(std::abs(shift)) / m + 1u);
      } else {
        EXPECT_EQ(fallbacks, 0u);
      }
    }
    EXPECT_EQ(differ, 0) << "statistics formed on 3 threads differ from those formed on 1";
  }
}

// ---- Whole fits: the engines agree ------------------------------------------------------------

struct Agreement {
  double params = 0.0;  // largest |a − b| / |b| over the free parameters
  double stds = 0.0;    // largest relative difference of the standard deviations
  int stds_compared = 0;
};

// Where the fit's identifiability check lands (fit.cpp, rank_check: eigenvalues of the
// column-scaled JᵀJ below 1e-9 of the largest, the cut moved to the widest gap of the spectrum
// nearby, are a rank deficiency; the parameters with large entries in the null space's
// directions, chosen from its projector, get no std). Either way both fits must report the same
// deficiencies: the same warnings naming the same parameters, and the same stds missing.
enum class Conditioning {
  // Every eigenvalue is far from the threshold: also the same other warnings (correlations).
  clear,
  // The model has near-degenerate directions (the full list: crosstalk against sensor rotation
  // and the centre of mass, base tilt against the accelerometer): correlations near the warning
  // threshold |rho| = 0.99 may differ by rounding; the deficiencies may not.
  near_degenerate,
};

// Compares every free parameter and every standard deviation of two fits of `o`.
Agreement compare_fits(const FitResult& ref, const FitResult& got, const FitOptions& o,
                       const std::string& what, Conditioning conditioning) {
  const bool clear = conditioning == Conditioning::clear;
  SCOPED_TRACE(what);
  Agreement a;
  EXPECT_TRUE(ref.usable) << ref.termination;
  EXPECT_TRUE(got.usable) << got.termination;
  EXPECT_EQ(got.num_params, ref.num_params);
  EXPECT_EQ(got.samples, ref.samples);
  EXPECT_EQ(got.std.has_value(), ref.std.has_value());
  auto rel = [](double x, double y) {
    if (x == y) return 0.0;
    return std::abs(x - y) / std::max(std::abs(y), 1e-300);
  };
  for (Effect e : model::kAllEffects) {
    if (!o.effects.has(e)) continue;
    for (int i = 0; i < model::info(e).num_params; ++i) {
      const double x = got.params.block(e)[i], y = ref.params.block(e)[i];
      a.params = std::max(a.params, rel(x, y));
      EXPECT_NEAR(x, y, 1e-6 * std::abs(y)) << param_label(e, i);
      if (!ref.std || !got.std) continue;
      const double sx = (*got.std)[model::index(e)][i], sy = (*ref.std)[model::index(e)][i];
      EXPECT_EQ(std::isnan(sx), std::isnan(sy)) << param_label(e, i);
      if (std::isnan(sy) || std::isnan(sx)) continue;
      a.stds = std::max(a.stds, rel(sx, sy));
      ++a.stds_compared;
      EXPECT_NEAR(sx, sy, 1e-6 * sy) << "std of " << param_label(e, i);
    }
  }
  for (int j = 0; j < o.user.num_terms; ++j) {
    const auto q = static_cast<std::size_t>(j);
    const double x = got.params.user.coeff[q], y = ref.params.user.coeff[q];
    a.params = std::max(a.params, rel(x, y));
    EXPECT_NEAR(x, y, 1e-6 * std::abs(y)) << "user term " << j;
    if (q >= ref.user_std.size() || q >= got.user_std.size()) continue;
    a.stds = std::max(a.stds, rel(got.user_std[q], ref.user_std[q]));
    ++a.stds_compared;
    EXPECT_NEAR(got.user_std[q], ref.user_std[q], 1e-6 * ref.user_std[q]) << "user term " << j;
  }
  EXPECT_EQ(got.user_std.size(), ref.user_std.size());
  for (int k = 0; k < 6; ++k) {
    EXPECT_NEAR(got.sigma[k], ref.sigma[k], 1e-9 * ref.sigma[k]);
    EXPECT_NEAR(got.residual_rms[k], ref.residual_rms[k], 1e-6 * ref.residual_rms[k]);
  }
  EXPECT_NEAR(got.bic, ref.bic, 1e-6 * std::abs(ref.bic));
  auto messages = [](const FitResult& r, const std::string& kind) {
    std::vector<std::string> m;
    for (const Warning& w : r.warnings)
      if (w.kind == kind) m.push_back(w.message);
    std::sort(m.begin(), m.end());
    return m;
  };
  auto count = [](const FitResult& r, const std::string& kind) {
    return std::count_if(r.warnings.begin(), r.warnings.end(),
                         [&](const Warning& w) { return w.kind == kind; });
  };
  EXPECT_EQ(count(got, "rank_deficient"), count(ref, "rank_deficient"));
  EXPECT_EQ(messages(got, "rank_deficient"), messages(ref, "rank_deficient"));
  EXPECT_EQ(count(got, "not_converged"), count(ref, "not_converged"));
  if (clear) {
    EXPECT_EQ(got.warnings.size(), ref.warnings.size());
    for (std::size_t k = 0; k < std::min(got.warnings.size(), ref.warnings.size()); ++k) {
      EXPECT_EQ(got.warnings[k].kind, ref.warnings[k].kind);
      EXPECT_EQ(got.warnings[k].message, ref.warnings[k].message);
    }
  }
  std::printf(
      "[ engines  ] %-52s params %.2e  stds %.2e (%d of %d compared; %ld deficiencies), "
      "%.2f s vs %.2f s\n",
      what.c_str(), a.params, a.stds, a.stds_compared, ref.num_params,
      static_cast<long>(count(ref, "rank_deficient")), got.seconds, ref.seconds);
  return a;
}

struct EngineAgreement {
  Agreement block_stats;  // against samples
  Agreement normal;       // against block_stats
};

// Fits with the three engines: block_stats against the samples reference, normal against
// block_stats (Ceres on the same block evaluation).
EngineAgreement compare_engines(const Dataset& data, FitOptions o, const std::string& what,
                                Conditioning conditioning = Conditioning::clear) {
  o.engine = "samples";
  const FitResult samples = fit(data, o);
  o.engine = "block_stats";
  const FitResult block_stats = fit(data, o);
  o.engine = "normal";
  const FitResult normal = fit(data, o);
  // A robust loss is delegated to block_stats (normal_equations.hpp), and says so.
  EXPECT_EQ(normal.engine, o.loss == "none" ? "normal" : "block_stats");
  EngineAgreement a;
  a.block_stats =
      compare_fits(samples, block_stats, o, what + ": block_stats vs samples", conditioning);
  a.normal = compare_fits(block_stats, normal, o, what + ": normal vs block_stats", conditioning);
  return a;
}

TEST(FitEngine, EnginesAgreeOnTheFullLibraryList) {
  const Dataset& data = library_run();
  FitOptions o;
  o.effects = full_list();
  const EngineAgreement a =
      compare_engines(data, o, "full library list", Conditioning::near_degenerate);
  EXPECT_GE(a.block_stats.stds_compared, 60);
  EXPECT_GE(a.normal.stds_compared, 60);
}

TEST(FitEngine, EnginesAgreeOnTheDefaultModel) {
  const Dataset& data = library_run();
  FitOptions o;
  o.effects = model::kDefaultModel;
  compare_engines(data, o, "default model");
}

// A user-defined effect (proto/user_effects.md): a viscous swivel, one term.
model::UserEffects swivel_user_term() {
  namespace fs = std::filesystem;
  const fs::path file =
      fs::temp_directory_path() / ("zerog_fit_engine_" + std::to_string(getpid()) + ".toml");
  std::ofstream(file) << "format = \"zerog-effect\"\nversion = 1\nname = \"swivel\"\n"
                         "description = \"viscous swivel\"\n\n[[term]]\naxis = \"Mz\"\n"
                         "basis = \"wz_S\"\nunit = \"N*m/(rad/s)\"\nvalue = 0.0\n";
  model::UserEffects user;
  io::read_effect_file(file, user);
  fs::remove(file);
  return user;
}

// The masked fits of diagnose and ladder (training blocks only), with a robust loss, a partial
// model with a user term (proto/user_effects.md), and block means of another length.
TEST(FitEngine, EnginesAgreeOnAMaskedRobustFit) {
  const Dataset& data = library_run();
  const auto held = heldout_mask(data, 20.0, 4);
  std::vector<std::uint8_t> train(held.size());
  for (std::size_t i = 0; i < held.size(); ++i) train[i] = held[i] ? 0 : 1;
  FitOptions o;
  o.effects = model::kDefaultModel;
  o.effects.add(Effect::imu_time_offset);
  o.effects.add(Effect::sensor_rotation);
  o.effects.add(Effect::cable);
  o.user = swivel_user_term();
  ASSERT_EQ(o.user.num_terms, 1);
  o.mask = &train;
  o.loss = "huber";
  o.block_samples = 5;
  compare_engines(data, o, "masked, huber, user term, blocks of 5");
  // The same without the robust loss: the normal engine solves it itself.
  o.loss = "none";
  compare_engines(data, o, "masked, user term, blocks of 5");
}

// A tool change: the sensor model frozen at a fitted model, gravity re-fitted on the static
// samples (FitOptions::frozen with a mask of the dwells, as fit_tool_change sets it up).
TEST(FitEngine, EnginesAgreeWithFrozenEffects) {
  const Dataset& data = library_run();
  FitOptions base_options;
  base_options.effects = full_list();
  base_options.covariance = false;
  const FitResult base = fit(data, base_options);
  ASSERT_TRUE(base.usable);
  const std::vector<std::uint8_t> mask = static_mask(data);
  FitOptions o;
  o.effects = base.params.effects;
  o.frozen = o.effects;
  o.frozen.remove(Effect::gravity);
  o.initial = &base.params;
  o.mask = &mask;
  compare_engines(data, o, "tool change (frozen, static mask)");
}

// Without dwells (the moving samples only) the whitening cannot be estimated before the solve:
// two passes, the second whitened by the first's block-mean residuals (from the block statistics
// with block_stats); with a user term, which those residuals must include.
TEST(FitEngine, EnginesAgreeWithoutDwellsInTwoPasses) {
  const Dataset& data = library_run();
  std::vector<std::uint8_t> moving = static_mask(data);
  for (auto& m : moving) m = m ? 0 : 1;
  FitOptions o;
  o.effects = model::kDefaultModel;
  o.effects.add(Effect::imu_time_offset);
  o.user = swivel_user_term();
  o.mask = &moving;
  compare_engines(data, o, "moving samples only (two passes)");
  // Two passes indeed: the second pass's line is printed.
  std::vector<std::string> lines;
  o.progress = [&](const std::string& line) { lines.push_back(line); };
  fit(data, o);
  EXPECT_TRUE(std::any_of(lines.begin(), lines.end(), [](const std::string& line) {
    return line.rfind("fit pass 2/2", 0) == 0;
  }));
}

// Acceptance on more runs: the normal engine against block_stats (Ceres on the same block
// evaluation) with the full list and the default model, simulator seeds 1 to 3 (60 s each).
TEST(FitEngine, NormalEqualsBlockStatsOnSeveralSeeds) {
  for (const std::uint64_t seed : {1u, 2u, 3u}) {
    const Dataset data = simulated_library_run(seed, 60.0);
    for (const bool full : {true, false}) {
      FitOptions o;
      o.effects = full ? full_list() : model::kDefaultModel;
      o.engine = "block_stats";
      const FitResult ref = fit(data, o);
      o.engine = "normal";
      const FitResult got = fit(data, o);
      const Agreement a =
          compare_fits(ref, got, o,
                       "seed " + std::to_string(seed) + (full ? ", full list" : ", default model") +
                           ": normal vs block_stats",
                       full ? Conditioning::near_degenerate : Conditioning::clear);
      EXPECT_GE(a.stds_compared, full ? 60 : 16);
    }
  }
}

// The normal engine sums its chunks' normal equations in chunk order: the same bits for any
// number of threads (the full list: 1,350 blocks, three chunks; the default model).
TEST(FitEngine, NormalIsBitIdenticalForAnyThreadCount) {
  const Dataset& data = library_run();
  for (const model::EffectSet& effects : {full_list(), model::kDefaultModel}) {
    SCOPED_TRACE("effects " + std::to_string(effects.bits()));
    FitOptions o;
    o.effects = effects;
    o.engine = "normal";
    o.threads = 1;
    const FitResult one = fit(data, o);
    o.threads = 2;
    const FitResult two = fit(data, o);
    o.threads = 3;
    const FitResult three = fit(data, o);
    ASSERT_TRUE(one.usable && two.usable && three.usable);
    ASSERT_TRUE(one.std && two.std && three.std);
    const auto bits = [](double v) { return std::bit_cast<std::uint64_t>(v); };
    int differ = 0;
    for (Effect e : model::kAllEffects) {
      if (!effects.has(e)) continue;
      for (int i = 0; i < model::info(e).num_params; ++i) {
        const double x = one.params.block(e)[i];
        for (const FitResult* r : {&two, &three}) {
          EXPECT_EQ(bits(r->params.block(e)[i]), bits(x)) << param_label(e, i);
          const double s1 = (*one.std)[model::index(e)][i], s = (*r->std)[model::index(e)][i];
          EXPECT_TRUE(bits(s) == bits(s1)) << "std of " << param_label(e, i);
          differ += bits(r->params.block(e)[i]) != bits(x) || bits(s) != bits(s1);
        }
      }
    }
    // The residuals' figures from the last pass (formed on the threads, summed in order).
    for (const FitResult* r : {&two, &three}) {
      EXPECT_EQ(bits(r->bic), bits(one.bic));
      for (int k = 0; k < 6; ++k) EXPECT_EQ(bits(r->residual_rms[k]), bits(one.residual_rms[k]));
    }
    EXPECT_EQ(three.warnings.size(), one.warnings.size());
    std::printf("[ threads  ] effects %u: %d values or stds differ between 1, 2 and 3 threads\n",
                effects.bits(), differ);
  }
}

TEST(FitEngine, UnknownEngineIsRefused) {
  const Dataset& data = library_run();
  FitOptions o;
  o.effects = model::kMinimalModel;
  o.engine = "fast";
  EXPECT_THROW(fit(data, o), std::runtime_error);
}

}  // namespace
}  // namespace zerog::ident
