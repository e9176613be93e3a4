// Discovery's fit grown one column at a time (host/ident/src/growing_fit.hpp, issue 16) against a
// fresh column-pivoted QR of the same columns, on a random problem with a rank-deficient A0 and
// candidates nearly inside the fit (where a single Gram–Schmidt pass loses orthogonality): after
// every accepted column the residual, every open candidate's projection and the trial's
// coefficients equal the fresh factorisation's, and the basis stays orthonormal.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <algorithm>
#include <random>
#include <vector>

#include "growing_fit.hpp"

namespace zerog::ident {
namespace {

constexpr Eigen::Index kRows = 900, kA0 = 7, kCandidates = 12;

Eigen::MatrixXd thin_q(const Eigen::ColPivHouseholderQR<Eigen::MatrixXd>& qr) {
  return qr.householderQ() * Eigen::MatrixXd::Identity(qr.rows(), qr.rank());
}

// The reference: a pivoted QR of the columns scaled to unit norm (the same span and solution;
// Householder's error is relative to the largest column, Gram–Schmidt's to each column, and the
// columns here span five decades).
struct Fresh {
  Eigen::MatrixXd Q;
  Eigen::VectorXd theta;  // least-squares coefficients of r on the unscaled columns
  Eigen::Index rank = 0;
};
Fresh fresh_fit(const Eigen::MatrixXd& A, const Eigen::VectorXd& r) {
  const Eigen::VectorXd norms = A.colwise().norm().transpose();
  const Eigen::MatrixXd An = A * norms.cwiseInverse().asDiagonal();
  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(An);
  return {thin_q(qr), qr.solve(r).cwiseQuotient(norms), qr.rank()};
}

TEST(GrowingFit, EqualsAFreshQrAfterEveryAcceptedColumn) {
  std::mt19937_64 rng(16);
  std::normal_distribution<double> n01;
  const auto random = [&](Eigen::Index rows, Eigen::Index cols) {
    Eigen::MatrixXd m(rows, cols);
    for (Eigen::Index j = 0; j < cols; ++j)
      for (Eigen::Index i = 0; i < rows; ++i) m(i, j) = n01(rng);
    return m;
  };
  // A0 with columns of very different scales and one column the sum of two others (rank 6).
  Eigen::MatrixXd A0 = random(kRows, kA0);
  A0.col(2) *= 1e3;
  A0.col(5) *= 1e-2;
  A0.col(6) = A0.col(1) + A0.col(3);
  // Candidates: random ones, and ones within 1e-4 of A0's span or of another candidate's (the
  // dependence test lets columns down to 3e-5 of their norm through).
  Eigen::MatrixXd X = random(kRows, kCandidates);
  const auto unit = [](const Eigen::VectorXd& v) -> Eigen::VectorXd { return v / v.norm(); };
  X.col(1) = unit(A0 * random(kA0, 1)) + 1e-4 * unit(X.col(1));
  X.col(4) = unit(X.col(0) + 2.0 * X.col(7)) + 1e-4 * unit(X.col(4));
  X.col(9) = unit(A0.col(2) * 1e-3 + X.col(3)) + 1e-4 * unit(X.col(9));
  const Eigen::VectorXd r = A0 * random(kA0, 1) + X * random(kCandidates, 1) + random(kRows, 1);

  const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(A0);
  ASSERT_EQ(qr.rank(), kA0 - 1);
  const Eigen::MatrixXd Q0 = thin_q(qr);
  const std::vector<int> order = {0, 3, 1, 7, 4, 9};  // the near-dependent ones after their kin
  GrowingFit gf(qr, Q0, r, static_cast<Eigen::Index>(order.size()), kCandidates);
  const Eigen::MatrixXd G = Q0.transpose() * X;
  gf.projections() = X - Q0 * G;
  gf.coefficients().topRows(qr.rank()) = G;

  // The independent columns of A0 in pivot order, then the accepted ones.
  Eigen::MatrixXd A(kRows, qr.rank());
  for (Eigen::Index i = 0; i < qr.rank(); ++i) A.col(i) = A0.col(qr.colsPermutation().indices()[i]);
  std::vector<int> accepted;
  for (const int j : order) {
    for (Eigen::Index c = 0; c < kCandidates; ++c)
      if (std::find(accepted.begin(), accepted.end(), c) == accepted.end()) gf.refresh(c);
    // The fresh factorisation of the current columns.
    const Fresh fresh = fresh_fit(A, r);
    ASSERT_EQ(fresh.rank, A.cols());
    const Eigen::MatrixXd& Qf = fresh.Q;
    const Eigen::VectorXd res = r - Qf * (Qf.transpose() * r);
    EXPECT_LE((gf.residual() - res).norm(), 1e-10 * r.norm()) << "after " << accepted.size();
    for (Eigen::Index c = 0; c < kCandidates; ++c) {
      if (std::find(accepted.begin(), accepted.end(), c) != accepted.end()) continue;
      const Eigen::VectorXd xp = X.col(c) - Qf * (Qf.transpose() * X.col(c));
      EXPECT_LE((gf.projections().col(c) - xp).norm(), 1e-10 * X.col(c).norm())
          << "candidate " << c << " after " << accepted.size();
    }
    // The trial's coefficients: those of a fresh solve with the candidate appended.
    const GrowingFit::Trial t = gf.trial(j);
    Eigen::MatrixXd At(kRows, A.cols() + 1);
    At << A, X.col(j);
    const Eigen::VectorXd theta = fresh_fit(At, r).theta;
    EXPECT_LE((t.theta - theta).cwiseAbs().maxCoeff(), 1e-9 * theta.cwiseAbs().maxCoeff())
        << "candidate " << j;
    gf.accept(t);
    accepted.push_back(j);
    A = At;
  }
  ASSERT_EQ(gf.columns(), A.cols());
  // Orthonormal to working precision (one Gram–Schmidt pass leaves ~1e-12 here).
  const Eigen::MatrixXd B = gf.basis();
  const double off =
      (B.transpose() * B - Eigen::MatrixXd::Identity(B.cols(), B.cols())).cwiseAbs().maxCoeff();
  EXPECT_LE(off, 1e-14);
}

}  // namespace
}  // namespace zerog::ident
