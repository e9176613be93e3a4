// Network fitting: backpropagation against autodiff, Levenberg–Marquardt and Adam on known small
// functions, determinism, the least-squares tool load of 001_… eq. 9–14, and clear errors.
#include <gtest/gtest.h>

#include <ceres/jet.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "zerog/learn/optimise.hpp"
#include "zerog/learn/predict.hpp"
#include "zerog/model/network.hpp"

namespace zerog {
namespace {

using model::Activation;

/// y = sin(2 x0) + 0.5 x1² − 0.3 x0 x1 on [−1, 1]², sampled with a seed.
learn::TrainingSet known_function(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 gen(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  learn::TrainingSet s;
  s.inputs = 2;
  s.outputs = 1;
  for (std::size_t i = 0; i < n; ++i) {
    const double a = u(gen), b = u(gen);
    s.x.push_back(a);
    s.x.push_back(b);
    s.y.push_back(std::sin(2 * a) + 0.5 * b * b - 0.3 * a * b);
  }
  return s;
}

TEST(Optimise, BackpropagationMatchesAutodiffThroughTheForwardPass) {
  model::NetworkShape shape{{3, 5, 4, 2},
                            {Activation::leaky_relu, Activation::tanh, Activation::identity}};
  learn::TrainingSet set;
  set.inputs = 3;
  set.outputs = 2;
  std::mt19937_64 gen(3);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  for (int i = 0; i < 7; ++i) {
    for (int k = 0; k < 3; ++k) set.x.push_back(u(gen));
    for (int k = 0; k < 2; ++k) set.y.push_back(u(gen));
  }
  const auto norm = learn::normalisation_for(set);
  const auto p = learn::initial_params(shape, 5);
  const auto np = static_cast<std::size_t>(shape.num_params());
  const double l2 = 0.01;
  std::vector<double> grad(np);
  const double loss = learn::loss_and_gradient(shape, norm, p, set, l2, grad);
  // The same loss with a ceres::Jet per parameter through model::network_forward.
  using J = ceres::Jet<double, 64>;
  ASSERT_LE(np, 64u);
  std::vector<J> pj(np), sa(model::kMaxNetworkWidth), sb(model::kMaxNetworkWidth), y(2);
  for (std::size_t c = 0; c < np; ++c) pj[c] = J(p[c], static_cast<int>(c));
  J total(0.0);
  for (std::size_t i = 0; i < set.size(); ++i) {
    model::network_forward<J>(shape, norm, pj.data(), &set.x[i * 3], y.data(), sa.data(),
                              sb.data());
    for (std::size_t o = 0; o < 2; ++o) {
      const J e = (y[o] - set.y[i * 2 + o]) / norm.output_scale[o];
      total += e * e;
    }
  }
  total = total / static_cast<double>(set.y.size());
  std::size_t offset = 0;
  for (int l = 0; l < shape.num_layers(); ++l) {
    const auto nw = static_cast<std::size_t>(shape.width[l] * shape.width[l + 1]);
    for (std::size_t q = offset; q < offset + nw; ++q) total += l2 * pj[q] * pj[q];
    offset += static_cast<std::size_t>(shape.layer_params(l));
  }
  EXPECT_NEAR(loss, total.a, 1e-12);
  for (std::size_t c = 0; c < np; ++c)
    EXPECT_NEAR(grad[c], total.v[static_cast<int>(c)], 1e-10) << c;
}

TEST(Optimise, LevenbergMarquardtRecoversAKnownFunction) {
  const auto train = known_function(400, 1);
  const auto val = known_function(200, 2);
  const auto test = known_function(500, 3);
  model::NetworkShape shape{{2, 10, 1}, {Activation::tanh, Activation::identity}};
  const auto norm = learn::normalisation_for(train);
  learn::LmOptions o;
  o.max_iterations = 200;
  const auto r = learn::fit_lm(shape, norm, train, &val, learn::initial_params(shape, 1), o);
  // Output scale is about 0.75: a normalised MSE of 1e-4 is an RMS of about 0.0075.
  EXPECT_LT(r.validation_mse, 1e-4) << r.termination;
  EXPECT_LT(learn::normalised_mse(shape, norm, r.params, test), 2e-4);
  EXPECT_GT(r.iterations, 0);
}

TEST(Optimise, AdamRecoversAKnownFunction) {
  const auto train = known_function(300, 4);
  const auto test = known_function(300, 5);
  model::NetworkShape shape{{2, 16, 16, 1},
                            {Activation::leaky_relu, Activation::leaky_relu, Activation::identity}};
  const auto norm = learn::normalisation_for(train);
  learn::AdamOptions o;
  o.iterations = 3000;
  o.l2 = 1e-6;
  const auto r = learn::fit_adam(shape, norm, train, nullptr, learn::initial_params(shape, 2), o);
  EXPECT_LT(r.train_mse, 5e-3);
  EXPECT_LT(learn::normalised_mse(shape, norm, r.params, test), 1e-2);
  // The schedule is 001_… Table 2 scaled: boundaries at 10 %, 30 %, 50 %.
  const auto s = learn::paper_zp_schedule(3000);
  ASSERT_EQ(s.size(), 4u);
  EXPECT_EQ(s[1].first, 300);
  EXPECT_EQ(s[2].first, 900);
  EXPECT_EQ(s[3].first, 1500);
  EXPECT_DOUBLE_EQ(s[0].second, 0.005);
  EXPECT_DOUBLE_EQ(s[3].second, 0.0001);
}

TEST(Optimise, DeterministicForASeedWhateverTheThreadCount) {
  const auto train = known_function(300, 6);
  const auto val = known_function(100, 7);
  model::NetworkShape shape{{2, 6, 1}, {Activation::sigmoid, Activation::identity}};
  const auto norm = learn::normalisation_for(train);
  // The initial weights, computed here from the standard's mt19937_64 sequence (fixed by the
  // C++ standard, so the same on every platform) and the documented rule: uniform in ±a with
  // Glorot's a = √(6 / (n_in + n_out)), biases zero.
  {
    std::mt19937_64 gen(9);
    const auto uniform = [&gen] { return static_cast<double>(gen() >> 11) * 0x1.0p-52 - 1.0; };
    std::vector<double> expected;
    const auto layer = [&](int n_in, int n_out) {
      const double a = std::sqrt(6.0 / (n_in + n_out));
      for (int k = 0; k < n_in * n_out; ++k) expected.push_back(a * uniform());
      expected.insert(expected.end(), static_cast<std::size_t>(n_out), 0.0);
    };
    layer(2, 6);  // sigmoid
    layer(6, 1);  // identity
    EXPECT_EQ(learn::initial_params(shape, 9), expected);
  }
  EXPECT_NE(learn::initial_params(shape, 9), learn::initial_params(shape, 10));
  learn::LmOptions o;
  o.max_iterations = 30;
  o.threads = 1;
  const auto a = learn::fit_lm(shape, norm, train, &val, learn::initial_params(shape, 9), o);
  o.threads = 2;
  const auto b = learn::fit_lm(shape, norm, train, &val, learn::initial_params(shape, 9), o);
  const auto c = learn::fit_lm(shape, norm, train, &val, learn::initial_params(shape, 9), o);
  EXPECT_EQ(a.params, b.params);  // bitwise
  EXPECT_EQ(b.params, c.params);
  learn::AdamOptions ao;
  ao.iterations = 50;
  const auto d = learn::fit_adam(shape, norm, train, nullptr, learn::initial_params(shape, 9), ao);
  const auto e = learn::fit_adam(shape, norm, train, nullptr, learn::initial_params(shape, 9), ao);
  EXPECT_EQ(d.params, e.params);
}

TEST(Optimise, ToolLoadRecoversMassAndCentreOfGravityOnNoiseFreeStaticPoses) {
  // 001_… eq. 7–8: ˢG_i = R_iᵀ ᴮG, ˢM_i = c × ˢG_i, plus a zero point that the caller subtracts.
  const double mass = 100.0;
  const Eigen::Vector3d cog(0.03, -0.02, 0.25);
  // A slightly tilted base: ᴮG = G (cos α sin β, −sin α, −cos α cos β) (001_… eq. 7).
  const double alpha = 0.004, beta = -0.003, G = mass * 9.80665;
  const Eigen::Vector3d g_base(G * std::cos(alpha) * std::sin(beta), -G * std::sin(alpha),
                               -G * std::cos(alpha) * std::cos(beta));
  std::mt19937_64 gen(11);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  std::vector<Eigen::Matrix3d> R;
  std::vector<ident::Wrench> w;
  for (int i = 0; i < 15; ++i) {  // 15 poses, as 001_… §4.2
    const Eigen::Vector3d rv(u(gen), u(gen), u(gen));
    R.push_back(Eigen::AngleAxisd(rv.norm(), rv.normalized()).toRotationMatrix());
    const Eigen::Vector3d f = R.back().transpose() * g_base;
    ident::Wrench x;
    x << f, cog.cross(f);
    w.push_back(x);
  }
  const learn::ToolLoad t = learn::tool_load_ls(R, w);
  EXPECT_NEAR(t.mass_kg(), mass, 1e-9);
  EXPECT_NEAR((t.gravity_base_N - g_base).norm(), 0.0, 1e-9);
  EXPECT_NEAR((t.cog_sensor_m - cog).norm(), 0.0, 1e-12);
  EXPECT_EQ(t.poses, 15);
  // eq. 15 reproduces the wrench at a new pose.
  const Eigen::Matrix3d Rn =
      Eigen::AngleAxisd(1.1, Eigen::Vector3d(0.3, -1, 0.2).normalized()).toRotationMatrix();
  const Eigen::Vector3d fn = Rn.transpose() * g_base;
  ident::Wrench expect;
  expect << fn, cog.cross(fn);
  EXPECT_NEAR((learn::tool_wrench(t, Rn) - expect).norm(), 0.0, 1e-9);
}

TEST(Optimise, BadInputsGiveClearErrors) {
  const auto train = known_function(50, 1);
  model::NetworkShape shape{{2, 4, 1}, {Activation::tanh, Activation::identity}};
  const auto norm = learn::normalisation_for(train);
  learn::LmOptions o;
  // Wrong number of initial parameters.
  EXPECT_THROW(learn::fit_lm(shape, norm, train, nullptr, std::vector<double>(3), o),
               std::invalid_argument);
  // A set that does not fit the network.
  model::NetworkShape three{{3, 4, 1}, {Activation::tanh, Activation::identity}};
  try {
    learn::fit_lm(three, norm, train, nullptr, learn::initial_params(three, 1), o);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("2 inputs"), std::string::npos) << e.what();
  }
  // Too many parameters for Levenberg–Marquardt.
  model::NetworkShape big{{2, 128, 128, 1},
                          {Activation::tanh, Activation::tanh, Activation::identity}};
  try {
    learn::fit_lm(big, norm, train, nullptr, learn::initial_params(big, 1), o);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("at most 1024 parameters"), std::string::npos);
  }
  EXPECT_THROW(learn::normalisation_for(learn::TrainingSet{}), std::invalid_argument);
  // Tool load: too few poses; all poses alike (gravity undetermined).
  std::vector<Eigen::Matrix3d> R(2, Eigen::Matrix3d::Identity());
  std::vector<ident::Wrench> w(2, ident::Wrench::Ones());
  EXPECT_THROW(learn::tool_load_ls(R, w), std::invalid_argument);
  // One attitude only: the gravity is determined, the centre of gravity along it is not.
  R.assign(5, Eigen::Matrix3d::Identity());
  w.assign(5, ident::Wrench::Ones());
  try {
    learn::tool_load_ls(R, w);
    FAIL() << "no exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("centre of gravity"), std::string::npos);
  }
  // No tool at all.
  R.clear();
  for (double a : {0.0, 1.0, 2.0, 3.0})
    R.push_back(Eigen::AngleAxisd(a, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix());
  w.assign(4, ident::Wrench::Zero());
  EXPECT_THROW(learn::tool_load_ls(R, w), std::invalid_argument);
}

}  // namespace
}  // namespace zerog
