// The recordings' data files read into SI series, one per [files.NAME] table of the mapping
// (import_series.cpp), and what merging them onto the master's time base needs.
#pragma once

#include <algorithm>
#include <cstddef>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "import_mapping.hpp"

namespace zerog::io::importer {

// ---------------------------------------------------------------------------------------------
// Data files, read into SI series.

struct Series {
  std::vector<double> t;
  std::array<std::vector<double>, kQuantityCount> values;  ///< `stored` values per row
};

/// The data file of `spec` (its columns resolved into spec.refs[].cell on the way).
Series read_series(FileSpec& spec, const fs::path& mapping);

/// Static tables joined by pose index (import_series.cpp).
void join_by_pose_index(std::vector<Series>& series, ImportReport& report);

// ---------------------------------------------------------------------------------------------
// Merging onto the master's time base.

/// Where a master time falls in another file: between rows k0 and k1, fraction alpha.
struct Bracket {
  std::size_t k0 = 0;
  std::size_t k1 = 0;
  double alpha = 0.0;
};

template <int N>
Eigen::Matrix<double, N, 1> at(const std::vector<double>& v, const Bracket& b) {
  const Eigen::Map<const Eigen::Matrix<double, N, 1>> a(v.data() + b.k0 * N);
  const Eigen::Map<const Eigen::Matrix<double, N, 1>> c(v.data() + b.k1 * N);
  if (b.alpha == 0.0) return a;  // the sample as it is (−0 + 0 · (c − a) would be +0)
  return a + b.alpha * (c - a);
}

inline Eigen::Quaterniond quaternion_at(const std::vector<double>& v, const Bracket& b) {
  const Eigen::Quaterniond a(v[b.k0 * 4], v[b.k0 * 4 + 1], v[b.k0 * 4 + 2], v[b.k0 * 4 + 3]);
  const Eigen::Quaterniond c(v[b.k1 * 4], v[b.k1 * 4 + 1], v[b.k1 * 4 + 2], v[b.k1 * 4 + 3]);
  return b.alpha == 0.0 ? a : a.slerp(b.alpha, c).normalized();
}

inline double median_period(const std::vector<double>& t) {
  if (t.size() < 2) return 0.0;
  std::vector<double> dt(t.size() - 1);
  for (std::size_t i = 1; i < t.size(); ++i) dt[i - 1] = t[i] - t[i - 1];
  std::nth_element(dt.begin(), dt.begin() + static_cast<std::ptrdiff_t>(dt.size() / 2), dt.end());
  return dt[dt.size() / 2];
}

}  // namespace zerog::io::importer
