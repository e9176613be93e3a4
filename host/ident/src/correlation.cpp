// The signals the residual follows: its correlation on the held-out samples with time,
// temperature, joint angles and velocities, IMU rates and the gravity direction, in plain words
// (what the verdict names when no library effect explains the residual).
#include <algorithm>
#include <cmath>
#include <functional>

#include <Eigen/Core>

#include "diagnose_internal.hpp"
#include "parallel.hpp"

namespace zerog::ident::diagnosis {
namespace {

// Candidate signals for residual correlation, in plain words.
// A signal the residual may follow: its values on samples [i0, i1) where `mask` is set, into
// out[i − i0] (the others are not read). Formed on demand, chunk by chunk: kept as columns, the
// forty-odd features of a 10^6-sample log held 320 MB (issue 16).
struct Feature {
  std::string name;
  std::function<void(std::size_t i0, std::size_t i1, const std::uint8_t* mask, double* out)> values;
};

std::vector<Feature> features(const Dataset& data) {
  std::vector<Feature> f;
  auto add = [&](std::string name, auto fn) {
    f.push_back({std::move(name),
                 [fn](std::size_t i0, std::size_t i1, const std::uint8_t* mask, double* out) {
                   for (std::size_t i = i0; i < i1; ++i)
                     if (mask[i]) out[i - i0] = fn(i);
                 }});
  };
  if (!data.columns.static_rows)
    add("time since start", [&](std::size_t i) { return data.pose(i).t_rel_s; });
  if (data.columns.temperature)
    add("sensor temperature", [&](std::size_t i) { return data.pose(i).temperature_C; });
  if (data.columns.joints) {
    for (int j = 0; j < 6; ++j) {
      const std::string a = "joint A" + std::to_string(j + 1);
      add(a + " angle (sine)", [&, j](std::size_t i) { return std::sin(data.joints_rad[i][j]); });
      add(a + " angle (cosine)", [&, j](std::size_t i) { return std::cos(data.joints_rad[i][j]); });
      if (data.columns.static_rows) continue;  // held poses: no velocities
      add(a + " velocity", [&, j](std::size_t i) { return data.joint_vel_radps(i)[j]; });
      add(a + " velocity direction (sign)", [&, j](std::size_t i) {
        const double v = data.joint_vel_radps(i)[j];
        return std::abs(v) < 1e-3 ? 0.0 : (v > 0 ? 1.0 : -1.0);
      });
    }
  }
  if (data.columns.any_imu()) {
    const char* ax = "xyz";
    for (int k = 0; k < 3; ++k) {
      if (data.columns.angular_rate) {
        add(std::string("angular rate about IMU ") + ax[k],
            [&, k](std::size_t i) { return data.imu[i * 9 + 3 + k]; });
        if (!data.columns.static_rows)
          add(std::string("angular acceleration about IMU ") + ax[k],
              [&, k](std::size_t i) { return data.imu[i * 9 + 6 + k]; });
      }
      if (data.columns.specific_force)
        add(std::string("specific force along IMU ") + ax[k],
            [&, k](std::size_t i) { return data.imu[i * 9 + k]; });
    }
    if (data.columns.angular_rate)
      add("squared angular rate", [&](std::size_t i) {
        return Eigen::Map<const Eigen::Vector3d>(&data.imu[i * 9 + 3]).squaredNorm();
      });
  }
  for (int k = 0; k < 3; ++k) {
    const char* ax = "xyz";
    add(std::string("gravity direction along sensor ") + ax[k], [&, k](std::size_t i) {
      return (data.pose(i).R_base_sensor.transpose() * Eigen::Vector3d(0, 0, -1))[k];
    });
  }
  return f;
}

}  // namespace

std::vector<SignalCorrelation> correlate(const Dataset& data, const std::vector<Wrench>& res,
                                         const std::vector<std::uint8_t>& mask, int threads) {
  // Each feature's correlations on their own (one thread's sums each, in sample order, over the
  // masked samples), then in feature order. A feature's values are formed a chunk at a time as
  // its walk reaches them (releasing a spilled log's rows behind it).
  const std::vector<Feature> fs = features(data);
  std::vector<std::vector<SignalCorrelation>> per(fs.size());
  constexpr std::size_t kChunk = 4096;
  parallel::for_each(fs.size(), threads, [&](std::size_t q, int) {
    const Feature& f = fs[q];
    std::array<double, 6> sx{}, sy{}, sxx{}, syy{}, sxy{};
    double n = 0;
    std::vector<double> x(kChunk);
    ResidentWindow window(data);
    for (std::size_t i0 = 0; i0 < data.size(); i0 += kChunk) {
      const std::size_t i1 = std::min(data.size(), i0 + kChunk);
      window.advance(i1 - 1);
      f.values(i0, i1, mask.data(), x.data());
      for (std::size_t i = i0; i < i1; ++i) {
        if (!mask[i]) continue;
        const double xi = x[i - i0];
        for (int a = 0; a < 6; ++a) {
          const double y = res[i][a];
          sx[a] += xi, sy[a] += y, sxx[a] += xi * xi, syy[a] += y * y, sxy[a] += xi * y;
        }
        n += 1;
      }
    }
    for (int a = 0; a < 6; ++a) {
      const double vx = sxx[a] - sx[a] * sx[a] / n, vy = syy[a] - sy[a] * sy[a] / n;
      if (vx <= 1e-12 * n || vy <= 0) continue;
      per[q].push_back({f.name, a, (sxy[a] - sx[a] * sy[a] / n) / std::sqrt(vx * vy)});
    }
  });
  std::vector<SignalCorrelation> out;
  for (auto& p : per) out.insert(out.end(), p.begin(), p.end());
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    return std::abs(a.correlation) > std::abs(b.correlation);
  });
  if (out.size() > 8) out.resize(8);
  return out;
}

}  // namespace zerog::ident::diagnosis
