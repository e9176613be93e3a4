#include "zerog/model/predict.hpp"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

namespace zerog::model {
namespace {

ModelParams payload(EffectSet effects) {
  ModelParams p;
  p.effects = effects;
  double* b = p.block(Effect::bias);
  b[0] = 10, b[1] = -5, b[2] = 3, b[3] = 0.5, b[4] = -0.2, b[5] = 0.1;
  double* g = p.block(Effect::gravity);
  g[0] = 100.0, g[1] = 0.03, g[2] = -0.02, g[3] = 0.25;
  double* I = p.block(Effect::rotational_inertia);
  I[0] = 4.0, I[1] = 3.0, I[2] = 2.0, I[3] = 0.1, I[4] = -0.05, I[5] = 0.02;
  return p;
}

Wrench<double> eval(const ModelParams& p, const PoseSignals& pose, const ImuSignals<double>& imu,
                    const RigGeometry& rig = {}) {
  return predict_wrench<double>(p.effects, pointers(p), pose, imu, rig);
}

TEST(Predict, BiasOnlyIsConstant) {
  ModelParams p = payload({Effect::bias});
  PoseSignals pose;
  pose.R_base_sensor = rot_x(0.7) * rot_y(-0.3);
  const Wrench<double> w = eval(p, pose, {});
  for (int k = 0; k < 6; ++k) EXPECT_DOUBLE_EQ(w[k], p.block(Effect::bias)[k]);
}

TEST(Predict, GravityStaticMatchesHandComputation) {
  ModelParams p = payload({Effect::gravity});
  PoseSignals pose;  // sensor axes = base axes: gravity along −z of S
  const Wrench<double> w = eval(p, pose, {});
  const Eigen::Vector3d F(0, 0, -100.0 * kStandardGravity);
  const Eigen::Vector3d c(0.03, -0.02, 0.25);
  EXPECT_NEAR((w.head<3>() - F).norm(), 0.0, 1e-9);
  EXPECT_NEAR((w.tail<3>() - c.cross(F)).norm(), 0.0, 1e-9);
  // Upside down: gravity along +z of S.
  pose.R_base_sensor = rot_x(M_PI);
  EXPECT_NEAR(eval(p, pose, {})[2], 100.0 * kStandardGravity, 1e-9);
}

TEST(Predict, LinearInertiaAtRestEqualsGravityFromPose) {
  // At rest the accelerometer reads −g in its own frame: both routes must agree, including an
  // IMU that is rotated and offset from the sensor (lever arm irrelevant at rest).
  PoseSignals pose;
  pose.R_base_sensor = rot_z(0.4) * rot_y(1.1) * rot_x(-0.6);
  RigGeometry rig;
  rig.R_sensor_imu = rot_z(M_PI / 2) * rot_x(0.1);
  rig.p_sensor_imu_m = Eigen::Vector3d(0.05, 0.0, -0.04);
  const Eigen::Vector3d g_S =
      pose.R_base_sensor.transpose() * Eigen::Vector3d(0, 0, -kStandardGravity);
  ImuSignals<double> imu;
  imu.specific_force_imu = -(rig.R_sensor_imu.transpose() * g_S);
  const Wrench<double> from_pose = eval(payload({Effect::gravity}), pose, imu, rig);
  const Wrench<double> from_imu =
      eval(payload({Effect::gravity, Effect::linear_inertia}), pose, imu, rig);
  // Both against the hand computation (000_… eq. 2–3), not only against each other.
  const Eigen::Vector3d F = 100.0 * g_S;
  const Eigen::Vector3d c(0.03, -0.02, 0.25);
  for (const Wrench<double>& w : {from_pose, from_imu}) {
    EXPECT_NEAR((w.head<3>() - F).norm(), 0.0, 1e-9);
    EXPECT_NEAR((w.tail<3>() - c.cross(F)).norm(), 0.0, 1e-9);
  }
}

TEST(Predict, LinearInertiaAddsCentripetalTermAtTheCentreOfMass) {
  // Pure spin about the sensor z axis at rate w, IMU at the sensor origin, no gravity in the
  // accelerometer (free fall): the centre of mass needs m w² r towards the axis.
  ModelParams p = payload({Effect::gravity, Effect::linear_inertia});
  ImuSignals<double> imu;
  imu.angular_rate_imu = Eigen::Vector3d(0, 0, 2.0);
  const Wrench<double> w = eval(p, {}, imu);
  const Eigen::Vector3d r(0.03, -0.02, 0.0);  // c projected off the axis
  EXPECT_NEAR((w.head<3>() - 100.0 * 4.0 * r).norm(), 0.0, 1e-9);
}

TEST(Predict, RotationalInertiaIncludesGyroscopicTerm) {
  ModelParams p = payload({Effect::gravity, Effect::linear_inertia, Effect::rotational_inertia});
  ModelParams q = payload({Effect::gravity, Effect::linear_inertia});
  ImuSignals<double> imu;
  imu.angular_rate_imu = Eigen::Vector3d(0.5, -0.3, 0.8);
  imu.angular_accel_imu = Eigen::Vector3d(1.0, 2.0, -0.5);
  const Wrench<double> diff = eval(p, {}, imu) - eval(q, {}, imu);
  Eigen::Matrix3d I;
  I << 4.0, 0.1, -0.05, 0.1, 3.0, 0.02, -0.05, 0.02, 2.0;
  const Eigen::Vector3d w = imu.angular_rate_imu, wd = imu.angular_accel_imu;
  EXPECT_NEAR((diff.tail<3>() + I * wd + w.cross(I * w)).norm(), 0.0, 1e-12);
  EXPECT_NEAR(diff.head<3>().norm(), 0.0, 1e-12);
}

TEST(Predict, BaseTiltTurnsGravityAsPaperEquation5) {
  ModelParams p = payload({Effect::gravity, Effect::base_tilt});
  const double alpha = 0.004, beta = -0.003;
  p.block(Effect::base_tilt)[0] = alpha;
  p.block(Effect::base_tilt)[1] = beta;
  // 001_… eq. 7: gravity in B is G (cos a sin b, −sin a, −cos a cos b) with G along −z_W.
  const double G = 100.0 * kStandardGravity;
  const Eigen::Vector3d expected(G * std::cos(alpha) * std::sin(beta), -G * std::sin(alpha),
                                 -G * std::cos(alpha) * std::cos(beta));
  const Wrench<double> w = eval(p, {}, {});
  EXPECT_NEAR((w.head<3>() - expected).norm(), 0.0, 1e-9);
}

TEST(Predict, SensorRotationRotatesGravityIntoTheTrueFrame) {
  ModelParams p = payload({Effect::gravity, Effect::sensor_rotation});
  p.block(Effect::sensor_rotation)[0] = 0.01;
  const Wrench<double> w = eval(p, {}, {});
  // True S = nominal S rotated by Rx(0.01): gravity in true S is Rx(0.01)^T (0,0,−g).
  const Eigen::Vector3d expected =
      rot_x(0.01).transpose() * Eigen::Vector3d(0, 0, -100 * kStandardGravity);
  EXPECT_NEAR((w.head<3>() - expected).norm(), 0.0, 1e-9);
}

TEST(Predict, DriftTemperatureCrosstalkAndCable) {
  ModelParams p = payload({Effect::gravity, Effect::crosstalk, Effect::bias_drift,
                           Effect::temperature_bias, Effect::cable});
  p.block(Effect::crosstalk)[0 * 6 + 1] = 0.01;  // Fx picks up 1 % of Fy
  p.block(Effect::bias_drift)[2] = 0.002;        // Fz drifts 2 mN/s
  p.block(Effect::temperature_bias)[5] = 0.1;    // Mz: 0.1 N·m/K
  p.block(Effect::cable)[2 * 12 + 6 + 1] = 3.0;  // A6 sine → Fy, 3 N
  PoseSignals pose;
  pose.R_base_sensor = rot_x(M_PI / 2);  // gravity along sensor −y: R^T (0,0,−g) = (0,−g,0)
  pose.t_rel_s = 100.0;
  pose.temperature_C = 30.0;
  pose.joints_rad[5] = M_PI / 2;
  const Wrench<double> w = eval(p, pose, {});
  // By hand, not by the model: the payload's weight F = m g_S and M = c × F (000_… eq. 2–3) …
  const Eigen::Vector3d F(0.0, -100.0 * kStandardGravity, 0.0);
  Wrench<double> base;
  base << F, Eigen::Vector3d(0.03, -0.02, 0.25).cross(F);
  // … then each effect's term.
  base[1] += 3.0;  // cable acts on the sensor, so it also sees the crosstalk
  const double fy = base[1];
  base[0] += 0.01 * fy;
  base[2] += 0.2;
  base[5] += 0.5;
  EXPECT_NEAR((w - base).norm(), 0.0, 1e-9);
}

TEST(Predict, AutodiffDerivativeOfForceWithRespectToMassIsGravity) {
  using J = ceres::Jet<double, 1>;
  ModelParams p = payload({Effect::gravity});
  std::array<J, kMaxEffectParams> grav{};
  for (int k = 0; k < 4; ++k) grav[k] = J(p.block(Effect::gravity)[k]);
  grav[0].v[0] = 1.0;
  ParamPointers<J> ptr{};
  ptr[index(Effect::gravity)] = grav.data();
  PoseSignals pose;
  pose.R_base_sensor = rot_y(0.5);
  const Wrench<J> w = predict_wrench<J>(p.effects, ptr, pose, ImuSignals<J>{}, RigGeometry{});
  const Eigen::Vector3d g =
      pose.R_base_sensor.transpose() * Eigen::Vector3d(0, 0, -kStandardGravity);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(w[k].v[0], g[k], 1e-12);
}

// The stage-1 effects of combination `bits` (0..15): gravity, and base_tilt, linear_inertia,
// rotational_inertia, sensor_rotation where bits 0..3 are set.
EffectSet stage1_combination(unsigned bits) {
  const std::array<Effect, 4> optional = {Effect::base_tilt, Effect::linear_inertia,
                                          Effect::rotational_inertia, Effect::sensor_rotation};
  EffectSet effects{Effect::gravity};
  for (unsigned k = 0; k < 4; ++k)
    if (bits >> k & 1u) effects.add(optional[k]);
  return effects;
}

// Random stage-1 parameters (gravity, base_tilt, rotational_inertia, sensor_rotation; a mass of
// 0–100 kg, principal inertias of 1–3 kg·m², the rest within ±0.1) as Jets, each with a unit
// derivative in the next of consecutive slots; `make(value, slot)` makes one.
template <typename T, typename Make>
void random_stage1_params(std::mt19937& rng,
                          std::array<std::array<T, kMaxEffectParams>, kEffectCount>& values,
                          ParamPointers<T>& ptr, const Make& make) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int slot = 0;
  for (Effect e :
       {Effect::gravity, Effect::base_tilt, Effect::rotational_inertia, Effect::sensor_rotation}) {
    for (int i = 0; i < info(e).num_params; ++i) {
      double v = 0.1 * u(rng);
      if (e == Effect::gravity && i == 0) v = 50.0 + 50.0 * u(rng);
      if (e == Effect::rotational_inertia && i < 3) v = 2.0 + u(rng);
      values[index(e)][i] = make(v, slot++);
    }
    ptr[index(e)] = values[index(e)].data();
  }
}

// payload_wrench_mean on the block means of the signals equals the mean of payload_wrench over
// the block, for random parameters and signals and every combination of the stage-1 effects
// (values and derivatives with respect to every parameter).
TEST(PayloadWrenchMean, EqualsTheMeanOfPayloadWrenchForEveryEffectCombination) {
  using J = ceres::Jet<double, 16>;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto vec = [&](double s) { return Eigen::Vector3d(s * u(rng), s * u(rng), s * u(rng)); };
  int cases = 0;
  for (unsigned bits = 0; bits < 16; ++bits) {
    for (int trial = 0; trial < 5; ++trial) {
      const EffectSet effects = stage1_combination(bits);
      // Random parameters, as Jets with one derivative slot per parameter (16 in all).
      std::array<std::array<J, kMaxEffectParams>, kEffectCount> values{};
      ParamPointers<J> ptr{};
      random_stage1_params(rng, values, ptr, [](double v, int slot) { return J(v, slot); });
      RigGeometry rig;
      rig.R_sensor_imu = rotation_from_vector<double>(vec(2.0));
      rig.p_sensor_imu_m = vec(0.1);
      // A block of 8 samples with random attitudes and IMU signals.
      constexpr int kCount = 8;
      Wrench<J> expected = Wrench<J>::Zero();
      PayloadMeans<J> means;
      means.R_base_sensor.setZero();
      for (int s = 0; s < kCount; ++s) {
        PoseSignals pose;
        pose.R_base_sensor = rotation_from_vector<double>(vec(3.0));
        ImuSignals<J> imu;
        imu.specific_force_imu = vec(15.0).cast<J>();
        imu.angular_rate_imu = vec(2.0).cast<J>();
        imu.angular_accel_imu = vec(5.0).cast<J>();
        expected += payload_wrench<J>(effects, ptr, pose, imu, rig) / J(kCount);
        means.R_base_sensor += pose.R_base_sensor / kCount;
        means.specific_force_imu += imu.specific_force_imu / J(kCount);
        means.angular_accel_imu += imu.angular_accel_imu / J(kCount);
        means.rate_outer_imu += imu.angular_rate_imu * imu.angular_rate_imu.transpose() / J(kCount);
      }
      const Wrench<J> got = payload_wrench_mean<J>(effects, ptr, means, rig);
      double scale = 0.0, dscale = 0.0;
      for (int k = 0; k < 6; ++k) {
        scale = std::max(scale, std::abs(expected[k].a));
        dscale = std::max(dscale, expected[k].v.cwiseAbs().maxCoeff());
      }
      for (int k = 0; k < 6; ++k) {
        EXPECT_NEAR(got[k].a, expected[k].a, 1e-12 * scale) << "effects " << bits << " row " << k;
        for (int d = 0; d < 16; ++d)
          EXPECT_NEAR(got[k].v[d], expected[k].v[d], 1e-12 * dscale)
              << "effects " << bits << " row " << k << " derivative " << d;
      }
      ++cases;
    }
  }
  EXPECT_EQ(cases, 80);
  // Without gravity there is no payload.
  PayloadMeans<double> means;
  means.specific_force_imu = Eigen::Vector3d(1, 2, 3);
  ModelParams p = payload({Effect::linear_inertia});
  EXPECT_EQ(payload_wrench_mean<double>(p.effects, pointers(p), means, {}), Wrench<double>::Zero());
}

// The host fit (fit.cpp, the normal engine) evaluates stage 1 with the mount computed once per
// parameter point, with Jet parameters on means that are plain doubles, and takes the derivative
// the means carry (the IMU time offset's) from a second evaluation with one-slot Jets. Jet
// arithmetic is slot by slot, so that must give exactly (bit for bit) the numbers of the one
// evaluation on Jet means: checked here for every combination of the stage-1 effects.
TEST(PayloadWrenchMean, SplitEvaluationGivesTheNumbersOfTheJetEvaluation) {
  using J = ceres::Jet<double, 16>;
  using J1 = ceres::Jet<double, 1>;
  constexpr int kTauSlot = 15;  // the parameters below take slots 0..14
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto vec = [&](double s) { return Eigen::Vector3d(s * u(rng), s * u(rng), s * u(rng)); };
  for (unsigned bits = 0; bits < 16; ++bits) {
    const EffectSet effects = stage1_combination(bits);
    std::array<std::array<J, kMaxEffectParams>, kEffectCount> values{};
    std::array<std::array<J1, kMaxEffectParams>, kEffectCount> values1{};
    ParamPointers<J> ptr{};
    ParamPointers<J1> ptr1{};
    random_stage1_params(rng, values, ptr, [](double v, int slot) { return J(v, slot); });
    // The same values without derivatives (the 1-slot Jets hold only tau's).
    for (Effect e : {Effect::gravity, Effect::base_tilt, Effect::rotational_inertia,
                     Effect::sensor_rotation}) {
      for (int i = 0; i < info(e).num_params; ++i) values1[index(e)][i] = J1(values[index(e)][i].a);
      ptr1[index(e)] = values1[index(e)].data();
    }
    RigGeometry rig;
    rig.R_sensor_imu = rotation_from_vector<double>(vec(2.0));
    rig.p_sensor_imu_m = vec(0.1);
    // Means that depend on one parameter only (slot kTauSlot), as with an IMU time offset.
    PayloadMeans<J> means;
    PayloadMeans<double> means_value;
    PayloadMeans<J1> means1;
    means.R_base_sensor = means_value.R_base_sensor = means1.R_base_sensor =
        rotation_from_vector<double>(vec(3.0));
    const auto jet = [&](double a, double d, J& x, double& xv, J1& x1) {
      x = J(a);
      x.v[kTauSlot] = d;
      xv = a;
      x1 = J1(a);
      x1.v[0] = d;
    };
    for (int r = 0; r < 3; ++r) {
      jet(15.0 * u(rng), 30.0 * u(rng), means.specific_force_imu[r],
          means_value.specific_force_imu[r], means1.specific_force_imu[r]);
      jet(5.0 * u(rng), 50.0 * u(rng), means.angular_accel_imu[r], means_value.angular_accel_imu[r],
          means1.angular_accel_imu[r]);
      for (int c = 0; c <= r; ++c) {
        jet(4.0 * u(rng), 8.0 * u(rng), means.rate_outer_imu(r, c),
            means_value.rate_outer_imu(r, c), means1.rate_outer_imu(r, c));
        means.rate_outer_imu(c, r) = means.rate_outer_imu(r, c);
        means_value.rate_outer_imu(c, r) = means_value.rate_outer_imu(r, c);
        means1.rate_outer_imu(c, r) = means1.rate_outer_imu(r, c);
      }
    }
    const Wrench<J> expected = payload_wrench_mean<J>(effects, ptr, means, rig);
    const ImuMount<J> mount = imu_mount(effects, ptr, rig);
    ImuMount<J1> mount1;
    const auto value1 = [](const J& x) { return J1(x.a); };
    mount1.R_nominal_true = mount.R_nominal_true.unaryExpr(value1);
    mount1.R_sensor_imu = mount.R_sensor_imu.unaryExpr(value1);
    mount1.p_sensor_imu = mount.p_sensor_imu.unaryExpr(value1);
    const Wrench<J> got = payload_wrench_mean<J, double>(effects, ptr, mount, means_value);
    const Wrench<J1> got1 = payload_wrench_mean<J1, J1>(effects, ptr1, mount1, means1);
    for (int k = 0; k < 6; ++k) {
      EXPECT_EQ(got[k].a, expected[k].a) << "effects " << bits << " row " << k;
      EXPECT_EQ(got1[k].a, expected[k].a) << "effects " << bits << " row " << k;
      for (int d = 0; d < kTauSlot; ++d)
        EXPECT_EQ(got[k].v[d], expected[k].v[d])
            << "effects " << bits << " row " << k << " d " << d;
      EXPECT_EQ(got[k].v[kTauSlot], 0.0) << "effects " << bits << " row " << k;
      EXPECT_EQ(got1[k].v[0], expected[k].v[kTauSlot]) << "effects " << bits << " row " << k;
    }
  }
}

// sensor_output_jacobian equals autodiff of sensor_output, for random parameters and inputs and
// every combination of the stage-2 effects, columns laid out as the fit lays them out.
TEST(SensorOutputJacobian, EqualsAutodiffForEveryEffectCombination) {
  constexpr int kCols = 96;
  using J = ceres::Jet<double, kCols>;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const std::array<Effect, 5> stage2 = {Effect::bias, Effect::bias_drift, Effect::temperature_bias,
                                        Effect::crosstalk, Effect::cable};
  for (unsigned bits = 0; bits < 32; ++bits) {
    EffectSet effects;
    std::array<int, kEffectCount> column{};
    std::array<std::array<double, kMaxEffectParams>, kEffectCount> values{};
    std::array<std::array<J, kMaxEffectParams>, kEffectCount> jets{};
    ParamPointers<double> p{};
    ParamPointers<J> pj{};
    int next = 6;  // the payload wrench first
    for (unsigned k = 0; k < 5; ++k) {
      if (!(bits >> k & 1u)) continue;
      const Effect e = stage2[k];
      effects.add(e);
      column[index(e)] = next;
      for (int i = 0; i < info(e).num_params; ++i) {
        values[index(e)][i] = (e == Effect::crosstalk ? 0.02 : 3.0) * u(rng);
        jets[index(e)][i] = J(values[index(e)][i], next + i);
      }
      p[index(e)] = values[index(e)].data();
      pj[index(e)] = jets[index(e)].data();
      next += info(e).num_params;
    }
    SensorInputs in;
    in.t_rel_s = 500.0 * (1.0 + u(rng));
    in.temperature_C = 25.0 + 10.0 * u(rng);
    for (auto& f : in.cable_features) f = u(rng);
    Wrench<double> payload;
    Wrench<J> payload_jet;
    for (int k = 0; k < 6; ++k) {
      payload[k] = 500.0 * u(rng);
      payload_jet[k] = J(payload[k], k);
    }
    const Wrench<J> out = sensor_output<J>(effects, pj, in, payload_jet);
    Eigen::Matrix<double, 6, kCols> jac;
    sensor_output_jacobian<kCols>(effects, p, in, payload, column, jac);
    const Wrench<double> value = sensor_output<double>(effects, p, in, payload);
    for (int r = 0; r < 6; ++r) {
      EXPECT_NEAR(value[r], out[r].a, 1e-12 * std::abs(out[r].a));  // Jet and double round apart
      for (int c = 0; c < kCols; ++c)
        EXPECT_NEAR(jac(r, c), out[r].v[c], 1e-12 * (1.0 + std::abs(out[r].v[c])))
            << "effects " << bits << " row " << r << " column " << c;
    }
  }
}

TEST(Rotation, VectorFormulaMatchesEigenAngleAxisAndKukaAbc) {
  const Eigen::Vector3d r(0.3, -0.2, 0.5);
  const Eigen::Matrix3d R = rotation_from_vector(r);
  const Eigen::Matrix3d E = Eigen::AngleAxisd(r.norm(), r.normalized()).toRotationMatrix();
  EXPECT_NEAR((R - E).norm(), 0.0, 1e-12);
  const Eigen::Matrix3d K = rotation_from_kuka_abc(0.1, 0.2, 0.3);
  const Eigen::Matrix3d expected = (Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY()) *
                                    Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()))
                                       .toRotationMatrix();
  EXPECT_NEAR((K - expected).norm(), 0.0, 1e-12);
}

TEST(Rotation, KukaAbcRoundTripsIncludingGimbalLock) {
  const double cases[][3] = {{0.1, 0.2, 0.3}, {-3.0, 1.4, 2.9}, {2.0, -0.7, -3.1}, {0, 0, 0}};
  for (const auto& c : cases) {
    const Eigen::Vector3d abc = kuka_abc_from_rotation(rotation_from_kuka_abc(c[0], c[1], c[2]));
    EXPECT_NEAR(abc[0], c[0], 1e-12);
    EXPECT_NEAR(abc[1], c[1], 1e-12);
    EXPECT_NEAR(abc[2], c[2], 1e-12);
  }
  // At B = ±90° the angles are not unique, but the rotation is reproduced.
  for (double b : {1.5707963267948966, -1.5707963267948966}) {
    const Eigen::Matrix3d R = rotation_from_kuka_abc(0.4, b, -0.3);
    const Eigen::Vector3d abc = kuka_abc_from_rotation(R);
    EXPECT_NEAR((rotation_from_kuka_abc(abc[0], abc[1], abc[2]) - R).norm(), 0.0, 1e-9);
  }
}

TEST(EffectInfo, NamesRoundTripAndParameterCountsFitTheBlocks) {
  for (Effect e : kAllEffects) {
    const EffectInfo& i = info(e);
    EXPECT_EQ(i.id, e);
    ASSERT_TRUE(effect_from_name(i.name).has_value());
    EXPECT_EQ(*effect_from_name(i.name), e);
    EXPECT_LE(i.num_params, kMaxEffectParams);
  }
  EXPECT_FALSE(effect_from_name("gravitation").has_value());
}

}  // namespace
}  // namespace zerog::model
