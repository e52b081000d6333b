// maxentflow example: basis_functions — the local max-ent basis of the paper's
// Figs. 1-3, and the basis on a user's own node cloud.
//
// Compile with:  cmake --preset release && cmake --build --preset release --target basis_functions
//
// Sample runs:
//   basis_functions                                   (Figs. 1-3 into results/basis_functions/)
//   basis_functions --out-dir /tmp/figs --no-plots    (CSV only)
//   basis_functions --nodes nodes.csv --points points.csv --gamma 1.6 --out basis.csv
//
// Description:
//   Fig. 1: 1-D basis functions on 21 nodes whose locality gamma grows from left to
//   right (0.5, 1.0, 1.5, 2.5, 4.0): from smooth meshfree functions to the Delaunay
//   (hat) limit. Fig. 2: 1-D functions and their derivatives for gamma = 0.8.
//   Fig. 3: in 2-D (11 x 11 nodes, gamma = 1.6), the function of an interior node
//   and of a node on the boundary, which vanishes off its boundary edge (weak
//   Kronecker-delta property). With --nodes/--points it evaluates the basis of a
//   user's cloud (CSV `x,y[,h][,gamma]`; h defaults to the Delaunay spacing) at the
//   user's points (CSV `x,y`) and writes `point,node,p,dpdx,dpdy` (0-based indices
//   in input order) for every nonzero function.
#include <maxentflow/basis/maxent_basis.hpp>
#include <maxentflow/io/csv.hpp>
#include <maxentflow/mesh/nodal_spacing.hpp>

#include "common/plotting.hpp"

#include <CLI/CLI.hpp>

#include <cmath>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace maxentflow;

namespace {

using Nodes1 = Eigen::Matrix<double, 1, Eigen::Dynamic>;

// Samples a 1-D basis on [lo, hi] into a dense table x, p_a..., (dp_a...).
CsvTable sample_1d(const MaxEntBasis<1>& basis, double lo, double hi, int samples, bool derivatives,
                   double& worst_unity, double& worst_linear, double& worst_dsum) {
  const Eigen::Index N = basis.size();
  std::vector<std::string> header{"x"};
  for (Eigen::Index a = 0; a < N; ++a) header.push_back("p" + std::to_string(a));
  if (derivatives)
    for (Eigen::Index a = 0; a < N; ++a) header.push_back("dp" + std::to_string(a));
  CsvTable csv(header);
  Nodes1 x(1, samples);
  for (int i = 0; i < samples; ++i) x(0, i) = lo + (hi - lo) * i / (samples - 1);
  const auto t = basis.evaluate(x, derivatives);
  for (int i = 0; i < samples; ++i) {
    std::vector<double> p(static_cast<std::size_t>(N), 0.0), dp(static_cast<std::size_t>(N), 0.0);
    double unity = 0, linear = 0, dsum = 0;
    for (std::size_t j = 0; j < t.nodes(i).size(); ++j) {
      const int a = t.nodes(i)[j];
      p[static_cast<std::size_t>(a)] = t.values(i)[j];
      unity += t.values(i)[j];
      linear += t.values(i)[j] * basis.nodes()(0, a);
      if (derivatives) {
        dp[static_cast<std::size_t>(a)] = t.gradients(i)(0, static_cast<Eigen::Index>(j));
        dsum += dp[static_cast<std::size_t>(a)];
      }
    }
    worst_unity = std::max(worst_unity, std::abs(unity - 1));
    worst_linear = std::max(worst_linear, std::abs(linear - x(0, i)));
    worst_dsum = std::max(worst_dsum, std::abs(dsum));
    csv.cell(x(0, i));
    for (double v : p) csv.cell(v);
    if (derivatives)
      for (double v : dp) csv.cell(v);
    csv.end_row();
  }
  return csv;
}

int figures(const fs::path& out, bool plots, bool check) {
  double unity = 0, linear = 0, dsum = 0;

  // 1. Fig. 1: gamma growing across the axis, 21 nodes at unit spacing.
  const int n1 = 21;
  Nodes1 nodes1(1, n1);
  Eigen::VectorXd gamma1(n1);
  const double zones[5] = {0.5, 1.0, 1.5, 2.5, 4.0};
  for (int a = 0; a < n1; ++a) {
    nodes1(0, a) = a;
    gamma1(a) = zones[std::min(4, a * 5 / n1)];
  }
  const MaxEntBasis<1> fig1(nodes1, Eigen::VectorXd::Ones(n1), gamma1);
  sample_1d(fig1, 0, n1 - 1, 2001, false, unity, linear, dsum).write(out / "fig1_gamma_varying.csv");
  CsvTable nodes_csv({"x", "gamma"});
  for (int a = 0; a < n1; ++a) nodes_csv.row({nodes1(0, a), gamma1(a)});
  nodes_csv.write(out / "fig1_nodes.csv");

  // 2. Fig. 2: gamma = 0.8, 11 nodes; functions and derivatives.
  const int n2 = 11;
  Nodes1 nodes2(1, n2);
  for (int a = 0; a < n2; ++a) nodes2(0, a) = a;
  MaxEntBasis<1>::params p2;
  p2.gamma = 0.8;
  const MaxEntBasis<1> fig2(nodes2, Eigen::VectorXd::Ones(n2), p2);
  sample_1d(fig2, 0, n2 - 1, 1001, true, unity, linear, dsum).write(out / "fig2_gamma0.8.csv");

  // 3. Fig. 3: 2-D, 11 x 11 nodes on the unit square, gamma = 1.6: the function
  //    of an interior node (0.5, 0.5) and of a boundary node (0.5, 0).
  const int n3 = 11, samples = 121;
  Eigen::Matrix2Xd nodes3(2, n3 * n3);
  for (int j = 0; j < n3; ++j)
    for (int i = 0; i < n3; ++i) nodes3.col(j * n3 + i) << i / 10.0, j / 10.0;
  const MaxEntBasis<2> fig3(nodes3, Eigen::VectorXd::Constant(n3 * n3, 0.1));
  const int interior = 5 * n3 + 5, boundary = 5;
  Eigen::Matrix2Xd x3(2, samples * samples);
  for (int j = 0; j < samples; ++j)
    for (int i = 0; i < samples; ++i) x3.col(j * samples + i) << i / (samples - 1.0), j / (samples - 1.0);
  const auto t3 = fig3.evaluate(x3, false);
  CsvTable csv3({"x", "y", "p_interior", "p_boundary"});
  double interior_on_edge = 0, boundary_off_edge = 0;
  for (int k = 0; k < t3.size(); ++k) {
    double pi = 0, pb = 0;
    for (std::size_t j = 0; j < t3.nodes(k).size(); ++j) {
      if (t3.nodes(k)[j] == interior) pi = t3.values(k)[j];
      if (t3.nodes(k)[j] == boundary) pb = t3.values(k)[j];
    }
    if (x3(1, k) == 0.0) interior_on_edge = std::max(interior_on_edge, pi);  // weak Kronecker
    if (x3(0, k) == 0.0 || x3(0, k) == 1.0 || x3(1, k) == 1.0)
      boundary_off_edge = std::max(boundary_off_edge, x3(1, k) == 0.0 ? 0.0 : pb);
    csv3.row({x3(0, k), x3(1, k), pi, pb});
  }
  csv3.write(out / "fig3_2d.csv");

  std::cout << "basis_functions: wrote " << (out / "fig1_gamma_varying.csv").string() << ", "
            << (out / "fig2_gamma0.8.csv").string() << ", " << (out / "fig3_2d.csv").string() << "\n"
            << "  1-D partition of unity error " << unity << ", linear reproduction error " << linear
            << ", derivative sum " << dsum << "\n"
            << "  2-D interior function on the edge y = 0: max " << interior_on_edge
            << "; boundary function on the other edges: max " << boundary_off_edge << "\n";
  std::cout.flush();
  if (plots) examples::run_plot_script(fs::path(MAXENTFLOW_EXAMPLE_DIR) / "plot_basis_functions.py", "\"" + out.string() + "\"");
  if (check) {
    const bool ok = unity <= 1e-12 && linear <= 1e-11 && dsum <= 1e-10 && interior_on_edge == 0.0 &&
                    boundary_off_edge <= 1e-10;
    std::cout << (ok ? "check passed\n" : "CHECK FAILED\n");
    return ok ? 0 : 1;
  }
  return 0;
}

int user_cloud(const fs::path& nodes_file, const fs::path& points_file, double gamma, double tol0,
               const fs::path& out, bool check) {
  // 1. Read the nodes (x, y and optional h, gamma) and the points (x, y).
  const CsvData nd = read_csv(nodes_file);
  const auto nx = nd.values("x", nodes_file.string()), ny = nd.values("y", nodes_file.string());
  Eigen::Matrix2Xd nodes(2, static_cast<Eigen::Index>(nx.size()));
  for (std::size_t a = 0; a < nx.size(); ++a) nodes.col(static_cast<Eigen::Index>(a)) << nx[a], ny[a];
  const CsvData pd = read_csv(points_file);
  const auto px = pd.values("x", points_file.string()), py = pd.values("y", points_file.string());
  Eigen::Matrix2Xd points(2, static_cast<Eigen::Index>(px.size()));
  for (std::size_t i = 0; i < px.size(); ++i) points.col(static_cast<Eigen::Index>(i)) << px[i], py[i];

  // 2. h from the file or the Delaunay spacing; gamma from the file or --gamma.
  Eigen::VectorXd h = nd.column("h") >= 0
                          ? Eigen::Map<const Eigen::VectorXd>(nd.values("h").data(), nodes.cols()).eval()
                          : delaunay_spacing<2>(nodes);
  Eigen::VectorXd g = nd.column("gamma") >= 0
                          ? Eigen::Map<const Eigen::VectorXd>(nd.values("gamma").data(), nodes.cols()).eval()
                          : Eigen::VectorXd::Constant(nodes.cols(), gamma);
  MaxEntBasis<2>::params prm;
  prm.tol0 = tol0;
  const MaxEntBasis<2> basis(nodes, h, g, prm);

  // 3. Evaluate and write every nonzero function.
  const auto t = basis.evaluate(points, true);
  CsvTable csv({"point", "node", "p", "dpdx", "dpdy"});
  for (int i = 0; i < t.size(); ++i)
    for (std::size_t j = 0; j < t.nodes(i).size(); ++j) {
      if (t.values(i)[j] == 0.0) continue;
      const auto gr = t.gradients(i).col(static_cast<Eigen::Index>(j));
      csv.cell(i).cell(t.nodes(i)[j]).cell(t.values(i)[j]).cell(gr(0)).cell(gr(1));
      csv.end_row();
    }
  csv.write(out);
  std::cout << "basis_functions: " << nodes.cols() << " nodes, " << points.cols() << " points, "
            << csv.rows() << " nonzero values, mean Newton iterations " << t.mean_iterations()
            << " -> " << out.string() << "\n";

  // 4. --check: read the file back; every point must reproduce 1 and x exactly.
  if (check) {
    const CsvData back = read_csv(out);
    std::vector<double> sum(static_cast<std::size_t>(points.cols()), 0.0);
    Eigen::Matrix2Xd lin = Eigen::Matrix2Xd::Zero(2, points.cols());
    for (const auto& r : back.rows) {
      const auto i = static_cast<Eigen::Index>(r[0]);
      sum[static_cast<std::size_t>(i)] += r[2];
      lin.col(i) += r[2] * nodes.col(static_cast<Eigen::Index>(r[1]));
    }
    double worst = 0;
    for (Eigen::Index i = 0; i < points.cols(); ++i)
      worst = std::max({worst, std::abs(sum[static_cast<std::size_t>(i)] - 1),
                        (lin.col(i) - points.col(i)).norm() / h.minCoeff()});
    const bool ok = back.header == std::vector<std::string>{"point", "node", "p", "dpdx", "dpdy"} &&
                    worst <= 1e-12;
    std::cout << "check: worst consistency error " << worst << (ok ? " passed\n" : " FAILED\n");
    return ok ? 0 : 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // 1. Parse options.
  CLI::App app{"maxentflow basis_functions: the local max-ent basis (paper Figs. 1-3)"};
  std::string out_dir = "results/basis_functions", nodes_file, points_file, out_file;
  double gamma = 1.6, tol0 = 1e-6;
  bool no_plots = false, check = false;
  app.add_option("--out-dir", out_dir, "Folder for the figures' CSV and PNG files");
  app.add_option("--nodes", nodes_file, "Nodes CSV: header x,y and optional h,gamma")->check(CLI::ExistingFile);
  app.add_option("--points", points_file, "Points CSV: header x,y")->check(CLI::ExistingFile);
  app.add_option("--gamma", gamma, "Locality gamma when the nodes file has no gamma column")->check(CLI::PositiveNumber);
  app.add_option("--tol0", tol0, "Support cut-off on the prior weight")->check(CLI::Range(1e-300, 0.5));
  app.add_option("--out", out_file, "Output CSV: point,node,p,dpdx,dpdy");
  app.add_flag("--no-plots", no_plots, "Write CSV only (no matplotlib)");
  app.add_flag("--check", check, "Verify the results (consistency, weak Kronecker delta); exit 1 if not");
  CLI11_PARSE(app, argc, argv);

  try {
    // 2. A user's cloud, or the paper's figures.
    if (!nodes_file.empty() || !points_file.empty() || !out_file.empty()) {
      if (nodes_file.empty() || points_file.empty() || out_file.empty()) {
        std::cerr << "basis_functions: --nodes, --points and --out go together\n";
        return 2;
      }
      return user_cloud(nodes_file, points_file, gamma, tol0, out_file, check);
    }
    return figures(out_dir, !no_plots, check);
  } catch (const maxentflow::Error& e) {
    std::cerr << e.what() << "\n";
    return 1;
  }
}
