// maxentflow: Newton solve of the max-ent dual problem, Eq. (4), for one point.
#pragma once

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include <array>
#include <cmath>
#include <limits>

namespace maxentflow::detail {

/// Scratch arrays for one point's dual solve; reused across points (no allocation
/// once grown). `dx[k]` holds the k-th component of x - x_a (structure of arrays so
/// that the exp and the reductions vectorize).
template <int D>
struct DualWorkspace {
  std::array<Eigen::ArrayXd, D> dx;
  Eigen::ArrayXd beta;  // beta_a = gamma_a / h_a^2
  Eigen::ArrayXd q;     // -beta_a |x - x_a|^2, the prior's exponent
  Eigen::ArrayXd f;     // exponent of Eq. (3) at the current lambda
  Eigen::ArrayXd p;     // p_a of Eq. (5) at the current lambda

  void reserve(Eigen::Index m) {
    if (q.size() >= m) return;
    const Eigen::Index n = std::max<Eigen::Index>(m, 2 * q.size());
    for (auto& a : dx) a.resize(n);
    beta.resize(n);
    q.resize(n);
    f.resize(n);
    p.resize(n);
  }
};

enum class DualStatus { converged, max_iterations, line_search_failed, not_finite };

template <int D>
struct DualResult {
  using Vec = Eigen::Matrix<double, D, 1>;
  using Mat = Eigen::Matrix<double, D, D>;
  Vec lambda = Vec::Zero();
  Vec r = Vec::Zero();  // gradient of ln Z: sum_a p_a (x - x_a), the consistency residual
  Mat J = Mat::Zero();  // Hessian of ln Z: covariance of (x - x_a) under p
  int iterations = 0;
  DualStatus status = DualStatus::converged;
  double residual() const { return r.norm(); }
};

/// ln Z, r and J of Eqs. (3)-(4) at `lambda`, with p left in ws.p. The exponents
/// are shifted by their maximum (log-sum-exp) so that Z never overflows. Three
/// passes: exponents and their maximum, the (vectorized) exp, all moments at once.
template <int D>
double evaluate_dual(DualWorkspace<D>& ws, Eigen::Index m,
                     const Eigen::Matrix<double, D, 1>& lambda, Eigen::Matrix<double, D, 1>& r,
                     Eigen::Matrix<double, D, D>& J) {
  const double* q = ws.q.data();
  const double* x0 = ws.dx[0].data();
  const double* x1 = ws.dx[D > 1 ? 1 : 0].data();
  const double* x2 = ws.dx[D > 2 ? 2 : 0].data();
  double* f = ws.f.data();
  const double l0 = lambda(0), l1 = D > 1 ? lambda(D > 1 ? 1 : 0) : 0.0,
               l2 = D > 2 ? lambda(D > 2 ? 2 : 0) : 0.0;
  double fmax = -std::numeric_limits<double>::infinity();
#pragma omp simd reduction(max : fmax)
  for (Eigen::Index j = 0; j < m; ++j) {
    double e = q[j] + l0 * x0[j];
    if constexpr (D > 1) e += l1 * x1[j];
    if constexpr (D > 2) e += l2 * x2[j];
    f[j] = e;
    fmax = e > fmax ? e : fmax;
  }
  ws.p.head(m) = (ws.f.head(m) - fmax).exp();
  double* p = ws.p.data();
  double Z = 0, s0 = 0, s1 = 0, s2 = 0, S00 = 0, S01 = 0, S02 = 0, S11 = 0, S12 = 0, S22 = 0;
#pragma omp simd reduction(+ : Z, s0, s1, s2, S00, S01, S02, S11, S12, S22)
  for (Eigen::Index j = 0; j < m; ++j) {
    const double w = p[j], a = w * x0[j];
    Z += w;
    s0 += a;
    S00 += a * x0[j];
    if constexpr (D > 1) {
      const double b = w * x1[j];
      s1 += b;
      S01 += a * x1[j];
      S11 += b * x1[j];
      if constexpr (D > 2) {
        const double c = w * x2[j];
        s2 += c;
        S02 += a * x2[j];
        S12 += b * x2[j];
        S22 += c * x2[j];
      }
    }
  }
  const double iz = 1.0 / Z;
  ws.p.head(m) *= iz;
  const double s[3] = {s0 * iz, s1 * iz, s2 * iz};
  const double S[3][3] = {{S00, S01, S02}, {S01, S11, S12}, {S02, S12, S22}};
  for (int k = 0; k < D; ++k) r(k) = s[k];
  for (int k = 0; k < D; ++k)
    for (int l = 0; l < D; ++l) J(k, l) = S[k][l] * iz - s[k] * s[l];
  return fmax + std::log(Z);
}

/// Newton's method on lambda for min ln Z (Eq. 4), globalized by backtracking on
/// ln Z (convex, so a descent direction always exists). The Hessian is the
/// covariance of the neighbours; near a hull edge it becomes ill-conditioned and
/// its small eigenvalues are floored relative to the largest (regularization).
/// Converged when |r| <= tol_abs (r is exactly the linear-reproduction error).
template <int D>
DualResult<D> solve_dual(DualWorkspace<D>& ws, Eigen::Index m,
                         const Eigen::Matrix<double, D, 1>& lambda0, double tol_abs,
                         int max_iterations) {
  using Vec = Eigen::Matrix<double, D, 1>;
  using Mat = Eigen::Matrix<double, D, D>;
  DualResult<D> res;
  res.lambda = lambda0;
  double lnZ = evaluate_dual<D>(ws, m, res.lambda, res.r, res.J);
  for (int it = 0;; ++it) {
    res.iterations = it;
    if (!std::isfinite(lnZ) || !res.r.allFinite()) {
      res.status = DualStatus::not_finite;
      return res;
    }
    if (res.r.norm() <= tol_abs) {
      res.status = DualStatus::converged;
      return res;
    }
    if (it >= max_iterations) {
      res.status = DualStatus::max_iterations;
      return res;
    }
    // Newton direction -J^{-1} r, with the spectrum floored (regularization).
    Vec dir;
    if constexpr (D == 1) {
      const double j = std::max(res.J(0, 0), 1e-300);
      dir(0) = -res.r(0) / j;
    } else if constexpr (D == 2) {  // closed form; shift if the smallest eigenvalue is tiny
      double a = res.J(0, 0), b = res.J(0, 1), c = res.J(1, 1);
      const double tr = a + c;
      const double lmin = 0.5 * tr - std::sqrt(0.25 * (a - c) * (a - c) + b * b);
      const double floor = std::max(1e-14 * tr, 1e-300);
      if (lmin < floor) {
        a += floor - lmin;
        c += floor - lmin;
      }
      const double det = a * c - b * b;
      dir(0) = -(c * res.r(0) - b * res.r(1)) / det;
      dir(1) = -(a * res.r(1) - b * res.r(0)) / det;
    } else {
      Eigen::SelfAdjointEigenSolver<Mat> eig;
      eig.computeDirect(res.J);
      Vec ev = eig.eigenvalues();
      const double floor = std::max(1e-14 * ev.maxCoeff(), 1e-300);
      for (int k = 0; k < D; ++k) ev(k) = std::max(ev(k), floor);
      dir = -(eig.eigenvectors() * ((eig.eigenvectors().transpose() * res.r).array() / ev.array())
                                        .matrix());
    }
    const double slope = res.r.dot(dir);  // < 0: a descent direction
    // Backtracking (Armijo) with a round-off allowance on ln Z.
    const double slack = 8 * std::numeric_limits<double>::epsilon() * (std::abs(lnZ) + 1.0);
    double step = 1.0;
    bool accepted = false;
    Vec r_trial;
    Mat J_trial;
    for (int ls = 0; ls < 60; ++ls) {
      const Vec trial = res.lambda + step * dir;
      const double lnZ_trial = evaluate_dual<D>(ws, m, trial, r_trial, J_trial);
      if (std::isfinite(lnZ_trial) && lnZ_trial <= lnZ + 1e-4 * step * slope + slack) {
        res.lambda = trial;
        res.r = r_trial;
        res.J = J_trial;
        lnZ = lnZ_trial;
        accepted = true;
        break;
      }
      step *= 0.5;
    }
    if (!accepted) {
      // ws.p holds the last trial; restore the state at res.lambda for the caller.
      lnZ = evaluate_dual<D>(ws, m, res.lambda, res.r, res.J);
      res.status = DualStatus::line_search_failed;
      res.iterations = it + 1;
      return res;
    }
  }
}

}  // namespace maxentflow::detail
