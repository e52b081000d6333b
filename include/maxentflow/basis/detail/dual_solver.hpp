// maxentflow: Newton solve of the max-ent dual problem, Eq. (4), for one point.
#pragma once

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>

namespace maxentflow::detail {

/// Lanes of the dual's loops: supports are padded to a multiple of this, so
/// that every loop runs whole SIMD vectors (8 doubles: one AVX-512 register).
inline constexpr int dual_lanes = 8;

/// 1/k! for k = 0..17 (k! is exact in double up to 18!).
inline constexpr std::array<double, 18> inverse_factorials = [] {
  std::array<double, 18> c{};
  double f = 1.0;
  for (int k = 0; k < 18; ++k) {
    if (k > 1) f *= k;
    c[static_cast<std::size_t>(k)] = 1.0 / f;
  }
  return c;
}();

/// e^t by its Taylor polynomial of degree N, Horner's scheme.
template <int N>
inline double taylor_exp(double t) {
  static_assert(N >= 1 && N < 18, "Taylor degree 1..17");
  double e = inverse_factorials[N];
  for (int k = N - 1; k >= 0; --k) e = e * t + inverse_factorials[static_cast<std::size_t>(k)];
  return e;
}

/// exp(x) to within 1 ulp for x in [-708, 709] (clamped there; NaN stays NaN),
/// written so that a loop over it vectorizes: x = k ln 2 + r, |r| <= ln(2)/2,
/// e^r by its Taylor polynomial of degree 13 (truncation < 5e-18), 2^k by
/// setting the exponent bits. libm's exp is a scalar call per entry, and
/// Eigen's vectorized exp pays a division. Plain a * b + c, not std::fma:
/// under -frounding-math (CGAL's) a call to fma blocks vectorization.
inline double exp_kernel(double x) {
  x = x < -708.0 ? -708.0 : (x > 709.0 ? 709.0 : x);
  constexpr double shifter = 0x1.8p52;  // adding it rounds to an integer kept in the low bits
  const double t = x * 1.4426950408889634 + shifter;
  const double k = t - shifter;
  double r = -k * 6.93147180369123816490e-01 + x;  // ln 2 split in two: k ln2_hi is exact
  r = -k * 1.90821492927058770002e-10 + r;
  const double e = taylor_exp<13>(r);
  const std::uint64_t two_k = (std::bit_cast<std::uint64_t>(t) + 1023) << 52;
  return e * std::bit_cast<double>(two_k);
}

/// Scratch arrays for one point's dual solve; reused across points (no allocation
/// once grown). `dx[k]` holds the k-th component of x - x_a (structure of arrays so
/// that the exp and the reductions vectorize). Capacity is a multiple of
/// dual_lanes; solve_dual fills the padding with entries of weight ~0.
template <int D>
struct DualWorkspace {
  std::array<Eigen::ArrayXd, D> dx;
  Eigen::ArrayXd beta;  // beta_a = gamma_a / h_a^2
  Eigen::ArrayXd q;     // -beta_a |x - x_a|^2, the prior's exponent
  Eigen::ArrayXd p;     // p_a of Eq. (5) (during a solve: unnormalized weights, p_a = p / Z)
  double Z = 1;         // sum of the weights of the last evaluation
  std::array<double, D> reach{};  // max_a |(x - x_a)_k| over the support

  static Eigen::Index padded(Eigen::Index m) { return (m + dual_lanes - 1) / dual_lanes * dual_lanes; }

  void reserve(Eigen::Index m) {
    if (q.size() >= padded(m)) return;
    const Eigen::Index n = padded(std::max<Eigen::Index>(m, 2 * q.size()));
    for (auto& a : dx) a.resize(n);
    beta.resize(n);
    q.resize(n);
    p.resize(n);
  }

  /// Entries m .. padded(m) - 1: at x_a = x, with a prior weight that underflows
  /// against any real entry's.
  void pad(Eigen::Index m) {
    for (int k = 0; k < D; ++k) reach[k] = dx[k].head(m).abs().maxCoeff();
    for (Eigen::Index j = m; j < padded(m); ++j) {
      for (auto& a : dx) a(j) = 0.0;
      beta(j) = 0.0;
      q(j) = -1e300;
    }
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
  double shift = 0;  ///< the exponents' shift of the last evaluation (a nearby point's first guess)
  double residual() const { return r.norm(); }
};

/// ln Z as shift + ln(Z_shifted): comparing two values with the same shift
/// needs no logarithm.
struct LogPartition {
  double shift = 0;
  double Z = 1;
  double value() const { return shift + std::log(Z); }
  bool finite() const { return std::isfinite(shift) && std::isfinite(Z) && Z > 0; }
};

/// ln Z, r and J of Eqs. (3)-(4) at `lambda` (m entries, padded), with the
/// weights exp(f_a - shift) left in ws.p unnormalized (p_a = ws.p / ws.Z).
/// The exponents f_a are shifted so that Z neither overflows nor underflows:
/// by `shift`, a value near max f (ln Z at a nearby lambda), which saves a pass
/// over the support; where that leaves Z outside [1e-200, 1e200], or shift is
/// NaN, by max f itself. One fused pass computes exponent, exp and moments.
/// Where ws.p holds the weights at lambda - step with this shift and step is
/// small (|step . (x - x_a)| <= 0.05 for all a), the weights are updated by
/// exp(step . (x - x_a)) from its Taylor polynomial (degree 9, or 5 below
/// 1e-3: truncation < 3e-20) instead of a whole exp: Newton's last steps.
/// Inlined into solve_dual's loop (1 M points: ~3 % faster than a call).
template <int D>
[[gnu::always_inline]] inline LogPartition evaluate_dual(DualWorkspace<D>& ws, Eigen::Index m,
                                                         const Eigen::Matrix<double, D, 1>& lambda,
                                                         Eigen::Matrix<double, D, 1>& r, Eigen::Matrix<double, D, D>& J,
                                                         double shift = std::numeric_limits<double>::quiet_NaN(),
                                                         const Eigen::Matrix<double, D, 1>* step = nullptr) {
  constexpr int W = dual_lanes;
  const Eigen::Index mp = DualWorkspace<D>::padded(m);
  const double* q = ws.q.data();
  const double* x0 = ws.dx[0].data();
  const double* x1 = ws.dx[D > 1 ? 1 : 0].data();
  const double* x2 = ws.dx[D > 2 ? 2 : 0].data();
  double* p = ws.p.data();
  const double l0 = lambda(0), l1 = D > 1 ? lambda(D > 1 ? 1 : 0) : 0.0,
               l2 = D > 2 ? lambda(D > 2 ? 2 : 0) : 0.0;
  int degree = 0;  // of the small-step update; 0: the whole exp
  if (step && !std::isnan(shift)) {
    double a = 0;
    for (int k = 0; k < D; ++k) a += std::abs((*step)(k)) * ws.reach[k];
    degree = a <= 1e-3 ? 5 : (a <= 0.05 ? 9 : 0);
  }
  const double d0 = step && degree ? (*step)(0) : 0.0, d1 = step && degree && D > 1 ? (*step)(D > 1 ? 1 : 0) : 0.0,
               d2 = step && degree && D > 2 ? (*step)(D > 2 ? 2 : 0) : 0.0;
  for (int attempt = 0;; ++attempt) {
    if (std::isnan(shift)) {  // the exact maximum
      double fmax = -std::numeric_limits<double>::infinity();
#pragma omp simd reduction(max : fmax)
      for (Eigen::Index j = 0; j < m; ++j) {
        double e = q[j] + l0 * x0[j];
        if constexpr (D > 1) e += l1 * x1[j];
        if constexpr (D > 2) e += l2 * x2[j];
        fmax = e > fmax ? e : fmax;
      }
      shift = fmax;
    }
    // Per-lane partial sums (one register each), added up after the loop.
    double aZ[W] = {}, a0[W] = {}, a1[W] = {}, a2[W] = {}, a00[W] = {}, a01[W] = {}, a02[W] = {},
           a11[W] = {}, a12[W] = {}, a22[W] = {};
    const auto pass = [&]<int Degree>() {
      for (Eigen::Index c = 0; c < mp; c += W) {
#pragma omp simd
        for (int l = 0; l < W; ++l) {
          const Eigen::Index j = c + l;
          double w;
          if constexpr (Degree == 0) {
            double e = q[j] + l0 * x0[j] - shift;
            if constexpr (D > 1) e += l1 * x1[j];
            if constexpr (D > 2) e += l2 * x2[j];
            w = exp_kernel(e);
          } else {
            double t = d0 * x0[j];
            if constexpr (D > 1) t += d1 * x1[j];
            if constexpr (D > 2) t += d2 * x2[j];
            w = p[j] * taylor_exp<Degree>(t);
          }
          const double a = w * x0[j];
          p[j] = w;
          aZ[l] += w;
          a0[l] += a;
          a00[l] += a * x0[j];
          if constexpr (D > 1) {
            const double b = w * x1[j];
            a1[l] += b;
            a01[l] += a * x1[j];
            a11[l] += b * x1[j];
            if constexpr (D > 2) {
              const double g = w * x2[j];
              a2[l] += g;
              a02[l] += a * x2[j];
              a12[l] += b * x2[j];
              a22[l] += g * x2[j];
            }
          }
        }
      }
    };
    if (degree == 5)
      pass.template operator()<5>();
    else if (degree == 9)
      pass.template operator()<9>();
    else
      pass.template operator()<0>();
    double Z = 0, s[3] = {0, 0, 0}, S[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
    for (int l = 0; l < W; ++l) {
      Z += aZ[l];
      s[0] += a0[l];
      s[1] += a1[l];
      s[2] += a2[l];
      S[0][0] += a00[l];
      S[0][1] += a01[l];
      S[0][2] += a02[l];
      S[1][1] += a11[l];
      S[1][2] += a12[l];
      S[2][2] += a22[l];
    }
    if (attempt == 0 && !(Z >= 1e-200 && Z <= 1e200)) {  // the guessed shift was too far off
      shift = std::numeric_limits<double>::quiet_NaN();
      degree = 0;
      continue;
    }
    const double iz = 1.0 / Z;
    ws.Z = Z;
    for (int k = 0; k < D; ++k) r(k) = s[k] * iz;
    for (int k = 0; k < D; ++k)
      for (int l = k; l < D; ++l) J(k, l) = J(l, k) = S[k][l] * iz - r(k) * r(l);
    return {shift, Z};
  }
}

/// Newton's method on lambda for min ln Z (Eq. 4), globalized by backtracking on
/// ln Z (convex, so a descent direction always exists). The Hessian is the
/// covariance of the neighbours; near a hull edge it becomes ill-conditioned and
/// its small eigenvalues are floored relative to the largest (regularization).
/// Converged when |r| <= tol_abs (r is exactly the linear-reproduction error).
/// ws must hold m entries and room for their padding; p of Eq. (5) is left in
/// ws.p.
template <int D>
DualResult<D> solve_dual(DualWorkspace<D>& ws, Eigen::Index m,
                         const Eigen::Matrix<double, D, 1>& lambda0, double tol_abs,
                         int max_iterations, double shift0 = std::numeric_limits<double>::quiet_NaN()) {
  using Vec = Eigen::Matrix<double, D, 1>;
  using Mat = Eigen::Matrix<double, D, D>;
  ws.pad(m);
  DualResult<D> res;
  res.lambda = lambda0;
  LogPartition lnZ = evaluate_dual<D>(ws, m, res.lambda, res.r, res.J, shift0);
  const auto finish = [&](DualStatus status) {
    res.status = status;
    res.shift = lnZ.shift;
    ws.p.head(m) *= 1.0 / ws.Z;
    return res;
  };
  for (int it = 0;; ++it) {
    res.iterations = it;
    if (!lnZ.finite() || !res.r.allFinite()) return finish(DualStatus::not_finite);
    if (res.r.squaredNorm() <= tol_abs * tol_abs) return finish(DualStatus::converged);
    if (it >= max_iterations) return finish(DualStatus::max_iterations);
    // Newton direction -J^{-1} r, with the spectrum floored (regularization).
    Vec dir;
    if constexpr (D == 1) {
      const double j = std::max(res.J(0, 0), 1e-300);
      dir(0) = -res.r(0) / j;
    } else if constexpr (D == 2) {  // closed form; shift if the smallest eigenvalue is tiny
      double a = res.J(0, 0), b = res.J(0, 1), c = res.J(1, 1);
      const double tr = a + c;
      const double floor = std::max(1e-14 * tr, 1e-300);
      // lambda_min >= det / tr: only a small determinant needs the eigenvalue.
      if (!(a * c - b * b >= floor * tr)) {
        const double lmin = 0.5 * tr - std::sqrt(0.25 * (a - c) * (a - c) + b * b);
        if (lmin < floor) {
          a += floor - lmin;
          c += floor - lmin;
        }
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
    // Backtracking (Armijo) with a round-off allowance on ln Z; trials share
    // the current shift, so the test is on Z's ratio where 1 + y bounds e^y.
    const double slack = 8 * std::numeric_limits<double>::epsilon() * (std::abs(lnZ.shift) + 4.0);
    double step = 1.0;
    bool accepted = false;
    Vec r_trial;
    Mat J_trial;
    for (int ls = 0; ls < 60; ++ls) {
      const Vec delta = step * dir, trial = res.lambda + delta;
      // ws.p holds the weights at res.lambda until a trial is rejected.
      const LogPartition t = evaluate_dual<D>(ws, m, trial, r_trial, J_trial, lnZ.shift, ls == 0 ? &delta : nullptr);
      const double y = 1e-4 * step * slope + slack;
      const bool decrease = t.finite() && ((t.shift == lnZ.shift && t.Z <= lnZ.Z * (1.0 + y)) ||
                                           t.value() <= lnZ.value() + y);
      if (decrease) {
        res.lambda = trial;
        res.r = r_trial;
        res.J = J_trial;
        lnZ = t;
        accepted = true;
        break;
      }
      step *= 0.5;
    }
    if (!accepted) {
      // ws.p holds the last trial; restore the state at res.lambda for the caller.
      lnZ = evaluate_dual<D>(ws, m, res.lambda, res.r, res.J, lnZ.shift);
      res.iterations = it + 1;
      return finish(DualStatus::line_search_failed);
    }
  }
}

}  // namespace maxentflow::detail
