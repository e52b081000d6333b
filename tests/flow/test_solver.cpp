// The nonlinear solver: consistent Newton tangent, quadratic convergence,
// thread-count independence, loud failures; GMRES and its preconditioner.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <sstream>
#include <type_traits>
#include <utility>
#include <vector>

#include <Eigen/SparseLU>
#include <dlfcn.h>

#include <maxentflow/solver/blas_gemv_forward.hpp>  // this test program's one translation unit that includes it

#include "../support/flow_problems.hpp"

using namespace maxentflow;
using maxentflow::test::block_nodes;
using maxentflow::test::FlowProblem;

namespace {

// Plane-strain compression of a block with a body force and a traction, so that
// the flow is not homogeneous and Newton has work to do.
FlowProblem<NortonHoff> compression(double n, bool perturbed = true, int nx = 13) {
  const double W = 4, H = 3, V = 0.1;
  FlowProblem<NortonHoff> P(block_nodes(nx, 10, W, H, perturbed), Geometry::plane_strain,
                            NortonHoff(150.0, n, 1e-5));
  const double tol = 1e-9;
  P.velocity(on_line({0, 0}, {1, 0}, tol), {1, 0}, 0.0, "symmetry");
  P.velocity(on_line({0, 0}, {0, 1}, tol), {0, 1}, 0.0, "bottom");
  P.velocity(on_line({0, 0}, {0, 1}, tol), {1, 0}, 0.0, "bottom sticking");
  P.velocity(on_line({0, H}, {0, 1}, tol), {0, 1}, -V, "top");
  P.system->add_traction(on_line({W, 0}, {1, 0}, tol),
                         [](const Eigen::Vector2d& x) { return Eigen::Vector2d(-5.0 * x.y(), 0); });
  P.system->assembler().set_body_force(Eigen::Vector2d(0, -2.0));
  return P;
}

}  // namespace

TEST_CASE("the Newton tangent is the derivative of the residual", "[flow][solver]") {
  for (double n : {0.2, 1.0}) {
    CAPTURE(n);
    auto P = compression(n);
    NonlinearSolver<> solver;
    Eigen::VectorXd X;
    solver.solve(*P.system, X);
    // Away from the solution: perturb it.
    std::mt19937 rng(3);
    std::normal_distribution<double> g;
    Eigen::VectorXd dX(X.size());
    for (Eigen::Index k = 0; k < X.size(); ++k) dX[k] = g(rng);
    X += 0.05 * dX.cwiseProduct(X.cwiseAbs());
    SystemPattern::Matrix A;
    Eigen::VectorXd R, Rp, Rm;
    P.system->assemble(X, Linearization::newton, A, R);
    for (Eigen::Index k = 0; k < X.size(); ++k) dX[k] = g(rng) * (std::abs(X[k]) + 1e-3);
    const double eps = 1e-6;
    P.system->residual(X + eps * dX, Rp);
    P.system->residual(X - eps * dX, Rm);
    const Eigen::VectorXd fd = (Rp - Rm) / (2 * eps);
    const Eigen::VectorXd an = A * dX;
    CHECK((fd - an).norm() <= 1e-6 * an.norm());
    // The matrix-free product is that matrix's, to round-off.
    Eigen::VectorXd Jv;
    P.system->apply_tangent(X, dX, Jv);
    CHECK((Jv - an).norm() <= 1e-12 * an.norm());
    // The Picard matrix is not the tangent when n != 1.
    P.system->assemble(X, Linearization::picard, A, R);
    const double picard_gap = (fd - A * dX).norm() / an.norm();
    if (n != 1.0) CHECK(picard_gap > 1e-3);
    else CHECK(picard_gap < 1e-6);
  }
}

TEST_CASE("Newton converges quadratically near the solution", "[flow][solver]") {
  auto P = compression(0.2);
  NonlinearSolver<> solver;
  Eigen::VectorXd X;
  const auto rep = solver.solve(*P.system, X);
  INFO(rep.log());
  REQUIRE(rep.converged);
  REQUIRE(rep.newton >= 2);
  // Three consecutive full Newton steps in the asymptotic range: the observed
  // order log(r2/r1) / log(r1/r0) is ~2 for a consistent tangent, ~1 otherwise.
  int checked = 0;
  const auto& h = rep.history;
  for (std::size_t k = 0; k + 2 < h.size(); ++k) {
    bool full = true;
    for (std::size_t j = k; j <= k + 2; ++j)
      full = full && h[j].kind == Linearization::newton && h[j].step == 1.0;
    if (!full || h[k].residual > 1e-2 || h[k + 2].residual < 1e-13) continue;
    const double order = std::log(h[k + 2].residual / h[k + 1].residual) /
                         std::log(h[k + 1].residual / h[k].residual);
    CAPTURE(k, h[k].residual, h[k + 1].residual, h[k + 2].residual, order);
    CHECK(order > 1.6);
    ++checked;
  }
  CHECK(checked >= 1);
}

TEST_CASE("matrix-free tangent, axisymmetric: the assembled Newton matrix's product", "[flow][solver]") {
  const double W = 2, H = 3;
  FlowProblem<NortonHoff> P(block_nodes(9, 12, W, H, true), Geometry::axisymmetric, NortonHoff(150.0, 0.2, 1e-5));
  P.velocity(on_line({0, 0}, {1, 0}, 1e-9), {1, 0}, 0.0, "axis");
  P.velocity(on_line({0, 0}, {0, 1}, 1e-9), {0, 1}, 0.0, "bottom");
  P.velocity(on_line({0, 0}, {0, 1}, 1e-9), {1, 0}, 0.0, "bottom sticking");
  P.velocity(on_line({0, H}, {0, 1}, 1e-9), {0, 1}, -0.1, "top");
  const int n = P.system->size();
  std::mt19937 rng(5);
  std::normal_distribution<double> g;
  Eigen::VectorXd X(n), v(n), Jv;
  for (int k = 0; k < n; ++k) X[k] = g(rng), v[k] = g(rng);
  SystemPattern::Matrix A;
  Eigen::VectorXd R;
  P.system->assemble(X, Linearization::newton, A, R);
  P.system->apply_tangent(X, v, Jv);
  CHECK((Jv - A * v).norm() <= 1e-12 * (A * v).norm());
  // A new X gets new point operators.
  X *= 0.5;
  P.system->assemble(X, Linearization::newton, A, R);
  P.system->apply_tangent(X, v, Jv);
  CHECK((Jv - A * v).norm() <= 1e-12 * (A * v).norm());
  // The Picard matrix's product, from the same point operators.
  const Eigen::VectorXd Newton_v = Jv;
  P.system->assemble(X, Linearization::picard, A, R);
  P.system->apply_tangent(X, v, Jv, Linearization::picard);
  CHECK((Jv - A * v).norm() <= 1e-12 * (A * v).norm());
  CHECK((Newton_v - A * v).norm() > 1e-3 * (A * v).norm());  // n = 0.2: the two differ
}

namespace {
// FlowSystem, counting its matrix assemblies.
struct CountingSystem {
  FlowSystem<NortonHoff>& s;
  int assemblies = 0;
  int size() { return s.size(); }
  long structure_generation() { return s.structure_generation(); }
  void assemble(const Eigen::VectorXd& X, Linearization k, SystemPattern::Matrix& A, Eigen::VectorXd& R) {
    ++assemblies;
    s.assemble(X, k, A, R);
  }
  void residual(const Eigen::VectorXd& X, Eigen::VectorXd& R) { s.residual(X, R); }
  double relative_residual(const Eigen::VectorXd& R) const { return s.relative_residual(R); }
  double velocity_norm(const Eigen::VectorXd& X) const { return s.velocity_norm(X); }
  void assemble_preconditioner(const Eigen::VectorXd& X, SystemPattern::Matrix& P) { s.assemble_preconditioner(X, P); }
  long preconditioner_generation() { return s.preconditioner_generation(); }
  const DofLayout& layout() { return s.layout(); }
  void apply_tangent(const Eigen::VectorXd& X, const Eigen::VectorXd& v, Eigen::VectorXd& Jv,
                     Linearization k = Linearization::newton) {
    s.apply_tangent(X, v, Jv, k);
  }
  bool symmetric(Linearization k) const { return s.symmetric(k); }
};
static_assert(MatrixFreePicardSystem<CountingSystem>);
static_assert(SymmetricSystem<CountingSystem>);

// compression(0.2) solved by the direct policy: the Krylov tests' reference.
Eigen::VectorXd direct_compression() {
  auto P = compression(0.2);
  Eigen::VectorXd X;
  NonlinearSolver<> direct;
  REQUIRE(direct.solve(*P.system, X).converged);
  return X;
}
}  // namespace

TEST_CASE("warm-started Picard iterations that a kept LU serves assemble no matrix; the same solution",
          "[flow][solver][gmres]") {
  const Eigen::VectorXd X_direct = direct_compression();

  NonlinearSolverParams prm;
  prm.newton_from_warm_start = false;  // as the extrusion and cutting examples: Picard first
  NonlinearSolver<GmresSolver<>> s(prm);
  auto P = compression(0.2);
  CountingSystem sys{*P.system};
  Eigen::VectorXd X;
  REQUIRE(s.solve(sys, X).converged);
  // Warm starts 5 % off: Picard (kept Picard LU), then Newton (kept Newton LU).
  for (int solve = 0; solve < 2; ++solve) {
    CAPTURE(solve);
    X = (1.0 + 0.05 * (solve + 1)) * X_direct;
    sys.assemblies = 0;
    const SolveReport r = s.solve(sys, X);
    INFO(r.log());
    REQUIRE(r.converged);
    CHECK(r.picard >= 2);
    CHECK(r.direct_fallbacks == 0);
    // Only the matrices of the LUs made: none for the other iterations.
    CHECK(sys.assemblies == r.preconditioner_updates);
    CHECK(sys.assemblies < r.picard + r.newton);
    CHECK((X - X_direct).lpNorm<Eigen::Infinity>() <= 1e-6 * X_direct.lpNorm<Eigen::Infinity>());
  }
}

TEST_CASE("iterations the linear-triangle companion serves are matrix-free: no matrix assembled, the same solution",
          "[flow][solver][gmres]") {
  const Eigen::VectorXd X_direct = direct_compression();
  // Every iteration with the companion (as above kept_lu_max_unknowns); GMRES
  // with at most `iterations` (2: it cannot converge, the direct fallback
  // serves).
  auto run = [&](bool matrix_free, int iterations, int& assemblies) {
    NonlinearSolverParams prm;
    prm.kept_lu = false;
    prm.matrix_free_krylov = matrix_free;
    NonlinearSolver<GmresSolver<>> s(prm);
    s.linear_solver().parameters().restart = std::min(iterations, s.linear_solver().parameters().restart);
    s.linear_solver().parameters().max_iterations = iterations;
    auto P = compression(0.2);
    CountingSystem sys{*P.system};
    Eigen::VectorXd X;
    const SolveReport r = s.solve(sys, X);
    INFO(r.log());
    REQUIRE(r.converged);
    CHECK((X - X_direct).lpNorm<Eigen::Infinity>() <= 1e-6 * X_direct.lpNorm<Eigen::Infinity>());
    assemblies = sys.assemblies;
    return r;
  };
  for (const bool matrix_free : {true, false}) {
    CAPTURE(matrix_free);
    int assemblies = 0;
    const SolveReport r = run(matrix_free, GmresParams{}.max_iterations, assemblies);
    CHECK(r.newton >= 2);
    CHECK(r.direct_fallbacks == 0);
    CHECK(assemblies == (matrix_free ? 0 : r.picard + r.newton + 1));  // + the converged iterate's
  }
  int assemblies = 0;  // GMRES that cannot converge: the fallback assembles the matrix it needs
  const SolveReport r = run(true, 2, assemblies);
  CHECK(r.direct_fallbacks >= 1);
  CHECK(assemblies >= 1);
}

TEST_CASE("Newton with the kept LU: the direct solution; the LU kept for one layout, made again for another",
          "[flow][solver][gmres]") {
  const Eigen::VectorXd X_direct = direct_compression();
  Eigen::VectorXd X_kept;
  NonlinearSolver<> direct;

  NonlinearSolver<GmresSolver<>> s;  // kept_lu on by default
  auto P1 = compression(0.2);
  const SolveReport first = s.solve(*P1.system, X_kept);
  INFO(first.log());
  REQUIRE(first.converged);
  CHECK(first.newton >= 2);
  CHECK(first.direct_fallbacks == 0);
  CHECK((X_kept - X_direct).lpNorm<Eigen::Infinity>() <= 1e-6 * X_direct.lpNorm<Eigen::Infinity>());
  const int lu_before = s.linear_solver().kept_factorizations();
  CHECK(lu_before >= 1);

  // Another system of the same layout, from a perturbed start: the LU is kept.
  auto P2 = compression(0.2);
  Eigen::VectorXd X2 = 1.01 * X_kept;
  const SolveReport again = s.solve(*P2.system, X2);
  INFO(again.log());
  REQUIRE(again.converged);
  CHECK(again.picard == 0);
  CHECK(s.linear_solver().kept_factorizations() == lu_before);
  CHECK(again.max_linear_iterations <= NonlinearSolverParams{}.kept_lu_iterations);
  CHECK((X2 - X_direct).lpNorm<Eigen::Infinity>() <= 1e-6 * X_direct.lpNorm<Eigen::Infinity>());

  // Other nodes: a new LU.
  auto P3 = compression(0.2, true, 14);
  Eigen::VectorXd X3;
  REQUIRE(s.solve(*P3.system, X3).converged);
  CHECK(s.linear_solver().kept_factorizations() > lu_before);

  // The same nodes with multiplier rows added (the right side held
  // vertically): the LU of P3 cannot serve, that of P2's layout can through
  // the layout map; either way the direct solution.
  auto P4 = compression(0.2);
  P4.velocity(on_line({4, 0}, {1, 0}, 1e-9), {0, 1}, 0.0, "right side held");
  auto P4d = compression(0.2);
  P4d.velocity(on_line({4, 0}, {1, 0}, 1e-9), {0, 1}, 0.0, "right side held");
  Eigen::VectorXd X4 = X_kept, X4d;
  REQUIRE(!(P4.system->layout() == P2.system->layout()));
  REQUIRE(direct.solve(*P4d.system, X4d).converged);
  REQUIRE(s.solve(*P4.system, X4).converged);
  CHECK((X4 - X4d).lpNorm<Eigen::Infinity>() <= 1e-6 * X4d.lpNorm<Eigen::Infinity>());
}

TEST_CASE("a kept Newton LU of the symmetric part that leaves GMRES short: the LU of the whole tangent",
          "[flow][solver][gmres]") {
  const Eigen::VectorXd X_direct = direct_compression();
  Eigen::VectorXd X;
  // One GMRES iteration a try: an LU of newton_symmetric's matrix (d tau / d v
  // left out) cannot bring it to the tolerance, the whole tangent's can.
  std::ostringstream log;
  NonlinearSolverParams prm;
  prm.kept_lu_iterations = 1;
  prm.eta_max = prm.eta_kept_lu = 1e-11;  // (the asymmetry is ~1e-5 of the tangent)
  prm.log = &log;
  for (bool symmetric : {true, false}) {
    prm.symmetric_lu = symmetric;
    NonlinearSolver<GmresSolver<>> s(prm);
    auto P = compression(0.2);
    X.resize(0);
    log.str("");
    const SolveReport rep = s.solve(*P.system, X);
    INFO(log.str());
    REQUIRE(rep.converged);
    CHECK((X - X_direct).lpNorm<Eigen::Infinity>() <= 1e-6 * X_direct.lpNorm<Eigen::Infinity>());
    // Only where the kept LU is of the symmetric part.
    CHECK((log.str().find("LU made: symmetric part short") != std::string::npos) == symmetric);
  }
}

TEST_CASE("results do not depend on the thread count", "[flow][solver]") {
  const int threads = max_threads();
  Eigen::VectorXd X1, X2;
  {
    set_threads(1);
    auto P = compression(0.2);
    NonlinearSolver<> s;
    s.solve(*P.system, X1);
  }
  {
    set_threads(std::max(2, threads));
    auto P = compression(0.2);
    NonlinearSolver<> s;
    s.solve(*P.system, X2);
  }
  set_threads(threads);
  CHECK((X1 - X2).norm() <= 1e-12 * X1.norm());
}

TEST_CASE("the BLAS thread count is set where the BLAS is OpenBLAS; results do not depend on it",
          "[flow][solver]") {
  using Getter = int (*)();
  void* get = dlsym(RTLD_DEFAULT, "openblas_get_num_threads");
  if (!get) {
    CHECK(!set_blas_threads(1));  // no OpenBLAS in this process: nothing to set
    return;
  }
  const int before = reinterpret_cast<Getter>(get)();
  Eigen::VectorXd X1, X2;
  for (int n : {1, 2}) {
    REQUIRE(set_blas_threads(n));
    CHECK(reinterpret_cast<Getter>(get)() == n);
    auto P = compression(0.2);
    NonlinearSolver<> s;
    s.solve(*P.system, n == 1 ? X1 : X2);
  }
  set_blas_threads(before);
  CHECK((X1 - X2).norm() <= 1e-10 * X1.norm());
}

TEST_CASE("an unconstrained rigid-body mode fails loudly", "[flow][solver]") {
  // Only the top plate: the block can slide sideways.
  FlowProblem<NortonHoff> P(block_nodes(6, 6, 1, 1, false), Geometry::plane_strain, NortonHoff());
  P.velocity(on_line({0, 1}, {0, 1}, 1e-9), {0, 1}, -0.1, "top");
  NonlinearSolver<> solver;
  Eigen::VectorXd X;
  CHECK_THROWS_AS(solver.solve(*P.system, X), Error);
}

TEST_CASE("a solve that cannot converge in the allowed iterations throws with its history",
          "[flow][solver]") {
  auto P = compression(0.2);
  NonlinearSolverParams prm;
  prm.max_iterations = 2;
  NonlinearSolver<> solver(prm);
  Eigen::VectorXd X;
  try {
    solver.solve(*P.system, X);
    FAIL("no exception");
  } catch (const Error& e) {
    CHECK_THAT(std::string(e.what()), Catch::Contains("no convergence") && Catch::Contains("picard"));
  }
}

namespace {
// FlowSystem with Newton's matrix negated: every Newton direction climbs.
struct ClimbingNewton {
  FlowSystem<NortonHoff>& s;
  int size() { return s.size(); }
  long structure_generation() { return s.structure_generation(); }
  void assemble(const Eigen::VectorXd& X, Linearization k, SystemPattern::Matrix& A, Eigen::VectorXd& R) {
    s.assemble(X, k, A, R);
    if (k == Linearization::newton) A = -A;
  }
  void residual(const Eigen::VectorXd& X, Eigen::VectorXd& R) { s.residual(X, R); }
  double relative_residual(const Eigen::VectorXd& R) const { return s.relative_residual(R); }
  double velocity_norm(const Eigen::VectorXd& X) const { return s.velocity_norm(X); }
};
}  // namespace

TEST_CASE("a Newton that keeps failing: Picard runs longer before each try, the solve stops at the fourth",
          "[flow][solver]") {
  auto P = compression(0.2);
  ClimbingNewton sys{*P.system};
  NonlinearSolverParams prm;
  NonlinearSolver<> solver(prm);
  Eigen::VectorXd X;
  try {
    solver.solve(sys, X);
    FAIL("no exception");
  } catch (const Error& e) {
    CHECK_THAT(std::string(e.what()), Catch::Contains("Newton failed 4 times"));
  }
  // Never stopped: Picard converges alone, Newton tried after 1, 2, 4, ...
  // Picard iterations (one each before: the alternation this rule ends).
  prm.max_newton_failures = 0;
  prm.max_iterations = 200;  // Picard alone: ~0.77 a step
  NonlinearSolver<> patient(prm);
  X.resize(0);
  const SolveReport rep = patient.solve(sys, X);
  REQUIRE(rep.converged);
  std::vector<int> runs;  // Picard iterations before each Newton try after a failure
  int run = 0, failures = 0;
  for (const auto& h : rep.history) {
    if (h.kind == Linearization::picard) {
      ++run;
      continue;
    }
    CHECK(h.step == 0.0);  // each try fails
    if (failures++ > 0) runs.push_back(run);
    run = 0;
  }
  REQUIRE(runs.size() >= 2);
  for (std::size_t k = 0; k < runs.size(); ++k) CHECK(runs[k] >= (1 << k));
}

namespace {
// Newton's tangent at X along a random direction dX (multipliers included):
// the assembled matrix against central differences of the residual, and the
// matrix-free product against the matrix. Returns fd, for checks that a
// tangent missing a term is off.
Eigen::VectorXd check_tangent(FlowSystem<NortonHoff>& sys, const Eigen::VectorXd& X, Eigen::VectorXd& dX,
                              unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g;
  dX.resize(X.size());
  for (Eigen::Index k = 0; k < X.size(); ++k) dX[k] = g(rng) * (std::abs(X[k]) + 1e-3);
  SystemPattern::Matrix A;
  Eigen::VectorXd R, Rp, Rm, Jv;
  sys.assemble(X, Linearization::newton, A, R);
  const double eps = 1e-6;
  sys.residual(X + eps * dX, Rp);
  sys.residual(X - eps * dX, Rm);
  const Eigen::VectorXd fd = (Rp - Rm) / (2 * eps), an = A * dX;
  CHECK((fd - an).norm() <= 1e-6 * an.norm());
  sys.apply_tangent(X, dX, Jv);
  CHECK((Jv - an).norm() <= 1e-12 * an.norm());
  return fd;
}
// |fd - A dX| / |fd| with A the tangent assembled now.
double tangent_gap(FlowSystem<NortonHoff>& sys, const Eigen::VectorXd& X, const Eigen::VectorXd& dX,
                   const Eigen::VectorXd& fd) {
  SystemPattern::Matrix A;
  Eigen::VectorXd R;
  sys.assemble(X, Linearization::newton, A, R);
  return (fd - A * dX).norm() / fd.norm();
}
}  // namespace

TEST_CASE("a velocity-dependent boundary traction: its Newton tangent, matrix and matrix-free",
          "[flow][solver][friction]") {
  // Regularized Tresca friction on the top face (normal +y, tool at rest),
  // with the material's shear flow stress k of the face's triangles:
  // t = -m k (2/pi) atan(v_x / v0) e_x, dt/dv_x = -m k (2/pi) / v0 / (1 + (v_x/v0)^2),
  // dt/dk = -m (2/pi) atan(v_x / v0) e_x.
  const double m = 0.5, v0 = 0.01, H = 3;
  auto P = compression(0.2, true);
  const auto& segs = P.mesh.boundary_segments();
  int on_top = 0;
  double k_min = 1e300, k_max = 0.0;
  auto add_friction = [&](bool with_dk) {
    on_top = 0;
    for (std::size_t k = 0; k < segs.size(); ++k)
      if (std::abs(P.mesh.nodes()(1, segs[k].a) - H) < 1e-9 && std::abs(P.mesh.nodes()(1, segs[k].b) - H) < 1e-9) {
        P.system->add_velocity_traction(7, static_cast<int>(k), [=, &k_min, &k_max](const TractionPointState& q) {
          VelocityTraction vt;
          const double s = q.v.x() / v0;
          vt.t.x() = -m * q.k * M_2_PI * std::atan(s);
          vt.dt_dv(0, 0) = -m * q.k * M_2_PI / v0 / (1 + s * s);
          if (with_dk) vt.dt_dk.x() = -m * M_2_PI * std::atan(s);
          k_min = std::min(k_min, q.k);
          k_max = std::max(k_max, q.k);
          return vt;
        });
        ++on_top;
      }
  };
  add_friction(true);
  REQUIRE(on_top >= 10);
  NonlinearSolver<> solver;
  Eigen::VectorXd X;
  const SolveReport rep = solver.solve(*P.system, X);
  CHECK(rep.converged);
  // k = sigma_eq / sqrt(3) of Norton-Hoff at the face's strain rates: of the
  // order of the flow stress at the mean rate (0.2 / 3 here), and varying
  // along the face, whose strain rate friction makes nonuniform.
  k_min = 1e300;
  k_max = 0.0;
  Eigen::VectorXd R0;
  P.system->residual(X, R0);  // k at the solution
  const NortonHoff law;
  const double k_mean = law.flow_stress(0.1 / 3 * 2 / std::sqrt(3.0)) / std::sqrt(3.0);
  CHECK(k_min > 0.3 * k_mean);
  CHECK(k_max < 3.0 * k_mean);
  CHECK(k_max > 1.01 * k_min);
  // The force on the "tool" opposes the traction: +x where the face slides +x.
  const Eigen::Vector2d F = P.system->velocity_traction_force(7, X);
  CHECK(F.x() > 0);
  CHECK(F.y() == 0.0);
  CHECK(P.system->velocity_traction_force(8, X).norm() == 0.0);
  Eigen::VectorXd dX;
  const Eigen::VectorXd fd = check_tangent(*P.system, X, dX, 5);
  // Without dt/dk (k held fixed), or with no traction at all, the tangent is visibly off.
  P.system->clear_velocity_tractions(7);
  add_friction(false);
  CHECK(tangent_gap(*P.system, X, dX, fd) > 1e-4);
  P.system->clear_velocity_tractions(7);
  CHECK(tangent_gap(*P.system, X, dX, fd) > 1e-4);
}

TEST_CASE("a traction that reads a multiplier (Coulomb friction): its field, its tangent", "[flow][solver][friction]") {
  // Coulomb-like friction on the top face, reading the top plate's
  // multipliers (their direction +y, so the plate pressure is +lambda there):
  // t = -mu lambda (2/pi) atan(v_x / v0) e_x.
  const double mu = 0.3, v0 = 0.01, H = 3;
  auto P = compression(0.2, true);
  const int top = P.system->constraints().find_part("top");
  const auto& segs = P.mesh.boundary_segments();
  int on_top = 0;
  auto add_friction = [&](bool with_dlambda) {
    on_top = 0;
    for (std::size_t k = 0; k < segs.size(); ++k)
      if (std::abs(P.mesh.nodes()(1, segs[k].a) - H) < 1e-9 && std::abs(P.mesh.nodes()(1, segs[k].b) - H) < 1e-9) {
        P.system->add_velocity_traction(
            7, static_cast<int>(k),
            [=](const TractionPointState& q) {
              VelocityTraction vt;
              const double s = q.v.x() / v0;
              vt.t.x() = -mu * q.lambda * M_2_PI * std::atan(s);
              vt.dt_dv(0, 0) = -mu * q.lambda * M_2_PI / v0 / (1 + s * s);
              if (with_dlambda) vt.dt_dlambda.x() = -mu * M_2_PI * std::atan(s);
              return vt;
            },
            top);
        ++on_top;
      }
  };
  add_friction(true);
  REQUIRE(on_top >= 10);
  NonlinearSolver<> solver;
  Eigen::VectorXd X;
  REQUIRE(solver.solve(*P.system, X).converged);
  // The multiplier field integrates to the plate's reaction (hats exact under Gauss).
  double F = 0.0, lambda_min = 1e300;
  for (const auto& smp : P.system->velocity_traction_samples(7, X)) {
    F += smp.w * smp.state.lambda;
    lambda_min = std::min(lambda_min, smp.state.lambda);
    CHECK(smp.t.x() == Approx(-mu * smp.state.lambda * M_2_PI * std::atan(smp.state.v.x() / v0)).epsilon(1e-12));
  }
  CHECK(F == Approx(P.system->reaction("top", X).y()).epsilon(1e-12));
  CHECK(lambda_min > 0);  // compressive all along the face
  CHECK(P.system->velocity_traction_force(7, X).x() > 0);
  // Newton's tangent includes dt/dlambda dlambda/dLambda (multiplier columns
  // in the velocity rows), matrix and matrix-free; without it, visibly off.
  Eigen::VectorXd dX;
  const Eigen::VectorXd fd = check_tangent(*P.system, X, dX, 9);
  P.system->clear_velocity_tractions(7);
  add_friction(false);
  CHECK(tangent_gap(*P.system, X, dX, fd) > 1e-4);
}

TEST_CASE("Norton-Hoff viscosity and its derivative", "[flow][material]") {
  const NortonHoff m(150.0, 0.2, 1e-9);
  for (double d : {1e-3, 0.05, 2.0}) {
    const double h = 1e-6 * d;
    const double fd = (m.viscosity(d + h).mu - m.viscosity(d - h).mu) / (2 * h);
    CHECK(m.viscosity(d).dmu_dd_over_d * d == Approx(fd).epsilon(1e-7));
    CHECK(m.viscosity(d).mu == Approx(150.0 * std::pow(std::sqrt(3.0) * d, -0.8)).epsilon(1e-9));
    CHECK(m.flow_stress(d) == Approx(3 * 150.0 * std::pow(std::sqrt(3.0) * d, -0.8) * d).epsilon(1e-9));
  }
  CHECK(std::isfinite(m.viscosity(0.0).mu));
  CHECK_THROWS_AS(NortonHoff(-1.0, 0.2), Error);
  CHECK_THROWS_AS(NortonHoff(150.0, 0.2, 0.0), Error);
}

namespace {

// A material defined outside the library that reads the point's position: a
// block of two materials (the right half three times stronger).
struct TwoZones {
  NortonHoff left{150.0, 0.2, 1e-5}, right{450.0, 0.2, 1e-5};
  double split = 2.0;
  Viscosity viscosity(const MaterialPoint& point) const {
    return (point.x.x() < split ? left : right).viscosity(point.d);
  }
};

}  // namespace

TEST_CASE("a material law gets the point state: strain rate and position", "[flow][material]") {
  const double W = 4, H = 3, tol = 1e-9;
  FlowProblem<TwoZones> P(block_nodes(13, 10, W, H, true), Geometry::plane_strain, TwoZones{});
  P.velocity(on_line({0, 0}, {1, 0}, tol), {1, 0}, 0.0, "symmetry");
  P.velocity(on_line({0, 0}, {0, 1}, tol), {0, 1}, 0.0, "bottom");
  P.velocity(on_line({0, H}, {0, 1}, tol), {0, 1}, -0.1, "top");
  NonlinearSolver<> solver;
  Eigen::VectorXd X;
  solver.solve(*P.system, X);
  const FlowPointState st = P.system->point_state(X);
  const auto& xq = P.disc.points();
  int left = 0, right = 0;
  double worst = 0;
  for (Eigen::Index g = 0; g < xq.cols(); ++g) {
    const bool is_left = xq(0, g) < 2.0;
    (is_left ? left : right) += 1;
    const double mu = (is_left ? TwoZones{}.left : TwoZones{}.right).viscosity(st.d[g]).mu;
    worst = std::max(worst, std::abs(st.mu[g] - mu) / mu);
  }
  CHECK(left > 0);
  CHECK(right > 0);
  CHECK(worst < 1e-14);
}

namespace {

// A 1-D convection-diffusion matrix: unsymmetric, and with a Jacobi
// preconditioner GMRES needs far more than a few iterations.
Eigen::SparseMatrix<double> convection_diffusion(int n) {
  std::vector<Eigen::Triplet<double>> t;
  for (int i = 0; i < n; ++i) {
    t.emplace_back(i, i, 2.0);
    if (i > 0) t.emplace_back(i, i - 1, -1.4);
    if (i + 1 < n) t.emplace_back(i, i + 1, -0.6);
  }
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(t.begin(), t.end());
  return A;
}

}  // namespace

TEST_CASE("GMRES: exact preconditioner, stagnation without and with the direct fallback",
          "[flow][solver][gmres]") {
  const int n = 300;
  const Eigen::SparseMatrix<double> A = convection_diffusion(n);
  Eigen::VectorXd b(n);
  for (int i = 0; i < n; ++i) b[i] = std::sin(0.1 * i) + 1.0;
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(A);
  const Eigen::VectorXd x_exact = lu.solve(b);

  SECTION("P = A, an exact LU: one iteration") {
    GmresSolver<DirectSolver> g;
    g.analyze_preconditioner(A);
    g.factorize_preconditioner(A);
    const Eigen::VectorXd x = g.solve(A, b);
    CHECK(g.last_iterations() == 1);
    CHECK(g.converged());
    CHECK((x - x_exact).norm() <= 1e-10 * x_exact.norm());
  }
  // The default companion LU: single precision where MUMPS is built.
  SECTION("P = A in single precision: a few iterations to a tight tolerance") {
    GmresParams prm;
    prm.tol = 1e-12;
    GmresSolver<> g(prm);
    g.analyze_preconditioner(A);
    g.factorize_preconditioner(A);
    const Eigen::VectorXd x = g.solve(A, b);
    CHECK(g.last_iterations() <= 4);
    CHECK(g.direct_fallbacks() == 0);
    CHECK((x - x_exact).norm() <= 1e-11 * x_exact.norm());
  }
  // A converged cycle's residual is the Arnoldi estimate; below 1e-10 a
  // product confirms it (the estimate can drop under the rounding floor).
  SECTION("reported residual: estimate, confirmed below 1e-10") {
    Eigen::SparseMatrix<double> P = A;
    P.diagonal() *= 1.05;  // an inexact preconditioner: several iterations
    for (const double tol : {1e-8, 1e-12}) {
      GmresParams prm;
      prm.tol = tol;
      GmresSolver<> g(prm);
      g.set_layout(DofLayout{n, {}});
      g.factorize_kept(P, true);
      int products = 0;
      const Eigen::VectorXd x = g.solve_kept(
          [&](const Eigen::VectorXd& v) -> Eigen::VectorXd {
            ++products;
            return A * v;
          },
          b, 100);
      const double true_residual = (b - A * x).norm() / b.norm();
      CHECK(g.converged());
      CHECK(g.last_iterations() >= 3);
      CHECK(true_residual <= 1.01 * tol);
      CHECK(g.last_residual() == Approx(true_residual).epsilon(1e-3));
      CHECK(products == g.last_iterations() + (tol < 1e-10 ? 1 : 0));
    }
  }
  SECTION("P = diag(A), short restart") {
    GmresParams prm;
    prm.tol = 1e-10;
    prm.restart = 8;
    prm.max_iterations = 16;
    GmresSolver<> g(prm);
    Eigen::SparseMatrix<double> D(n, n);
    D.setIdentity();
    D *= 2.0;
    g.analyze_preconditioner(D);
    g.factorize_preconditioner(D);
    // No fallback: one restart cycle, the last iterate, not converged.
    const Eigen::VectorXd x1 = g.solve(A, b, false);
    CHECK(g.last_iterations() == prm.restart);
    CHECK_FALSE(g.converged());
    CHECK(g.direct_fallbacks() == 0);
    CHECK((b - A * x1).norm() < b.norm());  // GMRES never increases the residual
    CHECK(g.last_residual() == Approx((b - A * x1).norm() / b.norm()).epsilon(1e-6));
    // With it: the direct LU of A, then kept as the preconditioner.
    const Eigen::VectorXd x2 = g.solve(A, b);
    CHECK(g.direct_fallbacks() == 1);
    CHECK(g.converged());
    CHECK((x2 - x_exact).norm() <= 1e-10 * x_exact.norm());
    const Eigen::VectorXd x3 = g.solve(A, 2.0 * b);
    CHECK(g.last_iterations() <= 2);
    CHECK(g.direct_fallbacks() == 1);
    CHECK((x3 - 2.0 * x_exact).norm() <= 1e-9 * x_exact.norm());
  }
}

TEST_CASE("DirectSolver (MUMPS where built with it): the LU of a saddle system, refactorized; loud failures",
          "[flow][solver][direct]") {
  // A flow system's saddle matrix (velocity, pressure, multiplier rows) at
  // the Stokes start, as the kept LU sees it.
  FlowProblem<NortonHoff> P = compression(0.2, true, 9);
  Eigen::SparseMatrix<double, Eigen::ColMajor, int> A;
  Eigen::VectorXd R, X = Eigen::VectorXd::Zero(P.system->size());
  P.system->assemble(X, Linearization::picard, A, R);
  A.makeCompressed();
  Eigen::SparseLU<Eigen::SparseMatrix<double>> ref(A);
  REQUIRE(ref.info() == Eigen::Success);
  const Eigen::VectorXd x_ref = ref.solve(-R);
  // Backward error at machine level, and the reference LU's solution to
  // the conditioning of the system (mu spans d_min's range).
  DirectSolver d;
  d.analyze(A);
  d.factorize(A);
  const Eigen::VectorXd x = d.solve(-R);
  CHECK((A * x + R).norm() <= 1e-13 * (A.norm() * x.norm() + R.norm()));
  CHECK((x - x_ref).norm() <= 1e-7 * x_ref.norm());
  // New values on the same pattern: no new analysis.
  const Eigen::SparseMatrix<double, Eigen::ColMajor, int> B = 3.0 * A;
  d.factorize(B);
  const Eigen::VectorXd y = d.solve(-R);
  CHECK((B * y + R).norm() <= 1e-13 * (B.norm() * y.norm() + R.norm()));
  CHECK((y - x_ref / 3.0).norm() <= 1e-7 * x_ref.norm());
  // Another pattern without analyze() (other nonzeros; as many, elsewhere),
  // and a singular matrix: Error.
  Eigen::SparseMatrix<double, Eigen::ColMajor, int> C(A.rows(), A.cols());
  C.setIdentity();
  C.makeCompressed();
  CHECK_THROWS_AS(d.factorize(C), Error);
  {
    std::vector<Eigen::Triplet<double>> t;
    for (int j = 0; j < A.outerSize(); ++j)
      for (Eigen::SparseMatrix<double, Eigen::ColMajor, int>::InnerIterator it(A, j); it; ++it)
        t.emplace_back(static_cast<int>(it.row()), j, it.value());
    // Column 0's first entry moves to a row where column 0 has none.
    int free_row = -1;
    for (int i = 0; i < A.rows() && free_row < 0; ++i)
      if (A.coeff(i, 0) == 0.0) free_row = i;
    REQUIRE(free_row >= 0);
    t.front() = Eigen::Triplet<double>(free_row, 0, 1.0);
    Eigen::SparseMatrix<double, Eigen::ColMajor, int> M(A.rows(), A.cols());
    M.setFromTriplets(t.begin(), t.end());
    M.makeCompressed();
    REQUIRE(M.nonZeros() == A.nonZeros());
    CHECK_THROWS_AS(d.factorize(M), Error);
  }
  Eigen::SparseMatrix<double, Eigen::ColMajor, int> S = A;
  for (int k = S.outerIndexPtr()[0]; k < S.outerIndexPtr()[1]; ++k) S.valuePtr()[k] = 0.0;  // column 0
  DirectSolver e;
  e.analyze(S);
  CHECK_THROWS_AS(e.factorize(S), Error);

  // The kept LU's solver (MUMPS with single-precision factors, built with
  // MUMPS): on this saddle matrix (viscosities over d_min's decades) a raw
  // solve with float factors is far off, GMRES makes it exact; double
  // factors on request.
  KeptLuSolver k;
  k.analyze(A);
  k.factorize(A);
#ifdef MAXENTFLOW_HAVE_MUMPS
  CHECK_FALSE(k.exact());
  CHECK((A * k.solve(-R) + R).norm() > 1e-3 * R.norm());
  k.set_exact(true);
  k.factorize(A);
  CHECK(k.exact());
  CHECK((A * k.solve(-R) + R).norm() <= 1e-13 * (A.norm() * x.norm() + R.norm()));
  {  // A direct fallback whose GMRES gets one iteration per LU: the float
     // LU leaves it short, the double one it asks for then solves.
    GmresParams one;
    one.restart = 1;
    GmresSolver<UmfpackSolver, KeptLuSolver> g1(one);
    const Eigen::VectorXd w1 = g1.solve(A, -R);
    CHECK(g1.direct_fallbacks() == 1);
    CHECK(g1.exact_factorizations() == 1);
    CHECK(g1.converged());
    CHECK((A * w1 + R).norm() <= 1e-9 * R.norm());
  }
  {  // A matrix singular in single precision only (1 + 1e-9 rounds to 1 in
     // float): the LU is made in double precision instead of failing.
    Eigen::SparseMatrix<double, Eigen::ColMajor, int> B(2, 2);
    B.insert(0, 0) = 1.0;
    B.insert(1, 0) = 1.0;
    B.insert(0, 1) = 1.0;
    B.insert(1, 1) = 1.0 + 1e-9;
    B.makeCompressed();
    KeptLuSolver kb;
    kb.analyze(B);
    kb.factorize(B);
    CHECK(kb.exact());
    CHECK(kb.singular_single() == 1);
    const Eigen::VectorXd rb = Eigen::VectorXd::LinSpaced(2, 1.0, 2.0);
    CHECK((B * kb.solve(rb) - rb).norm() <= 1e-6 * rb.norm());
    BasicMumpsSolver<float> fb;
    fb.analyze(B);
    CHECK_THROWS_AS(fb.factorize(B), Error);
  }
#endif
  GmresSolver<UmfpackSolver, KeptLuSolver> g;  // GMRES's default tolerance, 1e-9
  const Eigen::VectorXd w = g.solve(A, -R);  // no preconditioner given: the direct fallback
  CHECK(g.direct_fallbacks() == 1);
  CHECK(g.converged());
  CHECK(g.exact_factorizations() == 0);  // GMRES refines the float factors
  CHECK((A * w + R).norm() <= 1e-9 * R.norm());
  CHECK((w - x_ref).norm() <= 1e-7 * x_ref.norm());
}

TEST_CASE("Picard's and newton_symmetric's matrices are symmetric; their L D L^T", "[flow][solver][direct]") {
  auto P = compression(0.2);
  NonlinearSolver<> direct;
  Eigen::VectorXd X;
  REQUIRE(direct.solve(*P.system, X).converged);
  std::mt19937 rng(5);
  std::normal_distribution<double> g;
  for (Eigen::Index k = 0; k < X.size(); ++k) X[k] *= 1.0 + 0.05 * g(rng);  // away from the solution
  using Matrix = SystemPattern::Matrix;
  Matrix A, S, N;
  Eigen::VectorXd R, RS, RN;
  P.system->assemble(X, Linearization::picard, A, R);
  P.system->assemble(X, Linearization::newton_symmetric, S, RS);
  P.system->assemble(X, Linearization::newton, N, RN);
  CHECK(P.system->symmetric(Linearization::picard));
  CHECK(P.system->symmetric(Linearization::newton_symmetric));
  CHECK_FALSE(P.system->symmetric(Linearization::newton));
  const auto asymmetry = [](const Matrix& M) { return (M - Matrix(M.transpose())).norm() / M.norm(); };
  CHECK(asymmetry(A) <= 1e-15);
  CHECK(asymmetry(S) <= 1e-15);
  CHECK(asymmetry(N) > 1e-8);  // far above round-off
  CHECK((RS - R).norm() == 0.0);  // every kind's residual is the same
  CHECK((RN - R).norm() == 0.0);
  // newton_symmetric is Newton's tangent without d tau / d v: the two differ
  // in the pressure rows only, there by the tangent's asymmetric part.
  const int nv = DofLayout::fields_of(P.system->number_of_nodes());
  const Matrix D = N - S;
  double off = 0.0, on = 0.0;
  for (int j = 0; j < D.outerSize(); ++j)
    for (Matrix::InnerIterator it(D, j); it; ++it)
      (it.row() < nv && it.row() % 3 == 2 && j < nv && j % 3 != 2 ? on : off) += std::abs(it.value());
  CHECK(on > 1e-6 * N.norm());
  CHECK(off <= 1e-12 * N.norm());
  // newton_symmetric's matrix-free product is its matrix's.
  Eigen::VectorXd v(X.size()), Sv;
  for (Eigen::Index k = 0; k < v.size(); ++k) v[k] = g(rng);
  P.system->apply_tangent(X, v, Sv, Linearization::newton_symmetric);
  CHECK((Sv - S * v).norm() <= 1e-12 * (S * v).norm());
#ifdef MAXENTFLOW_HAVE_MUMPS
  // L D L^T of the symmetric saddle matrix from its lower triangle, exact in
  // double precision, refactorized on the same pattern; an LU where asked.
  BasicMumpsSolver<double> ldlt;
  ldlt.set_symmetric(true);
  ldlt.analyze(S);
  ldlt.factorize(S);
  const Eigen::VectorXd x = ldlt.solve(-R);
  CHECK((S * x + R).norm() <= 1e-12 * (S.norm() * x.norm() + R.norm()));
  const Matrix S3 = 3.0 * S;
  ldlt.factorize(S3);
  CHECK((S3 * ldlt.solve(-R) + R).norm() <= 1e-12 * (S3.norm() * x.norm() + R.norm()));
  Matrix I(S.rows(), S.cols());
  I.setIdentity();
  I.makeCompressed();
  CHECK_THROWS_AS(ldlt.factorize(I), Error);  // not the analysed pattern
  ldlt.set_symmetric(false);
  ldlt.analyze(N);
  ldlt.factorize(N);
  CHECK((N * ldlt.solve(-R) + R).norm() <= 1e-12 * (N.norm() * x.norm() + R.norm()));
  // The kept LU's solver: single-precision L D L^T, which GMRES refines.
  KeptLuSolver k;
  k.set_symmetric(true);
  k.analyze(S);
  k.factorize(S);
  CHECK((S * k.solve(-R) + R).norm() <= 1e-2 * R.norm());
#endif
  // Kept LUs of symmetric matrices or not: the same solution from a warm start.
  for (const bool symmetric_lu : {true, false}) {
    CAPTURE(symmetric_lu);
    NonlinearSolverParams prm;
    prm.newton_from_warm_start = false;
    prm.symmetric_lu = symmetric_lu;
    NonlinearSolver<GmresSolver<>> s(prm);
    auto Q = compression(0.2);
    Eigen::VectorXd Y;
    REQUIRE(s.solve(*Q.system, Y).converged);
    Eigen::VectorXd Y0 = Y;
    Y = 1.05 * Y0;
    const SolveReport r = s.solve(*Q.system, Y);
    INFO(r.log());
    REQUIRE(r.converged);
    CHECK(r.direct_fallbacks == 0);
    CHECK((Y - Y0).lpNorm<Eigen::Infinity>() <= 1e-6 * Y0.lpNorm<Eigen::Infinity>());
  }
}

TEST_CASE("the Krylov preconditioner is kept while it works, with the same solution",
          "[flow][solver][gmres]") {
  Eigen::VectorXd X_every, X_kept;
  SolveReport every, kept;
  {
    auto P = compression(0.2);
    NonlinearSolverParams prm;
    prm.preconditioner_refresh = 0;  // rebuilt every iteration
    NonlinearSolver<GmresSolver<>> s(prm);
    every = s.solve(*P.system, X_every);
  }
  {
    auto P = compression(0.2);
    NonlinearSolver<GmresSolver<>> s;  // default: rebuilt when GMRES slows down
    kept = s.solve(*P.system, X_kept);
  }
  INFO(every.log() << "---\n" << kept.log());
  REQUIRE(every.converged);
  REQUIRE(kept.converged);
  CHECK(every.preconditioner_updates == every.iterations());
  CHECK(kept.preconditioner_updates >= 1);
  CHECK(kept.preconditioner_updates < kept.iterations());
  CHECK(kept.direct_fallbacks == 0);
  CHECK((X_every - X_kept).lpNorm<Eigen::Infinity>() <= 1e-7 * X_every.lpNorm<Eigen::Infinity>());
}

namespace {
// Sticking compression driven by the plates alone (no body force or
// traction), as bench_flow's: from rest its first Picard system has the
// uniform viscosity mu(d_min), here ~1e5 times that of the flow.
FlowProblem<NortonHoff> plates_only(double n) {
  const double L = 10.0, V = 1.0;
  FlowProblem<NortonHoff> P(block_nodes(16, 16, L, L, true), Geometry::plane_strain,
                            NortonHoff(150.0, n, 1e-6 * V / L));
  const double tol = 1e-9 * L;
  P.velocity(on_line({0, 0}, {1, 0}, tol), {1, 0}, 0.0, "symmetry");
  P.velocity(on_line({0, 0}, {0, 1}, tol), {0, 1}, 0.0, "bottom");
  P.velocity(on_line({0, 0}, {0, 1}, tol), {1, 0}, 0.0, "bottom sticking");
  P.velocity(on_line({0, L}, {0, 1}, tol), {0, 1}, -V, "top");
  return P;
}
}  // namespace

TEST_CASE("after the first Picard solve from rest, pressure and multipliers take the flow's own scale",
          "[flow][solver]") {
  for (double n : {0.2, 1.0}) {
    CAPTURE(n);
    auto P = plates_only(n);
    FlowSystem<NortonHoff>& sys = *P.system;
    Eigen::VectorXd X = Eigen::VectorXd::Zero(sys.size()), R;
    Eigen::SparseMatrix<double> A;
    sys.assemble(X, Linearization::picard, A, R);
    Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(A);
    X = lu.solve(-R);  // the Picard iterate from rest
    sys.residual(X, R);
    const double before = sys.relative_residual(R);
    const Eigen::VectorXd X1 = X;
    const double c = sys.rescale_stresses(X);
    sys.residual(X, R);
    const double after = sys.relative_residual(R);
    const int nv = DofLayout::fields_of(sys.number_of_nodes());
    for (int a = 0; a < sys.number_of_nodes(); ++a) {  // velocities kept, pressures scaled by c
      CHECK(X[DofLayout::velocity(a, 0)] == X1[DofLayout::velocity(a, 0)]);
      CHECK(X[DofLayout::velocity(a, 1)] == X1[DofLayout::velocity(a, 1)]);
      CHECK(X[DofLayout::pressure(a)] == Approx(c * X1[DofLayout::pressure(a)]).margin(1e-300));
    }
    CHECK((X.tail(X.size() - nv) - c * X1.tail(X.size() - nv)).norm() <= 1e-12 * X.tail(X.size() - nv).norm());
    if (n == 1.0) {
      // Newtonian: the iterate from rest is the solution, nothing to rescale.
      CHECK(before < 1e-9);
      CHECK(c == 1.0);
    } else {
      // mu(d) with d ~ V/L against mu(d_min): c ~ (1e-6)^(1 - n) = 1.6e-5.
      CHECK(c > 1e-6);
      CHECK(c < 1e-3);
      CHECK(before > 0.5);
      CHECK(after < 0.4 * before);
    }
  }
}

TEST_CASE("the system's pattern: indices only, the structure of every assembled matrix", "[flow][solver]") {
  auto P = compression(0.2);
  FlowSystem<NortonHoff>& sys = *P.system;
  Eigen::VectorXd X = Eigen::VectorXd::Zero(sys.size()), R;
  SystemPattern::Matrix A;
  sys.assemble(X, Linearization::picard, A, R);
  const SystemPattern& pat = sys.pattern();
  REQUIRE(A.isCompressed());
  REQUIRE(A.nonZeros() == pat.nonzeros());
  CHECK(std::equal(A.outerIndexPtr(), A.outerIndexPtr() + A.cols() + 1, pat.outer_index()));
  CHECK(A.norm() > 0);
  const SystemPattern::Matrix Z = pat.matrix();
  CHECK(Z.nonZeros() == pat.nonzeros());
  CHECK(std::equal(A.innerIndexPtr(), A.innerIndexPtr() + A.nonZeros(), Z.innerIndexPtr()));
  CHECK(Z.norm() == 0.0);
  // Every entry's position from the pattern's adjacency (no row indices kept);
  // the multiplier rows and columns included, and no entry outside.
  REQUIRE(sys.size() > DofLayout::fields_of(sys.number_of_nodes()));  // there are multiplier rows
  int wrong = 0;
  for (int j = 0; j < A.cols(); ++j)
    for (int k = A.outerIndexPtr()[j]; k < A.outerIndexPtr()[j + 1]; ++k)
      if (pat.position(A.innerIndexPtr()[k], j) != k) ++wrong;
  CHECK(wrong == 0);
  int outside = 0;
  for (int j = 0; j < A.cols(); j += 7)
    for (int row = 0; row < A.rows(); ++row) {
      const int* b = A.innerIndexPtr() + A.outerIndexPtr()[j];
      const int* e = A.innerIndexPtr() + A.outerIndexPtr()[j + 1];
      if (!std::binary_search(b, e, row) && pat.position(row, j) != -1) ++outside;
    }
  CHECK(outside == 0);
  // Assembled again into the same matrix: zeroed in place, the same values.
  const SystemPattern::Matrix A1 = A;
  sys.assemble(X, Linearization::picard, A, R);
  CHECK((A - A1).norm() == 0.0);
}

TEST_CASE("GMRES with the linear-triangle companion converges from rest without a direct LU",
          "[flow][solver][gmres]") {
  // Unscaled, the momentum rows (~mu(d_min)) drown the multiplier rows in
  // GMRES's norm and the companion needed over 150 iterations per solve
  // (then the direct fallback); rows scaled by their largest entry and the
  // pressure rescaled after the first iterate, ~10-70.
  Eigen::VectorXd X_gmres, X_direct;
  SolveReport gmres, direct;
  {
    auto P = plates_only(0.2);
    NonlinearSolverParams prm;
    prm.kept_lu = false;  // the companion throughout, as above kept_lu_max_unknowns
    NonlinearSolver<GmresSolver<>> s(prm);
    gmres = s.solve(*P.system, X_gmres);
  }
  {
    auto P = plates_only(0.2);
    NonlinearSolver<UmfpackSolver> s;
    direct = s.solve(*P.system, X_direct);
  }
  INFO(gmres.log() << "---\n" << direct.log());
  REQUIRE(gmres.converged);
  REQUIRE(direct.converged);
  CHECK(gmres.direct_fallbacks == 0);
  CHECK(gmres.max_linear_iterations <= 100);
  CHECK(gmres.iterations() <= direct.iterations() + 4);
  CHECK((X_gmres - X_direct).lpNorm<Eigen::Infinity>() <= 1e-6 * X_direct.lpNorm<Eigen::Infinity>());
}

namespace {
// The sticking block's solution from rest, and a start a few per cent off
// it, as a time step's predictor is.
std::pair<Eigen::VectorXd, Eigen::VectorXd> rest_and_warm_start() {
  Eigen::VectorXd X_rest;
  auto P = compression(0.2);
  NonlinearSolver<GmresSolver<>> s;
  REQUIRE(s.solve(*P.system, X_rest).converged);
  Eigen::VectorXd start = X_rest;
  for (Eigen::Index i = 0; i < start.size(); ++i) start[i] *= 1.0 + 0.05 * std::sin(0.37 * static_cast<double>(i));
  return {X_rest, start};
}
int picard_linear_iterations(const SolveReport& r) {
  int its = 0;
  for (const auto& h : r.history)
    if (h.kind == Linearization::picard) its += h.linear_iterations;
  return its;
}
}  // namespace

TEST_CASE("a warm-started solve's Picard iterations solve to eta_picard_warm: same solution, fewer Krylov iterations",
          "[flow][solver][gmres]") {
  const auto rest_warm = rest_and_warm_start();
  const Eigen::VectorXd &X_rest = rest_warm.first, &start = rest_warm.second;
  auto warm = [&](double eta_warm, Eigen::VectorXd& X) {
    auto P = compression(0.2);
    NonlinearSolverParams prm;
    prm.newton_from_warm_start = false;  // Picard first, as E2 and E3 do
    prm.switch_increment = 1e-3;         // so that Picard does a few iterations
    prm.eta_picard_warm = eta_warm;
    NonlinearSolver<GmresSolver<>> s(prm);
    X = start;
    return s.solve(*P.system, X);
  };
  Eigen::VectorXd X_tight, X_loose;
  const SolveReport tight = warm(1e-4, X_tight), loose = warm(1e-2, X_loose);
  INFO(tight.log() << "---\n" << loose.log());
  REQUIRE(tight.converged);
  REQUIRE(loose.converged);
  REQUIRE(tight.picard >= 2);
  CHECK(picard_linear_iterations(loose) < picard_linear_iterations(tight));
  CHECK((X_loose - X_tight).lpNorm<Eigen::Infinity>() <= 1e-6 * X_tight.lpNorm<Eigen::Infinity>());
  CHECK((X_loose - X_rest).lpNorm<Eigen::Infinity>() <= 1e-6 * X_rest.lpNorm<Eigen::Infinity>());
}

TEST_CASE("a warm-started solve's Picard iterations solve with a kept Picard LU: same solution, fewer Krylov "
          "iterations than with the linear-triangle companion",
          "[flow][solver][gmres]") {
  const auto rest_warm = rest_and_warm_start();
  const Eigen::VectorXd &X_rest = rest_warm.first, &start = rest_warm.second;
  auto warm = [&](bool kept_picard, Eigen::VectorXd& X) {
    auto P = compression(0.2);
    NonlinearSolverParams prm;
    prm.newton_from_warm_start = false;
    prm.switch_increment = 1e-3;
    prm.kept_lu_picard = kept_picard;
    NonlinearSolver<GmresSolver<>> s(prm);
    X = start;
    // Two solves, as two steps: the second starts with the first's LUs.
    SolveReport first = s.solve(*P.system, X);
    REQUIRE(first.converged);
    X = start;
    return s.solve(*P.system, X);
  };
  Eigen::VectorXd X_kept, X_companion;
  const SolveReport kept = warm(true, X_kept), companion = warm(false, X_companion);
  INFO(kept.log() << "---\n" << companion.log());
  REQUIRE(kept.converged);
  REQUIRE(companion.converged);
  REQUIRE(kept.picard >= 2);
  CHECK(2 * picard_linear_iterations(kept) < picard_linear_iterations(companion));
  CHECK(kept.direct_fallbacks == 0);
  CHECK((X_kept - X_companion).lpNorm<Eigen::Infinity>() <= 1e-6 * X_companion.lpNorm<Eigen::Infinity>());
  CHECK((X_kept - X_rest).lpNorm<Eigen::Infinity>() <= 1e-6 * X_rest.lpNorm<Eigen::Infinity>());
}

TEST_CASE("GMRES: the kept LU serves the layouts it can be matched to", "[flow][solver][gmres]") {
  const int n = 300;
  const Eigen::SparseMatrix<double> A = convection_diffusion(n);
  Eigen::VectorXd b(n);
  for (int i = 0; i < n; ++i) b[i] = std::cos(0.07 * i);
  Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(A);
  const Eigen::VectorXd x_exact = lu.solve(b);
  auto product = [&A](const Eigen::VectorXd& v) -> Eigen::VectorXd { return A * v; };
  DofLayout L{n - 4, {}};
  for (int k = 0; k < 4; ++k) L.multipliers.push_back(DofLayout::key(0, k, 0));

  GmresSolver<UmfpackSolver, DirectSolver> g;  // an exact LU: one iteration where it is A's
  g.set_tolerance(1e-10);
  // An LU made while the layout did not describe A serves no layout.
  g.set_layout(DofLayout{10, {}});
  g.factorize_kept(A);
  CHECK_FALSE(g.kept_usable(n));
  g.set_layout(L);
  CHECK_FALSE(g.kept_usable(n));
  CHECK_THROWS_AS(g.solve_kept(product, b, 10), Error);

  // Its own layout: one iteration.
  g.factorize_kept(A);
  REQUIRE(g.kept_usable(n));
  Eigen::VectorXd x = g.solve_kept(product, b, 10);
  CHECK(g.converged());
  CHECK(g.last_iterations() == 1);
  CHECK((x - x_exact).norm() <= 1e-8 * x_exact.norm());

  // Two multiplier rows renamed (one released, one taken): a rank-two
  // difference, a few more iterations, the same solution.
  DofLayout L2 = L;
  L2.multipliers[1] = DofLayout::key(0, 99, 0);
  g.set_layout(L2);
  REQUIRE(g.kept_usable(n));
  x = g.solve_kept(product, b, 20);
  CHECK(g.converged());
  CHECK(g.last_iterations() <= 6);
  CHECK((x - x_exact).norm() <= 1e-8 * x_exact.norm());

  // Other field unknowns, or too many rows changed: not usable.
  g.set_layout(DofLayout{n - 5, {0, 1, 2, 3, 4}});
  CHECK_FALSE(g.kept_usable(n));
  GmresParams strict;
  strict.kept_max_changed_rows = 1;
  GmresSolver<> h(strict);
  h.set_layout(L);
  h.factorize_kept(A);
  h.set_layout(L2);
  CHECK_FALSE(h.kept_usable(n));
  CHECK(h.kept_factorizations() == 1);
}

namespace {
// [[A, L^T], [L, 0]] with A the convection-diffusion matrix and L the given
// constraint rows (each couples a few field unknowns), as FlowSystem lays out
// a saddle system: the multiplier columns are the rows' transpose.
Eigen::SparseMatrix<double> saddle(int nf, const std::vector<int>& rows) {
  const Eigen::SparseMatrix<double> A = convection_diffusion(nf);
  std::vector<Eigen::Triplet<double>> t;
  for (int j = 0; j < A.outerSize(); ++j)
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, j); it; ++it) t.emplace_back(it.row(), j, it.value());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const int r = rows[i], m = nf + static_cast<int>(i);
    for (int k = 0; k < 3; ++k) {
      const int dof = (37 * r + 11 * k) % nf;
      const double c = 1.0 + 0.5 * k - 0.1 * r;
      t.emplace_back(m, dof, c);
      t.emplace_back(dof, m, c);
    }
  }
  const int n = nf + static_cast<int>(rows.size());
  Eigen::SparseMatrix<double> K(n, n);
  K.setFromTriplets(t.begin(), t.end());
  K.makeCompressed();
  return K;
}
DofLayout saddle_layout(int nf, const std::vector<int>& rows) {
  DofLayout L{nf, {}};
  for (int r : rows) L.multipliers.push_back(DofLayout::key(0, r, 0));
  return L;
}
}  // namespace

TEST_CASE("GMRES: the kept LU takes released and new constraint rows exactly", "[flow][solver][gmres]") {
  const int nf = 240;
  const std::vector<int> kept_rows{0, 1, 2, 3, 5};
  GmresParams prm;
  prm.tol = 1e-10;
  GmresSolver<UmfpackSolver, DirectSolver> g(prm);  // an exact LU
  g.set_layout(saddle_layout(nf, kept_rows));
  g.factorize_kept(saddle(nf, kept_rows));

  // The same field block with other constraint rows: the preconditioner is
  // that system's inverse, so GMRES takes one iteration (two with round-off).
  // (The plain mapping took 13, 5, 40 and 40 iterations, the last two short
  // of the tolerance.)
  const std::vector<std::vector<int>> sets{{0, 2, 3, 5}, {0, 1, 2, 3, 5, 7, 8}, {1, 3, 4, 5, 9}, {5}};
  for (const auto& rows : sets) {
    const Eigen::SparseMatrix<double> K = saddle(nf, rows);
    Eigen::VectorXd b(K.rows());
    for (Eigen::Index i = 0; i < b.size(); ++i) b[i] = std::cos(0.05 * static_cast<double>(i)) + 0.3;
    Eigen::SparseLU<Eigen::SparseMatrix<double>> lu(K);
    const Eigen::VectorXd x_exact = lu.solve(b);
    g.set_layout(saddle_layout(nf, rows));
    REQUIRE(g.kept_usable(K.rows()));
    const Eigen::VectorXd x = g.solve_kept([&K](const Eigen::VectorXd& v) -> Eigen::VectorXd { return K * v; }, b, 40);
    INFO("rows " << rows.size() << ": " << g.last_iterations() << " iterations");
    CHECK(g.converged());
    CHECK(g.last_iterations() <= 2);
    CHECK(g.kept_updated_rows() > 0);
    CHECK((x - x_exact).norm() <= 1e-8 * x_exact.norm());
  }
  CHECK(g.kept_factorizations() == 1);

  // Its own layout again: the LU itself, no update.
  g.set_layout(saddle_layout(nf, kept_rows));
  CHECK(g.kept_updated_rows() == -1);
}

namespace {
// C = alpha op(A) op(B) + beta C through the program's xGEMM (found as any
// shared library finds it), against Eigen's product, for one-column and
// two-column C.
template <class T>
void check_gemm(const char* name, bool forwarded_expected) {
  using Mat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;
  using Gemm = maxentflow::detail::Gemm<T>;
  auto* gemm = reinterpret_cast<Gemm>(dlsym(RTLD_DEFAULT, name));
  REQUIRE(gemm != nullptr);
  const int m = 7, k = 5, lda = 9, ldb = 6, ldc = 8;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  for (const int n : {1, 2})
    for (const char ta : {'N', 'T'})
      for (const char tb : {'N', 'T'})
        for (const T beta : {T(0), T(0.5)}) {
          // op(A) m x k stored in lda rows; op(B) k x n stored in ldb rows.
          Mat A = Mat::NullaryExpr(lda, std::max(m, k), [&] { return T(u(rng)); });
          Mat B = Mat::NullaryExpr(ldb, std::max(k, n), [&] { return T(u(rng)); });
          Mat C = Mat::NullaryExpr(ldc, n, [&] { return T(u(rng)); });
          const Mat opA = ta == 'N' ? Mat(A.topLeftCorner(m, k)) : Mat(A.topLeftCorner(k, m).transpose());
          const Mat opB = tb == 'N' ? Mat(B.topLeftCorner(k, n)) : Mat(B.topLeftCorner(n, k).transpose());
          const T alpha = T(-1.5);
          Mat expected = alpha * opA * opB;
          if (beta != T(0)) expected += beta * C.topRows(m);
          if (beta == T(0)) C.topRows(m).setConstant(std::numeric_limits<T>::quiet_NaN());  // not to be read
          const long long before = blas_gemv_forwards();
          gemm(&ta, &tb, &m, &n, &k, &alpha, A.data(), &lda, B.data(), &ldb, &beta, C.data(), &ldc, 1, 1);
          CHECK(blas_gemv_forwards() - before == (n == 1 && forwarded_expected ? 1 : 0));
          const double tol = std::is_same_v<T, float> ? 1e-5 : 1e-13;
          CHECK((C.topRows(m) - expected).template lpNorm<Eigen::Infinity>() <= tol);
        }
}

// The TRSM named `name`, against Eigen's triangular solve: B one column (side
// L) or one row (side R) is forwarded to TRSV, two are not.
template <class T>
void check_trsm(const char* name) {
  using Mat = Eigen::Matrix<T, Eigen::Dynamic, Eigen::Dynamic>;
  using Trsm = maxentflow::detail::Trsm<T>;
  auto* trsm = reinterpret_cast<Trsm>(dlsym(RTLD_DEFAULT, name));
  REQUIRE(trsm != nullptr);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  for (const char side : {'L', 'R'})
    for (const char uplo : {'U', 'L'})
      for (const char ta : {'N', 'T'})
        for (const char diag : {'N', 'U'})
          for (const int cols : {1, 2})
            for (const T alpha : {T(1), T(-1.5)}) {
              CAPTURE(side, uplo, ta, diag, cols, alpha);
              const int k = 7;  // op(A) k x k
              const int m = side == 'L' ? k : cols, n = side == 'L' ? cols : k;
              const int lda = 9, ldb = m + 2;
              Mat A = Mat::NullaryExpr(lda, k, [&] { return T(u(rng)); });
              for (int i = 0; i < k; ++i) A(i, i) = T(2.0 + std::abs(u(rng)));
              Mat Tri = Mat::Zero(k, k);  // the triangle TRSM reads
              for (int j = 0; j < k; ++j)
                for (int i = 0; i < k; ++i)
                  if (i == j) Tri(i, i) = diag == 'U' ? T(1) : A(i, i);
                  else if ((uplo == 'U') == (i < j)) Tri(i, j) = A(i, j);
              const Mat opA = ta == 'N' ? Tri : Mat(Tri.transpose());
              Mat B = Mat::NullaryExpr(ldb, n, [&] { return T(u(rng)); });
              const Mat B0 = B.topRows(m), pad = B.bottomRows(ldb - m);
              // B op(A)^-1 = (op(A)^-T B^T)^T
              const Mat expected = side == 'L' ? Mat(alpha * opA.partialPivLu().solve(B0))
                                               : Mat(alpha * Mat(opA.transpose()).partialPivLu().solve(
                                                                 Mat(B0.transpose())).transpose());
              const long long before = blas_gemv_forwards();
              trsm(&side, &uplo, &ta, &diag, &m, &n, &alpha, A.data(), &lda, B.data(), &ldb, 1, 1, 1, 1);
              CHECK(blas_gemv_forwards() - before == (cols == 1 ? 1 : 0));
              const double tol = std::is_same_v<T, float> ? 1e-5 : 1e-13;
              CHECK((B.topRows(m) - expected).template lpNorm<Eigen::Infinity>() <= tol);
              CHECK(B.bottomRows(ldb - m) == pad);  // the rows between B's and ldb are not B's
            }
}
}  // namespace

TEST_CASE("BLAS: one-column GEMMs and TRSMs are made by GEMV and TRSV, with their results", "[flow][solver][blas]") {
  // The name every library of this program binds to is the program's own
  // (blas_gemv_forward.hpp): else MUMPS's solves would bypass it.
  CHECK(dlsym(RTLD_DEFAULT, "sgemm_") == reinterpret_cast<void*>(&sgemm_));
  CHECK(dlsym(RTLD_DEFAULT, "dgemm_") == reinterpret_cast<void*>(&dgemm_));
  check_gemm<float>("sgemm_", true);
  check_gemm<double>("dgemm_", true);
  // One-column triangular solves by TRSV, likewise.
  CHECK(dlsym(RTLD_DEFAULT, "strsm_") == reinterpret_cast<void*>(&strsm_));
  CHECK(dlsym(RTLD_DEFAULT, "dtrsm_") == reinterpret_cast<void*>(&dtrsm_));
  check_trsm<float>("strsm_");
  check_trsm<double>("dtrsm_");
#ifdef MAXENTFLOW_HAVE_MUMPS
  {  // MUMPS's one-right-hand-side solve of a 2-D Laplacian (fronts with
     // contribution blocks) goes through it, and solves.
    const int s = 40, n = s * s;
    std::vector<Eigen::Triplet<double>> t;
    for (int j = 0; j < s; ++j)
      for (int i = 0; i < s; ++i) {
        const int a = j * s + i;
        t.emplace_back(a, a, 4.0);
        if (i > 0) t.emplace_back(a, a - 1, -1.0);
        if (i + 1 < s) t.emplace_back(a, a + 1, -1.0);
        if (j > 0) t.emplace_back(a, a - s, -1.0);
        if (j + 1 < s) t.emplace_back(a, a + s, -1.0);
      }
    Eigen::SparseMatrix<double, Eigen::ColMajor, int> L(n, n);
    L.setFromTriplets(t.begin(), t.end());
    L.makeCompressed();
    const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(n, -1.0, 2.0);
    BasicMumpsSolver<double> mumps;
    mumps.analyze(L);
    mumps.factorize(L);
    const long long before = blas_gemv_forwards();
    const Eigen::VectorXd x = mumps.solve(b);
    CHECK(blas_gemv_forwards() > before);
    CHECK((L * x - b).norm() <= 1e-12 * b.norm());
  }
#endif
}
