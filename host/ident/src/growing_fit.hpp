#pragma once
// The least-squares fit inside discovery's orthogonal matching pursuit (discovery.cpp), grown one
// accepted column at a time instead of refactored per step (issue 16). Host only.
#include <Eigen/Dense>
#include <algorithm>
#include <cstddef>
#include <vector>

namespace zerog::ident {

/// The fit of a right-hand side r on the columns A = [A0, x_1, …, x_k] (A0: the independent
/// columns of a column-pivoted QR, in its pivot order; x_i: accepted candidates), kept as
/// A = Q R with Q orthonormal, and every candidate x_j with the fit projected out,
/// xp_j = x_j − Q c_j = (I − Q Qᵀ) x_j. Accepting a column costs O(rows × columns) for it and
/// O(rows) per candidate, where a new QR of A and a projection of every candidate on all of Q
/// cost O(rows × columns) per column each.
///
/// An accepted column is appended by classical Gram–Schmidt with re-orthogonalisation (CGS2:
/// its kept projection, already taken off every earlier column, gets a second pass against all
/// of Q; two passes keep Q orthonormal to working precision, Giraud, Langou, Rozložník, Numer.
/// Math. 101 (2005) 87–100). Qᵀ r is kept as modified Gram–Schmidt keeps a right-hand side: each
/// new entry is taken against the residual as it stood.
class GrowingFit {
 public:
  /// `qr`: the column-pivoted QR of A0 (rows × n0); `Q0`: its first qr.rank() columns of Q;
  /// room for `max_added` accepted columns and `candidates` candidates, each to be started
  /// (see `projections`) before it is refreshed.
  GrowingFit(const Eigen::ColPivHouseholderQR<Eigen::MatrixXd>& qr, const Eigen::MatrixXd& Q0,
             const Eigen::VectorXd& r, Eigen::Index max_added, Eigen::Index candidates)
      : rank0_(qr.rank()),
        cols_(rank0_),
        Q_(Q0.rows(), rank0_ + std::max<Eigen::Index>(max_added, 0)),
        R_(Eigen::MatrixXd::Zero(Q_.cols(), Q_.cols())),
        qtr_(Q_.cols()),
        xp_(Q0.rows(), candidates),
        c_(Eigen::MatrixXd::Zero(Q_.cols(), candidates)),
        seen_(static_cast<std::size_t>(candidates), rank0_) {
    Q_.leftCols(rank0_) = Q0;
    R_.topLeftCorner(rank0_, rank0_) =
        qr.matrixR().topLeftCorner(rank0_, rank0_).triangularView<Eigen::Upper>();
    qtr_.head(rank0_).noalias() = Q0.transpose() * r;
    r_cur_ = r - Q0 * qtr_.head(rank0_);
  }

  Eigen::Index rank0() const { return rank0_; }
  Eigen::Index columns() const { return cols_; }
  /// Q: the orthonormal basis of the current columns.
  auto basis() const { return Q_.leftCols(cols_); }
  /// r − A θ: the residual of the current fit.
  const Eigen::VectorXd& residual() const { return r_cur_; }

  /// Candidate j's projection and its coefficients on Q (x_j = Q c_j + xp_j). The caller starts
  /// each candidate against A0's part of Q, before any column is accepted, writing both (it
  /// knows the columns' structure: a few at a time, by matrix products); afterwards they are
  /// read only, once `refresh(j)` has brought them up to date.
  Eigen::MatrixXd& projections() { return xp_; }
  Eigen::MatrixXd& coefficients() { return c_; }
  const Eigen::MatrixXd& projections() const { return xp_; }

  /// Takes the columns accepted since candidate j was last refreshed off its projection.
  /// Touches only candidate j's data: candidates may be refreshed concurrently.
  void refresh(Eigen::Index j) {
    Eigen::Index& seen = seen_[static_cast<std::size_t>(j)];
    auto xp = xp_.col(j);
    for (; seen < cols_; ++seen) {
      const auto q = Q_.col(seen);
      const double g = q.dot(xp);
      xp -= g * q;
      c_(seen, j) = g;
    }
  }

  /// The fit with candidate j appended, not yet accepted.
  struct Trial {
    Eigen::Index candidate = -1;
    Eigen::VectorXd q;      // the new orthonormal column
    Eigen::MatrixXd R;      // (k + 1) × (k + 1), upper triangular
    Eigen::VectorXd qtr;    // Qᵀ r with the new column, k + 1
    Eigen::VectorXd theta;  // least-squares coefficients on [A0's independent columns, x_1, …]
  };
  /// Candidate j (refreshed, not accepted, its projection not negligible) on trial.
  Trial trial(Eigen::Index j) const {
    const Eigen::Index k = cols_;
    Trial t;
    t.candidate = j;
    const auto xp = xp_.col(j);
    const Eigen::VectorXd s = Q_.leftCols(k).transpose() * xp;  // the second pass
    t.q = xp - Q_.leftCols(k) * s;
    const double rho = t.q.norm();
    t.q /= rho;
    t.R = R_.topLeftCorner(k + 1, k + 1);
    t.R.col(k).head(k) = c_.col(j).head(k) + s;
    t.R(k, k) = rho;
    t.qtr = qtr_.head(k + 1);
    t.qtr[k] = t.q.dot(r_cur_);
    t.theta = t.R.triangularView<Eigen::Upper>().solve(t.qtr);
    return t;
  }

  /// Makes a trial's column part of the fit (the other candidates take it off when refreshed).
  void accept(const Trial& t) {
    const Eigen::Index k = cols_;
    Q_.col(k) = t.q;
    R_.topLeftCorner(k + 1, k + 1) = t.R;
    qtr_[k] = t.qtr[k];
    r_cur_ -= t.qtr[k] * t.q;
    cols_ = k + 1;
    seen_[static_cast<std::size_t>(t.candidate)] = cols_;
  }

 private:
  Eigen::Index rank0_, cols_;
  Eigen::MatrixXd Q_;               // rows × capacity, the first cols_ orthonormal
  Eigen::MatrixXd R_;               // capacity × capacity, A = Q R on the first cols_
  Eigen::VectorXd qtr_;             // Qᵀ r
  Eigen::VectorXd r_cur_;           // r − A θ
  Eigen::MatrixXd xp_, c_;          // candidates' projections and coefficients on Q
  std::vector<Eigen::Index> seen_;  // columns of Q taken off each candidate
};

}  // namespace zerog::ident
