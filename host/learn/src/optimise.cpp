#include "zerog/learn/optimise.hpp"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <thread>

namespace zerog::learn {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

std::string fmt(const char* f, double a, double b = 0, double c = 0) {
  char buf[256];
  std::snprintf(buf, sizeof buf, f, a, b, c);
  return buf;
}

/// Runs fn(begin, end) on `threads` static, contiguous ranges of [0, n): each range is the same
/// whatever the timing, so results do not depend on the schedule.
template <typename Fn>
void parallel_ranges(std::size_t n, int threads, Fn fn) {
  const auto t = static_cast<std::size_t>(std::max(1, threads));
  if (t == 1 || n < 2 * t) {
    fn(std::size_t{0}, n);
    return;
  }
  std::vector<std::thread> pool;
  const std::size_t chunk = (n + t - 1) / t;
  for (std::size_t k = 1; k < t; ++k) {
    const std::size_t b = std::min(n, k * chunk), e = std::min(n, (k + 1) * chunk);
    pool.emplace_back([&fn, b, e] { fn(b, e); });
  }
  fn(std::size_t{0}, std::min(n, chunk));
  for (auto& th : pool) th.join();
}

double derivative_from_output(model::Activation a, double y) {
  switch (a) {
    case model::Activation::sigmoid:
      return y * (1.0 - y);
    case model::Activation::tanh:
      return 1.0 - y * y;
    case model::Activation::leaky_relu:
      return y > 0.0 ? 1.0 : 0.01;
    case model::Activation::identity:
      break;
  }
  return 1.0;
}

/// Layer l alone as a network with identity normalisation: network_forward on it maps the
/// activations of layer l − 1 to those of layer l. Backpropagation needs every layer's
/// activations; this keeps model::network_forward the one forward pass. Entry 0 is the
/// zero-layer network with the real input normalisation: it returns the normalised inputs.
struct LayerNet {
  model::NetworkShape shape;
  model::NetworkNormalisation norm;
  std::size_t offset = 0;  ///< of the layer's parameters in the whole network's
};
std::vector<LayerNet> layer_nets(const model::NetworkShape& shape,
                                 const model::NetworkNormalisation& norm) {
  std::vector<LayerNet> out(static_cast<std::size_t>(shape.num_layers()) + 1);
  out[0].shape.width = {shape.width.front()};
  out[0].norm.input_mean = norm.input_mean;
  out[0].norm.input_scale = norm.input_scale;
  out[0].norm.output_mean.assign(norm.input_mean.size(), 0.0);
  out[0].norm.output_scale.assign(norm.input_mean.size(), 1.0);
  std::size_t offset = 0;
  for (int l = 0; l < shape.num_layers(); ++l) {
    LayerNet& n = out[static_cast<std::size_t>(l) + 1];
    const int in = shape.width[static_cast<std::size_t>(l)];
    const int m = shape.width[static_cast<std::size_t>(l) + 1];
    n.shape.width = {in, m};
    n.shape.activation = {shape.activation[static_cast<std::size_t>(l)]};
    n.norm.input_mean.assign(static_cast<std::size_t>(in), 0.0);
    n.norm.input_scale.assign(static_cast<std::size_t>(in), 1.0);
    n.norm.output_mean.assign(static_cast<std::size_t>(m), 0.0);
    n.norm.output_scale.assign(static_cast<std::size_t>(m), 1.0);
    n.offset = offset;
    offset += static_cast<std::size_t>(shape.layer_params(l));
  }
  return out;
}

void check_set(const model::NetworkShape& shape, const model::NetworkNormalisation& norm,
               const TrainingSet& set, const char* what) {
  if (set.inputs != shape.width.front() || set.outputs != shape.width.back())
    throw std::invalid_argument(std::string(what) + " set has " + std::to_string(set.inputs) +
                                " inputs and " + std::to_string(set.outputs) +
                                " outputs; the network " + std::to_string(shape.width.front()) +
                                " and " + std::to_string(shape.width.back()));
  if (set.size() == 0) throw std::invalid_argument(std::string(what) + " set is empty");
  if (set.y.size() != set.size() * static_cast<std::size_t>(set.outputs))
    throw std::invalid_argument(std::string(what) + " set: targets and inputs differ in count");
  if (norm.input_mean.size() != static_cast<std::size_t>(set.inputs) ||
      norm.output_mean.size() != static_cast<std::size_t>(set.outputs))
    throw std::invalid_argument("normalisation does not fit the network");
}

/// Normalised residuals of every sample and output, and their Jacobian with respect to the
/// parameters by forward-mode autodiff: model::network_forward on ceres::Jet<double, N>, each
/// parameter seeded with its own derivative direction (N ≥ number of parameters). One residual
/// block for the whole set: the samples are split over threads here, in fixed ranges.
template <int N>
class NetworkCost final : public ceres::CostFunction {
 public:
  NetworkCost(const model::NetworkShape& shape, const model::NetworkNormalisation& norm,
              const TrainingSet& set, int threads)
      : shape_(shape), norm_(norm), set_(set), threads_(threads) {
    set_num_residuals(static_cast<int>(set.size()) * set.outputs);
    mutable_parameter_block_sizes()->push_back(shape.num_params());
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const double* p = parameters[0];
    const int np = shape_.num_params();
    const auto k = static_cast<std::size_t>(set_.outputs);
    const auto d = static_cast<std::size_t>(set_.inputs);
    double* jac = jacobians ? jacobians[0] : nullptr;
    parallel_ranges(set_.size(), threads_, [&](std::size_t begin, std::size_t end) {
      if (jac == nullptr) {
        std::vector<double> sa(model::kMaxNetworkWidth), sb(model::kMaxNetworkWidth), y(k);
        for (std::size_t i = begin; i < end; ++i) {
          model::network_forward<double>(shape_, norm_, p, &set_.x[i * d], y.data(), sa.data(),
                                         sb.data());
          for (std::size_t o = 0; o < k; ++o)
            residuals[i * k + o] = (y[o] - set_.y[i * k + o]) / norm_.output_scale[o];
        }
        return;
      }
      using J = ceres::Jet<double, N>;
      std::vector<J> pj(static_cast<std::size_t>(np)), sa(model::kMaxNetworkWidth),
          sb(model::kMaxNetworkWidth), y(k);
      for (int c = 0; c < np; ++c) pj[static_cast<std::size_t>(c)] = J(p[c], c);
      for (std::size_t i = begin; i < end; ++i) {
        model::network_forward<J>(shape_, norm_, pj.data(), &set_.x[i * d], y.data(), sa.data(),
                                  sb.data());
        for (std::size_t o = 0; o < k; ++o) {
          const double s = norm_.output_scale[o];
          const std::size_t r = i * k + o;
          residuals[r] = (y[o].a - set_.y[r]) / s;
          double* row = jac + r * static_cast<std::size_t>(np);
          // Guard: a non-finite derivative (model::activate is written to avoid them) is taken
          // as 0, so one wild trial step cannot end the training.
          for (int c = 0; c < np; ++c) row[c] = std::isfinite(y[o].v[c]) ? y[o].v[c] / s : 0.0;
        }
      }
    });
    return true;
  }

 private:
  const model::NetworkShape& shape_;
  const model::NetworkNormalisation& norm_;
  const TrainingSet& set_;
  int threads_;
};

ceres::CostFunction* make_cost(const model::NetworkShape& shape,
                               const model::NetworkNormalisation& norm, const TrainingSet& set,
                               int threads) {
  const int np = shape.num_params();
  if (np <= 64) return new NetworkCost<64>(shape, norm, set, threads);
  if (np <= 128) return new NetworkCost<128>(shape, norm, set, threads);
  if (np <= 256) return new NetworkCost<256>(shape, norm, set, threads);
  if (np <= 512) return new NetworkCost<512>(shape, norm, set, threads);
  if (np <= 1024) return new NetworkCost<1024>(shape, norm, set, threads);
  throw std::invalid_argument(
      "Levenberg-Marquardt training handles at most 1024 parameters; "
      "this network has " +
      std::to_string(np) + " (use fewer hidden units)");
}

/// Early stopping on the validation set (MATLAB trainlm's max_fail), and progress lines.
class EarlyStopping final : public ceres::IterationCallback {
 public:
  EarlyStopping(const model::NetworkShape& shape, const model::NetworkNormalisation& norm,
                const TrainingSet& train, const TrainingSet* validation, const double* params,
                const LmOptions& o)
      : shape_(shape), norm_(norm), train_(train), validation_(validation), params_(params), o_(o) {
    best_.assign(params, params + shape.num_params());
  }

  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    const auto np = static_cast<std::size_t>(shape_.num_params());
    const double train_mse = 2.0 * s.cost / static_cast<double>(train_.y.size());
    if (!validation_) {
      best_.assign(params_, params_ + np);
      best_iteration_ = s.iteration;
      report(s, train_mse, std::nan(""));
      return ceres::SOLVER_CONTINUE;
    }
    if (s.iteration > 0 && !s.step_is_successful) return ceres::SOLVER_CONTINUE;
    const double v =
        normalised_mse(shape_, norm_, std::span<const double>(params_, np), *validation_);
    if (v < best_validation_) {
      best_validation_ = v;
      best_.assign(params_, params_ + np);
      best_iteration_ = s.iteration;
      fails_ = 0;
    } else {
      ++fails_;
    }
    report(s, train_mse, v);
    if (fails_ >= o_.patience) {
      stopped_ = true;
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    }
    return ceres::SOLVER_CONTINUE;
  }

  const std::vector<double>& best() const { return best_; }
  double best_validation() const { return best_validation_; }
  int best_iteration() const { return best_iteration_; }
  bool stopped() const { return stopped_; }

 private:
  void report(const ceres::IterationSummary& s, double train_mse, double val_mse) const {
    if (!o_.progress) return;
    if (s.iteration % 5 != 0 && !(validation_ && fails_ == 0)) return;
    o_.progress(o_.label + ": iteration " + std::to_string(s.iteration) +
                fmt(", train MSE %.4g, validation MSE %.4g (normalised), %.1f s", train_mse,
                    val_mse, s.cumulative_time_in_seconds));
  }

  const model::NetworkShape& shape_;
  const model::NetworkNormalisation& norm_;
  const TrainingSet& train_;
  const TrainingSet* validation_;
  const double* params_;
  const LmOptions& o_;
  std::vector<double> best_;
  double best_validation_ = std::numeric_limits<double>::infinity();
  int best_iteration_ = 0;
  int fails_ = 0;
  bool stopped_ = false;
};

}  // namespace

model::NetworkNormalisation normalisation_for(const TrainingSet& set) {
  const std::size_t n = set.size();
  if (n == 0) throw std::invalid_argument("cannot normalise an empty training set");
  auto stats = [n](const std::vector<double>& v, int width, std::vector<double>& mean,
                   std::vector<double>& scale) {
    const auto w = static_cast<std::size_t>(width);
    mean.assign(w, 0.0);
    scale.assign(w, 0.0);
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t c = 0; c < w; ++c) mean[c] += v[i * w + c];
    for (double& m : mean) m /= static_cast<double>(n);
    for (std::size_t i = 0; i < n; ++i)
      for (std::size_t c = 0; c < w; ++c) scale[c] += std::pow(v[i * w + c] - mean[c], 2);
    for (double& s : scale) {
      s = std::sqrt(s / static_cast<double>(n));
      if (!(s > 1e-12)) s = 1.0;
    }
  };
  model::NetworkNormalisation z;
  stats(set.x, set.inputs, z.input_mean, z.input_scale);
  stats(set.y, set.outputs, z.output_mean, z.output_scale);
  return z;
}

std::vector<double> initial_params(const model::NetworkShape& shape, std::uint64_t seed) {
  std::mt19937_64 gen(seed);
  // 53 random bits to [−1, 1): the mapping is ours, so identical on every platform.
  auto uniform = [&gen] { return static_cast<double>(gen() >> 11) * 0x1.0p-52 - 1.0; };
  std::vector<double> p;
  p.reserve(static_cast<std::size_t>(shape.num_params()));
  for (int l = 0; l < shape.num_layers(); ++l) {
    const int n = shape.width[static_cast<std::size_t>(l)];
    const int m = shape.width[static_cast<std::size_t>(l) + 1];
    const double a = shape.activation[static_cast<std::size_t>(l)] == model::Activation::leaky_relu
                         ? std::sqrt(6.0 / n)
                         : std::sqrt(6.0 / (n + m));
    for (int k = 0; k < m * n; ++k) p.push_back(a * uniform());
    for (int k = 0; k < m; ++k) p.push_back(0.0);
  }
  return p;
}

double normalised_mse(const model::NetworkShape& shape, const model::NetworkNormalisation& norm,
                      std::span<const double> params, const TrainingSet& set) {
  check_set(shape, norm, set, "evaluation");
  const auto k = static_cast<std::size_t>(set.outputs);
  const auto d = static_cast<std::size_t>(set.inputs);
  std::vector<double> sa(model::kMaxNetworkWidth), sb(model::kMaxNetworkWidth), y(k);
  double ss = 0.0;
  for (std::size_t i = 0; i < set.size(); ++i) {
    model::network_forward<double>(shape, norm, params.data(), &set.x[i * d], y.data(), sa.data(),
                                   sb.data());
    for (std::size_t o = 0; o < k; ++o)
      ss += std::pow((y[o] - set.y[i * k + o]) / norm.output_scale[o], 2);
  }
  return ss / static_cast<double>(set.y.size());
}

double loss_and_gradient(const model::NetworkShape& shape, const model::NetworkNormalisation& norm,
                         std::span<const double> params, const TrainingSet& set, double l2,
                         std::span<double> grad) {
  check_set(shape, norm, set, "training");
  const int L = shape.num_layers();
  const auto np = static_cast<std::size_t>(shape.num_params());
  if (params.size() != np || grad.size() != np)
    throw std::invalid_argument("loss_and_gradient: parameter count does not fit the network");
  const std::vector<LayerNet> layers = layer_nets(shape, norm);
  const auto k = static_cast<std::size_t>(set.outputs);
  const auto d = static_cast<std::size_t>(set.inputs);
  const double scale = 2.0 / static_cast<double>(set.y.size());
  // Two fixed halves of the samples, each with its own gradient, summed in a fixed order.
  constexpr int kParts = 2;
  std::array<std::vector<double>, kParts> g;
  std::array<double, kParts> ss{};
  auto part = [&](int q, std::size_t begin, std::size_t end) {
    std::vector<double>& gq = g[static_cast<std::size_t>(q)];
    gq.assign(np, 0.0);
    // act[l]: activations after layer l (act[0]: the normalised inputs).
    std::vector<std::vector<double>> act(static_cast<std::size_t>(L) + 1,
                                         std::vector<double>(model::kMaxNetworkWidth));
    std::vector<double> sa(model::kMaxNetworkWidth), sb(model::kMaxNetworkWidth);
    std::vector<double> delta(model::kMaxNetworkWidth), delta_prev(model::kMaxNetworkWidth);
    for (std::size_t i = begin; i < end; ++i) {
      model::network_forward<double>(layers[0].shape, layers[0].norm, params.data(), &set.x[i * d],
                                     act[0].data(), sa.data(), sb.data());
      for (std::size_t l = 1; l <= static_cast<std::size_t>(L); ++l)
        model::network_forward<double>(layers[l].shape, layers[l].norm,
                                       params.data() + layers[l].offset, act[l - 1].data(),
                                       act[l].data(), sa.data(), sb.data());
      // Output error in normalised units: the last activations are ŷ_n, the target (y − mean)
      // / scale.
      const std::vector<double>& out = act[static_cast<std::size_t>(L)];
      for (std::size_t o = 0; o < k; ++o) {
        const double e = out[o] - (set.y[i * k + o] - norm.output_mean[o]) / norm.output_scale[o];
        ss[static_cast<std::size_t>(q)] += e * e;
        delta[o] =
            scale * e *
            derivative_from_output(shape.activation[static_cast<std::size_t>(L) - 1], out[o]);
      }
      for (std::size_t l = static_cast<std::size_t>(L); l >= 1; --l) {
        const auto n = static_cast<std::size_t>(layers[l].shape.width[0]);
        const auto m = static_cast<std::size_t>(layers[l].shape.width[1]);
        const std::vector<double>& in = act[l - 1];
        const double* W = params.data() + layers[l].offset;
        double* gW = gq.data() + layers[l].offset;
        double* gb = gW + m * n;
        for (std::size_t r = 0; r < m; ++r) {
          gb[r] += delta[r];
          for (std::size_t c = 0; c < n; ++c) gW[r * n + c] += delta[r] * in[c];
        }
        if (l == 1) break;
        const model::Activation a = shape.activation[l - 2];
        for (std::size_t c = 0; c < n; ++c) delta_prev[c] = 0.0;
        for (std::size_t r = 0; r < m; ++r)
          for (std::size_t c = 0; c < n; ++c) delta_prev[c] += W[r * n + c] * delta[r];
        for (std::size_t c = 0; c < n; ++c) delta_prev[c] *= derivative_from_output(a, in[c]);
        std::swap(delta, delta_prev);
      }
    }
  };
  const std::size_t half = set.size() / 2;
  std::thread other(part, 1, half, set.size());
  part(0, 0, half);
  other.join();
  double reg = 0.0;
  for (std::size_t q = 0; q < np; ++q) grad[q] = g[0][q] + g[1][q];
  for (std::size_t l = 1; l <= static_cast<std::size_t>(L); ++l) {
    const auto nw = static_cast<std::size_t>(layers[l].shape.width[0] * layers[l].shape.width[1]);
    for (std::size_t q = layers[l].offset; q < layers[l].offset + nw; ++q) {
      reg += params[q] * params[q];
      grad[q] += 2.0 * l2 * params[q];
    }
  }
  return (ss[0] + ss[1]) / static_cast<double>(set.y.size()) + l2 * reg;
}

NetworkFitResult fit_lm(const model::NetworkShape& shape, const model::NetworkNormalisation& norm,
                        const TrainingSet& train, const TrainingSet* validation,
                        std::vector<double> initial, const LmOptions& options) {
  check_set(shape, norm, train, "training");
  if (validation) check_set(shape, norm, *validation, "validation");
  if (initial.size() != static_cast<std::size_t>(shape.num_params()))
    throw std::invalid_argument("fit_lm: initial parameters do not fit the network");
  if (options.max_iterations < 1) throw std::invalid_argument("fit_lm: max_iterations < 1");
  const auto t0 = Clock::now();
  NetworkFitResult r;
  std::vector<double> p = std::move(initial);
  ceres::Problem problem;
  problem.AddResidualBlock(make_cost(shape, norm, train, options.threads), nullptr, p.data());
  EarlyStopping stop(shape, norm, train, validation, p.data(), options);
  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  // J is (samples × outputs) × parameters, dense; JᵀJ is small (≤ 1024²), so the normal
  // equations are the cheap way; LM's damping keeps them well conditioned.
  so.linear_solver_type = ceres::DENSE_NORMAL_CHOLESKY;
  so.max_num_iterations = options.max_iterations;
  so.num_threads = 1;  // the cost function parallelises itself over fixed sample ranges
  so.function_tolerance = 1e-9;
  so.gradient_tolerance = 1e-12;
  so.parameter_tolerance = 1e-10;
  so.logging_type = ceres::SILENT;
  so.update_state_every_iteration = true;
  so.callbacks.push_back(&stop);
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  if (!summary.IsSolutionUsable())
    throw std::runtime_error(options.label + ": Levenberg-Marquardt failed: " + summary.message);
  r.params = stop.best();
  r.iterations = static_cast<int>(summary.iterations.size()) - 1;
  r.best_iteration = stop.best_iteration();
  r.termination = stop.stopped() ? "validation error stopped falling (" +
                                       std::to_string(options.patience) + " steps)"
                                 : ceres::TerminationTypeToString(summary.termination_type) +
                                       std::string(": ") + summary.message;
  r.train_mse = normalised_mse(shape, norm, r.params, train);
  if (validation) r.validation_mse = stop.best_validation();
  r.seconds = seconds_since(t0);
  return r;
}

std::vector<std::pair<int, double>> paper_zp_schedule(int iterations) {
  // 001_… Table 2 over 100,000 iterations: 0–10k 0.005, 10k–30k 0.001, 30k–50k 0.0005,
  // 50k–100k 0.0001.
  auto at = [iterations](int paper_iteration) {
    return static_cast<int>(static_cast<long long>(paper_iteration) * iterations / 100000);
  };
  return {{0, 0.005}, {at(10000), 0.001}, {at(30000), 0.0005}, {at(50000), 0.0001}};
}

// Adam (Kingma & Ba 2015) is 001_…'s optimiser (PyTorch there). No Debian C++ package offers it
// (Ceres has LM, dogleg and line searches only), and the update is ten lines, so it lives here.
NetworkFitResult fit_adam(const model::NetworkShape& shape, const model::NetworkNormalisation& norm,
                          const TrainingSet& train, const TrainingSet* validation,
                          std::vector<double> initial, const AdamOptions& options) {
  check_set(shape, norm, train, "training");
  if (validation) check_set(shape, norm, *validation, "validation");
  const auto np = static_cast<std::size_t>(shape.num_params());
  if (initial.size() != np) throw std::invalid_argument("fit_adam: initial parameters do not fit");
  if (options.iterations < 1) throw std::invalid_argument("fit_adam: iterations < 1");
  const auto schedule =
      options.schedule.empty() ? paper_zp_schedule(options.iterations) : options.schedule;
  const auto t0 = Clock::now();
  std::vector<double> p = std::move(initial), g(np), m(np, 0.0), v(np, 0.0);
  double b1t = 1.0, b2t = 1.0, loss = 0.0;
  for (int it = 0; it < options.iterations; ++it) {
    double lr = schedule.front().second;
    for (const auto& [from, rate] : schedule)
      if (it >= from) lr = rate;
    loss = loss_and_gradient(shape, norm, p, train, options.l2, g);
    b1t *= options.beta1;
    b2t *= options.beta2;
    for (std::size_t q = 0; q < np; ++q) {
      m[q] = options.beta1 * m[q] + (1.0 - options.beta1) * g[q];
      v[q] = options.beta2 * v[q] + (1.0 - options.beta2) * g[q] * g[q];
      const double mh = m[q] / (1.0 - b1t), vh = v[q] / (1.0 - b2t);
      p[q] -= lr * mh / (std::sqrt(vh) + options.epsilon);
    }
    if (options.progress && (it % 1000 == 0 || it + 1 == options.iterations))
      options.progress(options.label + ": iteration " + std::to_string(it) +
                       fmt(", learning rate %.4g, loss %.4g (normalised MSE + L2), %.1f s", lr,
                           loss, seconds_since(t0)));
  }
  NetworkFitResult r;
  r.params = std::move(p);
  r.iterations = options.iterations;
  r.best_iteration = options.iterations;
  r.termination = "ran the scheduled " + std::to_string(options.iterations) + " iterations";
  r.train_mse = normalised_mse(shape, norm, r.params, train);
  if (validation) r.validation_mse = normalised_mse(shape, norm, r.params, *validation);
  r.seconds = seconds_since(t0);
  return r;
}

ToolLoad tool_load_ls(std::span<const Eigen::Matrix3d> R_base_sensor,
                      std::span<const ident::Wrench> wrench) {
  const std::size_t n = R_base_sensor.size();
  if (n != wrench.size())
    throw std::invalid_argument("tool load: attitudes and wrenches differ in count");
  if (n < 3)
    throw std::invalid_argument("tool load: needs at least 3 static poses, got " +
                                std::to_string(n));
  const auto rows = static_cast<Eigen::Index>(3 * n);
  // eq. 9: ˢG = R ᴮG, R stacking R_base_sensor,iᵀ.
  Eigen::MatrixXd R(rows, 3), A(rows, 3);
  Eigen::VectorXd G(rows), M(rows);
  for (std::size_t i = 0; i < n; ++i) {
    const auto r0 = static_cast<Eigen::Index>(3 * i);
    R.block<3, 3>(r0, 0) = R_base_sensor[i].transpose();
    G.segment<3>(r0) = wrench[i].head<3>();
    M.segment<3>(r0) = wrench[i].tail<3>();
  }
  const Eigen::Matrix3d RtR = R.transpose() * R;
  Eigen::LDLT<Eigen::Matrix3d> ldlt_g(RtR);
  if (ldlt_g.info() != Eigen::Success || std::abs(RtR.determinant()) < 1e-9)
    throw std::invalid_argument("tool load: the poses do not determine the gravity (eq. 13)");
  ToolLoad t;
  t.poses = static_cast<int>(n);
  t.gravity_base_N = ldlt_g.solve(R.transpose() * G);  // eq. 13
  // eq. 8 and 10: ˢM_i = A_i r with A_i the cross-product matrix of ˢG_i = R_iᵀ ᴮG*.
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d g = R_base_sensor[i].transpose() * t.gravity_base_N;
    const auto r0 = static_cast<Eigen::Index>(3 * i);
    A.block<3, 3>(r0, 0) << 0, g.z(), -g.y(), -g.z(), 0, g.x(), g.y(), -g.x(), 0;
  }
  const Eigen::Matrix3d AtA = A.transpose() * A;
  const double tr = AtA.trace();
  if (!(tr > 1e-12) || !(std::abs(AtA.determinant()) > 1e-9 * tr * tr * tr))
    throw std::invalid_argument(
        "tool load: the centre of gravity is not determined (eq. 14): the tool gravity is "
        "(nearly) zero or the poses do not turn it enough");
  t.cog_sensor_m = AtA.ldlt().solve(A.transpose() * M);  // eq. 14
  return t;
}

}  // namespace zerog::learn
