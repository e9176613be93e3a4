#include "screening.hpp"

#include <Eigen/Dense>
#include <utility>

namespace zerog::ident::screening {
namespace {

// Jacobi scaling of the columns `idx` of H (1/√H_jj; 1 where H_jj is zero).
Eigen::VectorXd jacobi(const Eigen::MatrixXd& H, const std::vector<int>& idx) {
  Eigen::VectorXd d(static_cast<Eigen::Index>(idx.size()));
  for (std::size_t i = 0; i < idx.size(); ++i) {
    const double h = H(idx[i], idx[i]);
    d[static_cast<Eigen::Index>(i)] = h > 0.0 ? 1.0 / std::sqrt(h) : 1.0;
  }
  return d;
}

Eigen::MatrixXd sub(const Eigen::MatrixXd& H, const std::vector<int>& rows,
                    const std::vector<int>& cols) {
  Eigen::MatrixXd out(static_cast<Eigen::Index>(rows.size()),
                      static_cast<Eigen::Index>(cols.size()));
  for (std::size_t i = 0; i < rows.size(); ++i)
    for (std::size_t j = 0; j < cols.size(); ++j)
      out(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j)) = H(rows[i], cols[j]);
  return out;
}

Eigen::VectorXd sub(const Eigen::VectorXd& g, const std::vector<int>& idx) {
  Eigen::VectorXd out(static_cast<Eigen::Index>(idx.size()));
  for (std::size_t i = 0; i < idx.size(); ++i) out[static_cast<Eigen::Index>(i)] = g[idx[i]];
  return out;
}

// Pseudo-inverse of a symmetric matrix with (nearly) unit diagonal: eigen-directions below
// kRankCut of max(1, largest eigenvalue) are dropped. The floor of 1 keeps a block that is null
// as a whole (a candidate the base already spans: its Schur complement is ~0) from being
// inverted at its own, meaningless, scale.
Eigen::MatrixXd pinv(const Eigen::MatrixXd& C) {
  if (C.rows() == 0) return C;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(C);
  const Eigen::VectorXd& l = eig.eigenvalues();
  const double cut = BorderedSolver::kRankCut * std::max(1.0, l.maxCoeff());
  Eigen::VectorXd inv = Eigen::VectorXd::Zero(l.size());
  for (Eigen::Index k = 0; k < l.size(); ++k)
    if (l[k] > cut) inv[k] = 1.0 / l[k];
  return eig.eigenvectors() * inv.asDiagonal() * eig.eigenvectors().transpose();
}

}  // namespace

BorderedSolver::BorderedSolver(const Eigen::MatrixXd& H, const Eigen::VectorXd& g,
                               std::vector<int> base, bool drop_coupling)
    : H_(H), g_(g), base_(std::move(base)), drop_coupling_(drop_coupling) {
  d_base_ = jacobi(H_, base_);
  pinv_base_ = pinv(d_base_.asDiagonal() * sub(H_, base_, base_) * d_base_.asDiagonal());
}

Eigen::VectorXd BorderedSolver::step(const std::vector<int>& candidate) const {
  // Scaled variables y = x / d: C = D H D (unit diagonal), gradient D g.
  const Eigen::VectorXd dc = jacobi(H_, candidate);
  const Eigen::MatrixXd Cbc = d_base_.asDiagonal() * sub(H_, base_, candidate) * dc.asDiagonal();
  const Eigen::MatrixXd Ccc = dc.asDiagonal() * sub(H_, candidate, candidate) * dc.asDiagonal();
  const Eigen::VectorXd gb = d_base_.cwiseProduct(sub(g_, base_));
  const Eigen::VectorXd gc = dc.cwiseProduct(sub(g_, candidate));
  Eigen::VectorXd yb, yc;
  if (drop_coupling_) {
    yc = -pinv(Ccc) * gc;
    yb = Eigen::VectorXd::Zero(gb.size());
  } else {
    // Eliminate the base: C_bb y_b = −g_b − C_bc y_c, then S y_c = −g_c + C_cb C_bb⁺ g_b.
    const Eigen::MatrixXd W = pinv_base_ * Cbc;  // C_bb⁺ C_bc
    const Eigen::MatrixXd S = Ccc - Cbc.transpose() * W;
    yc = pinv(0.5 * (S + S.transpose())) * (-gc + W.transpose() * gb);
    yb = -pinv_base_ * (gb + Cbc * yc);
  }
  Eigen::VectorXd x = Eigen::VectorXd::Zero(g_.size());
  for (std::size_t i = 0; i < base_.size(); ++i)
    x[base_[i]] = d_base_[static_cast<Eigen::Index>(i)] * yb[static_cast<Eigen::Index>(i)];
  for (std::size_t i = 0; i < candidate.size(); ++i)
    x[candidate[i]] = dc[static_cast<Eigen::Index>(i)] * yc[static_cast<Eigen::Index>(i)];
  return x;
}

Eigen::VectorXd direct_step(const Eigen::MatrixXd& H, const Eigen::VectorXd& g,
                            const std::vector<int>& columns) {
  const Eigen::VectorXd d = jacobi(H, columns);
  const Eigen::VectorXd y = -pinv(d.asDiagonal() * sub(H, columns, columns) * d.asDiagonal()) *
                            d.cwiseProduct(sub(g, columns));
  Eigen::VectorXd x = Eigen::VectorXd::Zero(g.size());
  for (std::size_t i = 0; i < columns.size(); ++i)
    x[columns[i]] = d[static_cast<Eigen::Index>(i)] * y[static_cast<Eigen::Index>(i)];
  return x;
}

}  // namespace zerog::ident::screening
