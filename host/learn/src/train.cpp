#include "zerog/learn/train.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <span>
#include <stdexcept>

#include "zerog/ident/compare.hpp"
#include "zerog/ident/diagnose.hpp"
#include "zerog/learn/optimise.hpp"
#include "zerog/learn/predict.hpp"
#include "zerog/learn/signals.hpp"

namespace zerog::learn {

namespace {

using model::Activation;
using model::Feature;

/// Inputs of 000_… §3: sensor position and attitude (the 9 rotation elements), IMU specific
/// force, angular rate and angular acceleration (differenced gyro).
const std::vector<Feature> kPaperBpInputs = {
    Feature::px,  Feature::py,  Feature::pz,  Feature::r11, Feature::r12, Feature::r13,
    Feature::r21, Feature::r22, Feature::r23, Feature::r31, Feature::r32, Feature::r33,
    Feature::fx,  Feature::fy,  Feature::fz,  Feature::wx,  Feature::wy,  Feature::wz,
    Feature::wdx, Feature::wdy, Feature::wdz};
/// Inputs of 001_… §3.1: the 9 elements of the rotation matrix.
const std::vector<Feature> kPaperZpInputs = {Feature::r11, Feature::r12, Feature::r13,
                                             Feature::r21, Feature::r22, Feature::r23,
                                             Feature::r31, Feature::r32, Feature::r33};

void say(const TrainOptions& o, const std::string& s) {
  if (o.progress) o.progress(s);
}

std::vector<std::size_t> indices_where(const std::vector<std::uint8_t>* mask, std::size_t n) {
  std::vector<std::size_t> out;
  for (std::size_t i = 0; i < n; ++i)
    if (!mask || (*mask)[i]) out.push_back(i);
  return out;
}

/// Fisher–Yates with our own index mapping, so identical on every platform for a seed.
void shuffle(std::vector<std::size_t>& v, std::mt19937_64& gen) {
  for (std::size_t i = v.size(); i > 1; --i) std::swap(v[i - 1], v[gen() % i]);
}

/// A seeded random subset of at most `max` elements, in ascending order.
std::vector<std::size_t> subsample(std::vector<std::size_t> v, std::size_t max,
                                   std::mt19937_64& gen) {
  if (v.size() <= max) return v;
  shuffle(v, gen);
  v.resize(max);
  std::sort(v.begin(), v.end());
  return v;
}

TrainingSet make_set(const ident::Dataset& data, const formats::Log& log,
                     const std::vector<Feature>& features, const std::vector<std::size_t>& idx,
                     std::span<const ident::Wrench> target, const std::vector<int>& axes) {
  TrainingSet s;
  s.inputs = static_cast<int>(features.size());
  s.outputs = static_cast<int>(axes.size());
  s.x = feature_rows(data, log, features, idx);
  s.y.reserve(idx.size() * axes.size());
  for (std::size_t i : idx)
    for (int a : axes) s.y.push_back(target[i][a]);
  return s;
}

/// Per-axis RMS (physical units) of the network's error on a set.
std::vector<double> axis_rms(const NetworkFile& n, const TrainingSet& set) {
  const auto k = static_cast<std::size_t>(set.outputs), d = static_cast<std::size_t>(set.inputs);
  std::vector<double> sa(model::kMaxNetworkWidth), sb(model::kMaxNetworkWidth), y(k), ss(k, 0.0);
  for (std::size_t i = 0; i < set.size(); ++i) {
    model::network_forward<double>(n.shape, n.normalisation, n.params.data(), &set.x[i * d],
                                   y.data(), sa.data(), sb.data());
    for (std::size_t o = 0; o < k; ++o) ss[o] += std::pow(y[o] - set.y[i * k + o], 2);
  }
  for (double& v : ss) v = set.size() ? std::sqrt(v / static_cast<double>(set.size())) : 0.0;
  return ss;
}

nlohmann::json axis_json(const std::vector<double>& v, const std::vector<int>& axes) {
  nlohmann::json j = nlohmann::json::object();
  for (std::size_t k = 0; k < v.size(); ++k)
    j[ident::kAxisNames[static_cast<std::size_t>(axes[k])]] = v[k];
  return j;
}

nlohmann::json fit_json(const NetworkFitResult& r) {
  return {{"iterations", r.iterations},
          {"best_iteration", r.best_iteration},
          {"termination", r.termination},
          {"train_mse_normalised", r.train_mse},
          {"validation_mse_normalised",
           std::isfinite(r.validation_mse) ? nlohmann::json(r.validation_mse) : nlohmann::json()},
          {"seconds", r.seconds}};
}

int hidden_or(const TrainOptions& o, int fallback) {
  const int h = o.hidden.value_or(fallback);
  if (h < 1 || h > model::kMaxNetworkWidth)
    throw std::invalid_argument("--hidden must lie in 1.." +
                                std::to_string(model::kMaxNetworkWidth) + ", got " +
                                std::to_string(h));
  return h;
}

void check_common(const ident::Dataset& data, const formats::Log& log, const TrainOptions& o) {
  if (log.samples.size() != data.size())
    throw std::invalid_argument("the dataset was not made from this log");
  if (o.usable && o.usable->size() != data.size())
    throw std::invalid_argument("the sample mask does not fit the log");
  if (o.max_train_samples < 10) throw std::invalid_argument("max_train_samples must be >= 10");
  if (o.max_iterations < 1) throw std::invalid_argument("max_iterations must be >= 1");
  if (o.threads < 1) throw std::invalid_argument("threads must be >= 1");
}

struct BpTrained {
  NetworkFile net;
  NetworkFitResult fit;
};

// 000_… §3–4: one hidden sigmoid layer, random 60/20/20 split into training, validation and test.
BpTrained train_paper_bp(const ident::Dataset& data, const formats::Log& log,
                         const TrainOptions& o) {
  if (!data.columns.full_imu() || data.columns.static_rows)
    throw std::runtime_error(
        "paper-bp needs both IMU groups (imu_f*_mps2 and imu_w*_radps) and time (t_s); the log "
        "lacks them");
  const int hidden = hidden_or(o, 8);
  std::mt19937_64 gen(o.seed);
  std::vector<std::size_t> all = indices_where(o.usable, data.size());
  if (all.size() < 50)
    throw std::runtime_error("paper-bp: too few samples (" + std::to_string(all.size()) + ")");
  shuffle(all, gen);
  const std::size_t n_train = all.size() * 6 / 10, n_val = all.size() * 2 / 10;
  std::vector<std::size_t> tr(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(n_train));
  std::vector<std::size_t> va(all.begin() + static_cast<std::ptrdiff_t>(n_train),
                              all.begin() + static_cast<std::ptrdiff_t>(n_train + n_val));
  std::vector<std::size_t> te(all.begin() + static_cast<std::ptrdiff_t>(n_train + n_val),
                              all.end());
  std::sort(tr.begin(), tr.end());
  std::sort(va.begin(), va.end());
  std::sort(te.begin(), te.end());
  const std::size_t n_train_all = tr.size();
  tr = subsample(std::move(tr), static_cast<std::size_t>(o.max_train_samples), gen);
  va = subsample(std::move(va), 20000, gen);
  const std::vector<int> axes = {0, 1, 2, 3, 4, 5};
  const TrainingSet train = make_set(data, log, kPaperBpInputs, tr, data.measured, axes);
  const TrainingSet val = make_set(data, log, kPaperBpInputs, va, data.measured, axes);
  const TrainingSet test = make_set(data, log, kPaperBpInputs, te, data.measured, axes);
  NetworkFile n;
  n.kind = NetworkKind::paper_bp;
  n.shape.width = {static_cast<int>(kPaperBpInputs.size()), hidden, 6};
  n.shape.activation = {Activation::sigmoid, Activation::identity};
  n.normalisation = normalisation_for(train);
  n.inputs = kPaperBpInputs;
  n.output_axes = axes;
  n.seed = o.seed;
  say(o, "paper-bp: " + std::to_string(n.shape.num_params()) + " parameters, " +
             std::to_string(train.size()) + " training samples (of " + std::to_string(n_train_all) +
             "), " + std::to_string(val.size()) + " validation, " + std::to_string(test.size()) +
             " test");
  LmOptions lm;
  lm.max_iterations = o.max_iterations;
  lm.threads = o.threads;
  lm.label = "paper-bp";
  lm.progress = o.progress;
  NetworkFitResult r =
      fit_lm(n.shape, n.normalisation, train, &val, initial_params(n.shape, o.seed), lm);
  n.params = r.params;
  round_to_float(n);
  n.training = {
      {"method", "000_… §3-4: BP network, one sigmoid hidden layer, random 60/20/20 split"},
      {"optimiser",
       "Levenberg-Marquardt (Ceres, DENSE_NORMAL_CHOLESKY), early stopping "
       "after 6 validation failures (as MATLAB trainlm)"},
      {"samples",
       {{"train", train.size()},
        {"train_available", n_train_all},
        {"validation", val.size()},
        {"test", test.size()}}},
      {"fit", fit_json(r)},
      {"test_rms", axis_json(axis_rms(n, test), axes)},
      {"validation_rms", axis_json(axis_rms(n, val), axes)}};
  return {std::move(n), std::move(r)};
}

// 001_… §3.1–3.3: zero point from the rotation matrix (45 and 90 leaky-ReLU units, Adam with
// the Table 2 schedule, L2), then the least-squares tool load (eq. 9–14) on the static poses
// minus the zero point. One pose per static dwell: the median of its samples (001_… §4: 200
// samples per posture, the median taken).
NetworkFile train_paper_zp(const ident::Dataset& data, const formats::Log& log,
                           const TrainOptions& o) {
  const std::vector<Dwell> dwells = static_dwells(data, o.usable);
  if (dwells.size() < 10)
    throw std::runtime_error("paper-zp: needs at least 10 static dwells (poses), found " +
                             std::to_string(dwells.size()));
  std::vector<std::size_t> mid;
  std::vector<ident::Wrench> median;
  for (const Dwell& d : dwells) {
    mid.push_back((d.begin + d.end) / 2);
    ident::Wrench w;
    std::vector<double> v;
    for (int a = 0; a < 6; ++a) {
      v.clear();
      for (std::size_t i = d.begin; i < d.end; ++i) v.push_back(data.measured[i][a]);
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
      w[a] = v[v.size() / 2];
    }
    median.push_back(w);
  }
  // Targets indexed like the samples for make_set: a sparse table keyed by the dwell middles.
  std::vector<ident::Wrench> target(data.size(), ident::Wrench::Zero());
  for (std::size_t k = 0; k < mid.size(); ++k) target[mid[k]] = median[k];
  const std::vector<int> axes = {0, 1, 2, 3, 4};
  const TrainingSet train = make_set(data, log, kPaperZpInputs, mid, target, axes);
  NetworkFile n;
  n.kind = NetworkKind::paper_zp;
  n.shape.width = {9, 45, 90, 5};
  n.shape.activation = {Activation::leaky_relu, Activation::leaky_relu, Activation::identity};
  n.normalisation = normalisation_for(train);
  n.inputs = kPaperZpInputs;
  n.output_axes = axes;
  n.seed = o.seed;
  say(o, "paper-zp: " + std::to_string(n.shape.num_params()) + " parameters, " +
             std::to_string(train.size()) + " static poses (dwell medians)");
  AdamOptions adam;
  adam.iterations = o.adam_iterations;
  adam.label = "paper-zp";
  adam.progress = o.progress;
  const NetworkFitResult r =
      fit_adam(n.shape, n.normalisation, train, nullptr, initial_params(n.shape, o.seed), adam);
  n.params = r.params;
  round_to_float(n);
  // Least squares on the static poses minus the (float) zero point; Mz has no zero point.
  std::vector<double> sa(model::kMaxNetworkWidth), sb(model::kMaxNetworkWidth), z(5);
  std::vector<Eigen::Matrix3d> R;
  std::vector<ident::Wrench> rest;
  for (std::size_t k = 0; k < mid.size(); ++k) {
    model::network_forward<double>(n.shape, n.normalisation, n.params.data(), &train.x[k * 9],
                                   z.data(), sa.data(), sb.data());
    ident::Wrench w = median[k];
    for (int a = 0; a < 5; ++a) w[a] -= z[static_cast<std::size_t>(a)];
    R.push_back(data.pose(mid[k]).R_base_sensor);
    rest.push_back(w);
  }
  n.tool_load = tool_load_ls(R, rest);
  say(o, "paper-zp: least-squares tool load " + std::to_string(n.tool_load->mass_kg()) +
             " kg from " + std::to_string(R.size()) + " poses");
  nlohmann::json sched = nlohmann::json::array();
  for (const auto& [from, rate] : paper_zp_schedule(o.adam_iterations))
    sched.push_back({{"from_iteration", from}, {"learning_rate", rate}});
  n.training = {
      {"method",
       "001_… §3.1-3.3: zero-point network (rotation matrix -> Fx Fy Fz Mx My), then "
       "least-squares tool load (eq. 9-14) on the static poses minus the zero point"},
      {"optimiser", "Adam, full batch, L2 " + std::to_string(1e-4) +
                        ", the Table 2 learning-rate schedule scaled from 100,000 to " +
                        std::to_string(o.adam_iterations) + " iterations"},
      {"schedule", sched},
      {"samples", {{"poses", train.size()}, {"note", "one pose per static dwell: median"}}},
      {"fit", fit_json(r)},
      {"train_rms", axis_json(axis_rms(n, train), axes)}};
  return n;
}

NetworkFile train_residual(const ident::Dataset& data, const formats::Log& log,
                           const TrainOptions& o) {
  if (!o.physics)
    throw std::invalid_argument("residual: needs the physics model (--model fit.json)");
  const io::ModelFile& physics = *o.physics;
  ident::check_signals(physics.params.effects, data);
  const int hidden = hidden_or(o, 12);
  std::vector<std::string> signals;
  std::vector<Feature> inputs = o.inputs;
  if (inputs.empty()) {
    say(o, "residual: choosing inputs from the diagnosis of the physics model");
    inputs = inputs_from_diagnosis(data, physics, o.threads, &signals, 0.2, o.progress, o.usable);
  }
  check_feature_signals(inputs, data);
  say(o, "residual: inputs " + feature_list_string(inputs));
  std::vector<ident::Wrench> target(data.size());
  for (std::size_t i = 0; i < data.size(); ++i)
    target[i] = data.measured[i] - ident::predict(physics.params, data, i);
  // Early stopping on time blocks (30 s, every 6th), not on random samples: neighbouring samples
  // share their slow errors, so a random validation set would flatter the network.
  const std::vector<std::uint8_t> vmask = time_block_mask(data, 30.0, 6, 1);
  std::vector<std::size_t> tr, va;
  for (std::size_t i = 0; i < data.size(); ++i) {
    if (o.usable && !(*o.usable)[i]) continue;
    (vmask[i] ? va : tr).push_back(i);
  }
  if (tr.size() < 50 || va.size() < 20)
    throw std::runtime_error("residual: too few samples for training and validation (" +
                             std::to_string(tr.size()) + ", " + std::to_string(va.size()) + ")");
  std::mt19937_64 gen(o.seed);
  const std::size_t n_train_all = tr.size();
  tr = subsample(std::move(tr), static_cast<std::size_t>(o.max_train_samples), gen);
  va = subsample(std::move(va), 20000, gen);
  const std::vector<int> axes = {0, 1, 2, 3, 4, 5};
  const TrainingSet train = make_set(data, log, inputs, tr, target, axes);
  const TrainingSet val = make_set(data, log, inputs, va, target, axes);
  NetworkFile n;
  n.kind = NetworkKind::residual;
  n.shape.width = {static_cast<int>(inputs.size()), hidden, 6};
  n.shape.activation = {Activation::tanh, Activation::identity};
  n.normalisation = normalisation_for(train);
  n.inputs = inputs;
  n.output_axes = axes;
  n.seed = o.seed;
  n.physics = physics;
  say(o, "residual: " + std::to_string(n.shape.num_params()) + " parameters, " +
             std::to_string(train.size()) + " training samples (of " + std::to_string(n_train_all) +
             "), " + std::to_string(val.size()) + " validation");
  LmOptions lm;
  lm.max_iterations = o.max_iterations;
  lm.threads = o.threads;
  lm.label = "residual";
  lm.progress = o.progress;
  const NetworkFitResult r =
      fit_lm(n.shape, n.normalisation, train, &val, initial_params(n.shape, o.seed), lm);
  n.params = r.params;
  round_to_float(n);
  // The physics residual on the validation blocks, before and after the network. An output
  // that does not lower its axis' validation RMS is switched off (weights, bias and mean set to
  // zero, so it outputs exactly 0): the network then never adds noise to an axis it cannot
  // explain.
  std::vector<double> before(6, 0.0);
  for (std::size_t k = 0; k < val.size(); ++k)
    for (std::size_t a = 0; a < 6; ++a) before[a] += val.y[k * 6 + a] * val.y[k * 6 + a];
  for (double& v : before) v = std::sqrt(v / static_cast<double>(val.size()));
  const std::vector<double> after_all = axis_rms(n, val);
  nlohmann::json gated = nlohmann::json::array();
  {
    const int last = n.shape.num_layers() - 1;
    std::size_t offset = 0;
    for (int l = 0; l < last; ++l) offset += static_cast<std::size_t>(n.shape.layer_params(l));
    const auto in = static_cast<std::size_t>(n.shape.width[static_cast<std::size_t>(last)]);
    const auto out = static_cast<std::size_t>(n.shape.width.back());
    for (std::size_t a = 0; a < out; ++a) {
      if (after_all[a] < before[a]) continue;
      for (std::size_t c = 0; c < in; ++c) n.params[offset + a * in + c] = 0.0;
      n.params[offset + out * in + a] = 0.0;
      n.normalisation.output_mean[a] = 0.0;
      gated.push_back(ident::kAxisNames[a]);
    }
  }
  if (!gated.empty())
    say(o, "residual: outputs switched off (no validation gain): " + gated.dump());
  n.training = {
      {"method", "physics model + residual network (one tanh hidden layer)"},
      {"optimiser",
       "Levenberg-Marquardt (Ceres, DENSE_NORMAL_CHOLESKY), early stopping "
       "on time-blocked validation (30 s blocks, every 6th)"},
      {"inputs_from", signals.empty() ? nlohmann::json("--inputs") : nlohmann::json(signals)},
      {"physics_effects", io::effect_list_string(physics.params.effects)},
      {"samples",
       {{"train", train.size()}, {"train_available", n_train_all}, {"validation", val.size()}}},
      {"fit", fit_json(r)},
      {"validation_rms_physics", axis_json(before, axes)},
      {"outputs_switched_off", gated},
      {"validation_rms_physics_plus_network", axis_json(axis_rms(n, val), axes)}};
  return n;
}

}  // namespace

std::vector<Feature> inputs_from_diagnosis(const ident::Dataset& data, const io::ModelFile& physics,
                                           int threads, std::vector<std::string>* signals,
                                           double min_correlation,
                                           std::function<void(const std::string&)> progress,
                                           const std::vector<std::uint8_t>* usable) {
  ident::DiagnoseOptions o;
  // Samples outside `usable` (a test set) are neither fitted nor correlated; the diagnosis then
  // validates on another block of each four than the default test blocks.
  std::vector<std::uint8_t> exclude;
  if (usable) {
    exclude.resize(usable->size());
    for (std::size_t i = 0; i < usable->size(); ++i) exclude[i] = (*usable)[i] ? 0 : 1;
    o.exclude = &exclude;
    o.heldout_offset = 1;
  }
  o.fit.effects = physics.params.effects;
  o.fit.initial = &physics.params;
  o.fit.threads = threads;
  o.fit.covariance = false;
  o.progress = progress;
  const ident::Diagnosis d = ident::diagnose(data, o);
  std::vector<Feature> out;
  for (std::size_t q = 0; q < d.correlated.size(); ++q) {
    const auto& s = d.correlated[q];
    if (q > 0 && std::abs(s.correlation) < min_correlation) break;
    const std::vector<Feature> f = features_for_signal(s.signal);
    bool added = false;
    for (Feature x : f) {
      if (std::find(out.begin(), out.end(), x) != out.end()) continue;
      out.push_back(x);
      added = true;
    }
    if (added && signals) signals->push_back(s.signal);
  }
  if (out.empty())
    throw std::runtime_error(
        "residual: the diagnosis names no signal the residual follows; give --inputs");
  return out;
}

NetworkFile train(const ident::Dataset& data, const formats::Log& log,
                  const TrainOptions& options) {
  check_common(data, log, options);
  const auto t0 = std::chrono::steady_clock::now();
  NetworkFile n;
  switch (options.kind) {
    case NetworkKind::paper_bp:
      n = train_paper_bp(data, log, options).net;
      break;
    case NetworkKind::paper_zp:
      n = train_paper_zp(data, log, options);
      break;
    case NetworkKind::residual:
      n = train_residual(data, log, options);
      break;
  }
  n.training["seconds_total"] =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  n.training["log_samples"] = data.size();
  n.training["usable_samples"] = options.usable
                                     ? std::count(options.usable->begin(), options.usable->end(), 1)
                                     : static_cast<std::ptrdiff_t>(data.size());
  validate(n);
  return n;
}

std::vector<SweepRow> sweep_hidden(const ident::Dataset& data, const formats::Log& log,
                                   const TrainOptions& options, const std::vector<int>& hidden,
                                   int repeats) {
  check_common(data, log, options);
  if (repeats < 1) throw std::invalid_argument("sweep: repeats must be >= 1");
  std::vector<SweepRow> rows;
  for (int h : hidden) {
    SweepRow row;
    row.hidden = h;
    const auto t0 = std::chrono::steady_clock::now();
    for (int r = 0; r < repeats; ++r) {
      TrainOptions o = options;
      o.kind = NetworkKind::paper_bp;
      o.hidden = h;
      o.seed = options.seed + static_cast<std::uint64_t>(r);
      const BpTrained t = train_paper_bp(data, log, o);
      row.validation_mse.push_back(t.fit.validation_mse);
      row.mean += t.fit.validation_mse / repeats;
    }
    row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (options.progress)
      options.progress("sweep: " + std::to_string(h) + " hidden units, mean validation MSE " +
                       std::to_string(row.mean));
    rows.push_back(std::move(row));
  }
  return rows;
}

}  // namespace zerog::learn
