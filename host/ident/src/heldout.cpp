// The held-out split of a log into time blocks (every fourth held out unless told otherwise), the
// baseline model fitted on the training blocks, and the held-out error and white noise every
// diagnosis measures against (diagnose_internal.hpp).
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "diagnose_internal.hpp"
#include "zerog/io/model_file.hpp"

namespace zerog::ident::diagnosis {
namespace {

std::vector<std::uint8_t> invert(const std::vector<std::uint8_t>& m) {
  std::vector<std::uint8_t> out(m.size());
  for (std::size_t i = 0; i < m.size(); ++i) out[i] = m[i] ? 0 : 1;
  return out;
}

struct SplitCount {
  std::size_t heldout = 0, train = 0;
};

SplitCount count_split(const Dataset& data, double block_s, int every, int offset,
                       const std::vector<std::uint8_t>* exclude) {
  const auto mask = heldout_mask(data, block_s, every, offset);
  SplitCount n;
  for (std::size_t i = 0; i < mask.size(); ++i) {
    if (exclude && (*exclude)[i]) continue;
    (mask[i] ? n.heldout : n.train) += 1;
  }
  return n;
}

BlockChoice choose_blocks_excluding(const Dataset& data, double block_s, int every, int offset,
                                    const std::vector<std::uint8_t>* exclude) {
  BlockChoice c;
  const double duration = data.size() > 1 ? data.t_s.back() - data.t_s.front() : 0.0;
  const std::string log_words =
      std::to_string(data.size()) + " samples over " + fmt("%.1f", duration) + " s";
  const int keep = every > 0 ? every : 4;
  if (data.columns.static_rows) {
    c.block_s = 0.0;
    c.blocks = static_cast<int>(data.size());
    c.text = "rows without time: each row is its own block (every " + std::to_string(keep) +
             "th row held out)";
  } else if (block_s > 0.0) {
    c.block_s = block_s;
    c.automatic = false;
  } else if (duration >= kMinBlocks * kDefaultBlockS) {
    c.block_s = kDefaultBlockS;
  } else if (duration >= kMinBlocks * kMinBlockS) {
    // A hair longer than duration / 8, so that the last sample falls in block 8, not a 9th.
    c.block_s = duration / kMinBlocks * (1.0 + 1e-9);
  } else {
    throw std::runtime_error(
        "log too short for a time-blocked held-out split (" + log_words + "): it needs at least " +
        std::to_string(kMinBlocks) + " blocks of at least " + fmt("%.1f", kMinBlockS) +
        " s, i.e. " + fmt("%.0f", kMinBlocks * kMinBlockS) + " s of recording with at least " +
        std::to_string(kMinSplitSamples) +
        " samples held out; record longer, or import the poses as rows without time (static "
        "samples, one block each)");
  }
  if (!data.columns.static_rows) c.blocks = static_cast<int>(std::floor(duration / c.block_s)) + 1;
  const SplitCount n = count_split(data, c.block_s, keep, offset, exclude);
  c.heldout_samples = n.heldout;
  c.training_samples = n.train;
  if (data.columns.static_rows && (n.heldout < kMinSplitSamples || n.train < kMinSplitSamples)) {
    // A static table: no blocks to choose, only more poses (or a fit without a held-out split).
    throw std::runtime_error(
        "static table of " + std::to_string(data.size()) + " rows (no time): diagnose holds out " +
        "every " + std::to_string(keep) + "th row and needs at least " +
        std::to_string(kMinSplitSamples) + " held-out and " + std::to_string(kMinSplitSamples) +
        " training rows (here " + std::to_string(n.heldout) + " and " + std::to_string(n.train) +
        "), about " + std::to_string(static_cast<std::size_t>(keep) * kMinSplitSamples) +
        " poses: record more poses (a longer design, or several readings per pose), or use "
        "`zerog fit` on this table (it fits every row: bias, gravity and the payload, without "
        "a held-out split) and `zerog compare` for the residual of each pose");
  }
  if (n.heldout < kMinSplitSamples || n.train < kMinSplitSamples) {
    // What would work: the longest block that still gives both sides enough samples.
    std::string hint = "record longer";
    if (!data.columns.static_rows) {
      for (double b = std::min(block_s > 0 ? block_s : kDefaultBlockS, duration / 2);
           b >= kMinBlockS * 0.999; b *= 0.9) {
        const SplitCount m = count_split(data, b, keep, offset, exclude);
        if (m.heldout >= kMinSplitSamples && m.train >= kMinSplitSamples) {
          hint = "use --block " + fmt("%.3g", b) + " or shorter (or omit --block: zerog chooses)";
          break;
        }
      }
    }
    throw std::runtime_error("log too short for a time-blocked held-out split (" + log_words +
                             ", " +
                             (c.block_s > 0 ? "blocks of " + fmt("%.3g", c.block_s) + " s"
                                            : std::string("one row each")) +
                             ": " + std::to_string(n.heldout) + " held-out and " +
                             std::to_string(n.train) + " training samples, at least " +
                             std::to_string(kMinSplitSamples) + " each are needed): " + hint);
  }
  if (c.text.empty()) {
    c.text = "blocks of " + fmt("%.3g", c.block_s) + " s (" + std::to_string(c.blocks) +
             " blocks in " + fmt("%.1f", duration) + " s, every " + std::to_string(keep) +
             "th held out: " + std::to_string(n.heldout) + " held-out samples); " +
             (c.automatic ? (c.block_s == kDefaultBlockS
                                 ? std::string("the default")
                                 : "chosen for this short log (" + std::to_string(kMinBlocks) +
                                       " blocks; 60 s needs a log of " +
                                       fmt("%.0f", kMinBlocks * kDefaultBlockS) + " s)")
                          : std::string("given with --block"));
  }
  return c;
}

}  // namespace

// The residuals (measured − predicted) of the samples in `mask` (every sample without one; zero
// outside it in a new vector, left as they were in `out`), on `threads` threads: each sample's
// is its own, as residuals() forms it.
void residuals_into(std::vector<Wrench>& out, const model::ModelParams& params, const Dataset& data,
                    const std::vector<std::uint8_t>* mask, int threads) {
  const std::size_t n = data.size();
  out.resize(n, Wrench::Zero());
  for_each_sample_chunk(data, threads, [&](std::size_t i0, std::size_t i1) {
    for (std::size_t i = i0; i < i1; ++i)
      if (!mask || (*mask)[i]) out[i] = data.measured[i] - predict(params, data, i);
  });
}

std::vector<Wrench> residuals_of(const model::ModelParams& params, const Dataset& data,
                                 const std::vector<std::uint8_t>* mask, int threads) {
  std::vector<Wrench> out;
  residuals_into(out, params, data, mask, threads);
  return out;
}

HeldOut heldout_error(const std::vector<Wrench>& res, const std::vector<std::uint8_t>& mask,
                      const std::array<double, 6>& sigma) {
  ErrorAccumulator acc;
  double ws = 0.0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < res.size(); ++i) {
    if (!mask[i]) continue;
    acc.add(res[i]);
    for (int k = 0; k < 6; ++k) ws += (res[i][k] / sigma[k]) * (res[i][k] / sigma[k]);
    ++n;
  }
  HeldOut h;
  h.stats = acc.stats();
  h.whitened_mse = n ? ws / (6.0 * static_cast<double>(n)) : 0.0;
  return h;
}

std::array<double, 6> noise_estimate(const std::vector<Wrench>& res,
                                     const std::vector<std::uint8_t>& mask) {
  constexpr std::size_t kLag = 5;
  std::array<double, 6> dd{};
  std::size_t nd = 0;
  for (std::size_t i = kLag; i < res.size(); ++i) {
    if (!mask[i] || !mask[i - kLag]) continue;
    const Wrench diff = res[i] - res[i - kLag];
    for (int k = 0; k < 6; ++k) dd[k] += diff[k] * diff[k];
    ++nd;
  }
  std::array<double, 6> out{};
  for (int k = 0; k < 6; ++k)
    out[k] = std::max(std::sqrt(dd[k] / (2.0 * static_cast<double>(std::max<std::size_t>(nd, 1)))),
                      1e-9);
  return out;
}

Split make_split(const Dataset& data, const DiagnoseOptions& o) {
  Split s;
  s.blocks = choose_blocks_excluding(data, o.block_s, o.every, o.heldout_offset, o.exclude);
  s.heldout = heldout_mask(data, s.blocks.block_s, o.every, o.heldout_offset);
  s.train = invert(s.heldout);
  if (o.exclude) {
    for (std::size_t i = 0; i < data.size(); ++i) {
      if ((*o.exclude)[i]) s.heldout[i] = 0, s.train[i] = 0;
    }
  }
  return s;
}

Baseline fit_baseline(const Dataset& data, const model::EffectSet& effects,
                      const model::UserEffects& user, const Split& split, const DiagnoseOptions& o,
                      const model::ModelParams* initial) {
  FitOptions fo = o.fit;
  fo.effects = effects;
  fo.user = user;
  fo.mask = &split.train;
  fo.covariance = false;
  fo.initial = initial;
  fo.progress = nullptr;
  Baseline b;
  b.fit = fit(data, fo);
  if (!b.fit.usable)
    throw std::runtime_error("the fit of the model " + io::effect_list_string(effects) +
                             " is not usable: " + b.fit.termination);
  b.res = residuals_of(b.fit.params, data, nullptr, o.fit.threads);
  b.heldout = heldout_error(b.res, split.heldout, b.fit.residual_rms);
  return b;
}

}  // namespace zerog::ident::diagnosis

namespace zerog::ident {

BlockChoice choose_blocks(const Dataset& data, double block_s, int every, int offset) {
  return diagnosis::choose_blocks_excluding(data, block_s, every, offset, nullptr);
}

}  // namespace zerog::ident
