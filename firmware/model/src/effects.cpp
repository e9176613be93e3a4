#include "zerog/model/effects.hpp"

namespace zerog::model {
namespace {

constexpr ParamInfo kBias[] = {{"F0x", "N"},   {"F0y", "N"},   {"F0z", "N"},
                               {"M0x", "N*m"}, {"M0y", "N*m"}, {"M0z", "N*m"}};
constexpr ParamInfo kGravity[] = {{"mass", "kg"}, {"cx", "m"}, {"cy", "m"}, {"cz", "m"}};
constexpr ParamInfo kBaseTilt[] = {{"alpha", "rad"}, {"beta", "rad"}};
constexpr ParamInfo kRotInertia[] = {{"Ixx", "kg*m^2"}, {"Iyy", "kg*m^2"}, {"Izz", "kg*m^2"},
                                     {"Ixy", "kg*m^2"}, {"Ixz", "kg*m^2"}, {"Iyz", "kg*m^2"}};
constexpr ParamInfo kTimeOffset[] = {{"tau", "s"}};
constexpr ParamInfo kDrift[] = {{"dF0x", "N/s"},   {"dF0y", "N/s"},   {"dF0z", "N/s"},
                                {"dM0x", "N*m/s"}, {"dM0y", "N*m/s"}, {"dM0z", "N*m/s"}};
constexpr ParamInfo kTemp[] = {{"kFx", "N/K"},   {"kFy", "N/K"},   {"kFz", "N/K"},
                               {"kMx", "N*m/K"}, {"kMy", "N*m/K"}, {"kMz", "N*m/K"}};
constexpr ParamInfo kSensorRot[] = {{"rx", "rad"}, {"ry", "rad"}, {"rz", "rad"}};

// Crosstalk E (row-major, measured = (1 + E) · wrench): rows/columns Fx Fy Fz Mx My Mz.
// Units: force from force 1, force from torque 1/m, torque from force m, torque from torque 1.
constexpr ParamInfo kCrosstalk[] = {
    {"E_Fx_Fx", "1"},   {"E_Fx_Fy", "1"},   {"E_Fx_Fz", "1"},   {"E_Fx_Mx", "1/m"},
    {"E_Fx_My", "1/m"}, {"E_Fx_Mz", "1/m"}, {"E_Fy_Fx", "1"},   {"E_Fy_Fy", "1"},
    {"E_Fy_Fz", "1"},   {"E_Fy_Mx", "1/m"}, {"E_Fy_My", "1/m"}, {"E_Fy_Mz", "1/m"},
    {"E_Fz_Fx", "1"},   {"E_Fz_Fy", "1"},   {"E_Fz_Fz", "1"},   {"E_Fz_Mx", "1/m"},
    {"E_Fz_My", "1/m"}, {"E_Fz_Mz", "1/m"}, {"E_Mx_Fx", "m"},   {"E_Mx_Fy", "m"},
    {"E_Mx_Fz", "m"},   {"E_Mx_Mx", "1"},   {"E_Mx_My", "1"},   {"E_Mx_Mz", "1"},
    {"E_My_Fx", "m"},   {"E_My_Fy", "m"},   {"E_My_Fz", "m"},   {"E_My_Mx", "1"},
    {"E_My_My", "1"},   {"E_My_Mz", "1"},   {"E_Mz_Fx", "m"},   {"E_Mz_Fy", "m"},
    {"E_Mz_Fz", "m"},   {"E_Mz_Mx", "1"},   {"E_Mz_My", "1"},   {"E_Mz_Mz", "1"}};

// Cable: for joint A4, A5, A6 in turn, six cosine then six sine coefficients (Fx..Mz).
constexpr ParamInfo kCable[] = {
    {"A4cos_Fx", "N"},   {"A4cos_Fy", "N"},   {"A4cos_Fz", "N"},   {"A4cos_Mx", "N*m"},
    {"A4cos_My", "N*m"}, {"A4cos_Mz", "N*m"}, {"A4sin_Fx", "N"},   {"A4sin_Fy", "N"},
    {"A4sin_Fz", "N"},   {"A4sin_Mx", "N*m"}, {"A4sin_My", "N*m"}, {"A4sin_Mz", "N*m"},
    {"A5cos_Fx", "N"},   {"A5cos_Fy", "N"},   {"A5cos_Fz", "N"},   {"A5cos_Mx", "N*m"},
    {"A5cos_My", "N*m"}, {"A5cos_Mz", "N*m"}, {"A5sin_Fx", "N"},   {"A5sin_Fy", "N"},
    {"A5sin_Fz", "N"},   {"A5sin_Mx", "N*m"}, {"A5sin_My", "N*m"}, {"A5sin_Mz", "N*m"},
    {"A6cos_Fx", "N"},   {"A6cos_Fy", "N"},   {"A6cos_Fz", "N"},   {"A6cos_Mx", "N*m"},
    {"A6cos_My", "N*m"}, {"A6cos_Mz", "N*m"}, {"A6sin_Fx", "N"},   {"A6sin_Fy", "N"},
    {"A6sin_Fz", "N"},   {"A6sin_Mx", "N*m"}, {"A6sin_My", "N*m"}, {"A6sin_Mz", "N*m"}};

const EffectInfo kInfos[kEffectCount] = {
    {Effect::bias,
     "bias",
     "constant sensor zero offset (F0, M0)",
     "w += [F0; M0]",
     "none",
     "a constant offset on every axis, static and moving alike",
     6,
     kBias,
     {}},
    {Effect::gravity,
     "gravity",
     "payload weight at its centre of mass, from the sensor pose",
     "F += m g_S, M += c x F, g_S = R_BS^T R_WB^T (0,0,-g)",
     "sensor pose",
     "a pattern that follows the sensor attitude in static poses (sinusoidal in the wrist joints)",
     4,
     kGravity,
     {}},
    {Effect::base_tilt,
     "base_tilt",
     "robot base not level: gravity is tilted in the base frame",
     "R_WB = Rx(alpha) Ry(beta) in g_S",
     "sensor pose",
     "static force error proportional to the mass, in a fixed world direction (a few N per mrad)",
     2,
     kBaseTilt,
     {Effect::gravity}},
    {Effect::linear_inertia,
     "linear_inertia",
     "payload inertia from the IMU specific force, moved to the centre of mass (lever arm)",
     "F = -m (R_SI f_I + w_dot x r + w x (w x r)), r = c - p_SI; replaces m g_S",
     "IMU specific force and angular rate",
     "force errors during moves proportional to acceleration; silent in static poses",
     0,
     nullptr,
     {Effect::gravity}},
    {Effect::rotational_inertia,
     "rotational_inertia",
     "payload rotational inertia with the gyroscopic term",
     "M -= I w_dot + w x (I w)",
     "IMU angular rate (and its derivative)",
     "torque errors during moves, following angular acceleration and the square of angular rate",
     6,
     kRotInertia,
     {Effect::gravity}},
    {Effect::imu_time_offset,
     "imu_time_offset",
     "IMU samples lag the F/T samples: IMU signals are read at t + tau",
     "f_I(t+tau), w_I(t+tau), w_dot_I(t+tau)",
     "IMU signals",
     "errors at the start and end of moves, proportional to jerk, opposite in sign",
     1,
     kTimeOffset,
     {Effect::linear_inertia}},
    {Effect::bias_drift,
     "bias_drift",
     "sensor zero drifting linearly with time",
     "w += d * (t - t0)",
     "time",
     "an offset that grows steadily over the run",
     6,
     kDrift,
     {Effect::bias}},
    {Effect::temperature_bias,
     "temperature_bias",
     "sensor zero depending on temperature",
     "w += k * (T - 25 C)",
     "sensor temperature",
     "an offset that follows the temperature",
     6,
     kTemp,
     {Effect::bias}},
    {Effect::crosstalk,
     "crosstalk",
     "sensor calibration error: gains and cross-axis coupling",
     "w_meas = (1 + E) w",
     "none",
     "an axis that echoes the load on another axis; errors proportional to load",
     36,
     kCrosstalk,
     {}},
    {Effect::sensor_rotation,
     "sensor_rotation",
     "sensor mounted rotated against its nominal orientation on the flange",
     "R_BS = R_BS,nom Exp(r); the IMU turns against S by Exp(r)^T",
     "sensor pose, IMU",
     "force errors about 1.7 N per mrad per 100 kg, perpendicular to gravity",
     3,
     kSensorRot,
     {Effect::gravity}},
    {Effect::cable,
     "cable",
     "wrench of the cable dress pulling on the sensor, by wrist angle",
     "w += sum_j a_j cos(q_j) + b_j sin(q_j), j = A4, A5, A6",
     "joint angles",
     "errors that follow the wrist joint angles A4..A6, static and moving alike",
     36,
     kCable,
     {}},
};

}  // namespace

const EffectInfo& info(Effect e) { return kInfos[index(e)]; }

std::optional<Effect> effect_from_name(std::string_view name) {
  for (const EffectInfo& i : kInfos) {
    if (name == i.name) return i.id;
  }
  return std::nullopt;
}

}  // namespace zerog::model
