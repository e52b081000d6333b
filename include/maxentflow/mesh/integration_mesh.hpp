// maxentflow: the integration mesh. The paper integrates on "the Delaunay
// triangulation of the cloud of nodes in combination with the alpha-shape
// technique", removing "the triangles whose circum-radius is bigger than a
// given value" (paragraph before "Numerical examples"). The mesh is rebuilt
// from scratch every step as the nodes move; the alpha-shape alone finds free
// surfaces, so it decides what is material.
//
// The cut. A Delaunay triangle T is kept when its circumradius
// R_T <= alpha h_T, h_T the mean of the cut spacing h_a of its three nodes, and
// (drop_slivers) its area exceeds sliver_tolerance times its longest edge^2.
//
// The cut spacing, and why not the paper's h. The natural-neighbour mean of
// the full Delaunay mesh is polluted exactly where the cut matters: across a
// concavity the Delaunay mesh joins boundary nodes by long edges (a slot's
// walls, an extrusion's billet corner to its product tip), which inflate h
// there and let the bridging triangles pass. So:
//  1. start: h_a = median of the `cut_neighbours` (4) shortest Delaunay edges
//     at a, capped by the median of that value over a's Delaunay neighbours (a
//     convex corner beside a void has only 2 material edges of its own);
//     cut once with it;
//  2. fixed point: h_a = sqrt(2) * median circumradius of the KEPT triangles
//     at a, cut again; repeat until the kept set repeats (1-2 re-cuts in
//     practice, at most `cut_iterations`).
// Step 2 measures the local node spacing on material only (bridges do not
// feed back, unlike edge means, which ratchet slots shut from their ends), and
// it follows anisotropy: on any regular lattice (square, rectangular, sheared,
// compressed) all triangles share R and h_a = sqrt(2) R, i.e. the grid spacing
// on a square grid and sqrt((a^2 + b^2)/2) on an a x b grid, so R_T/h_T = 0.71
// everywhere. Step 1 alone under-estimates h on compressed, jittered clouds
// (shortest edges across the compressed direction) and loses interior
// triangles there. h() is then the paper's natural-neighbour mean on the kept
// mesh (nodal_spacing()); cut_spacing() is the h_a of the last cut.
//
// The default alpha = 1.3, between two failure modes (measured by the "alpha
// sweep" test and the clouds of the other tests, h = grid spacing):
//  - too small loses interior triangles of distorted clouds: a square with
//    30 % random perturbation and a sheared, 2:1 compressed one with 20 % are
//    whole from alpha = 1.05 on; 40 % perturbation, or 4:1 compression with
//    15 %, from 1.2 (a regular grid: from 0.71). 10:1 compression AND
//    perturbation needs more than any alpha that keeps slots open;
//  - too large bridges gaps: a slot of width w whose walls face each other
//    node for node is bridged by triangles with R = sqrt(h^2 + w^2)/2, so it
//    stays open iff w > h sqrt(4 alpha^2 - 1), 2.4 h at alpha = 1.3 (tests: a
//    2.5 h slot closes at alpha 1.35, a 3 h slot at 1.6). Narrower slots are
//    bridged: locally they are indistinguishable from a compressed grid,
//    which must be kept. Staggered walls: open iff
//    w > (alpha + sqrt(alpha^2 - 1/4)) h, 2.5 h at 1.3.
// Either way a 90-degree re-entrant corner of a grid is chamfered by half a
// cell (that triangle is congruent to the interior ones), wedges narrower than
// about 135 degrees are filled near their apex, and boundary nodes perturbed
// off a straight side are followed exactly (the slivers of three nearly
// collinear boundary nodes are cut).
//
// Licence: CGAL's 2-D triangulation is GPL-3.0+ (see README).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/core/error.hpp>
#include <maxentflow/mesh/detail/delaunay_2.hpp>
#include <maxentflow/mesh/detail/spacing.hpp>
#include <maxentflow/mesh/quadrature.hpp>

namespace maxentflow {

/// Quadrature points with weights and the cell (triangle, edge or boundary
/// segment) each belongs to; `normal` is set for edge and boundary points.
template <int Dim>
struct BasicQuadraturePoints {
  Eigen::Matrix<double, Dim, Eigen::Dynamic> x;
  Eigen::VectorXd w;
  std::vector<int> cell;
  Eigen::Matrix<double, Dim, Eigen::Dynamic> normal;
  Eigen::Index size() const { return w.size(); }
};
using QuadraturePoints = BasicQuadraturePoints<2>;

/// A boundary edge of the kept mesh, running counter-clockwise around the
/// material (material on its left), with the outward unit normal (dy, -dx)/length.
struct BoundarySegment {
  int a = -1;
  int b = -1;
  Eigen::Vector2d normal = Eigen::Vector2d::Zero();
  double length = 0.0;
  bool on_convex_hull = false;  ///< lies on the convex hull of all nodes
  int loop = -1;                ///< index into boundary_loops()
  int edge = -1;                ///< index into edges()
};

/// A closed simple boundary loop: nodes in order (the segment k runs from
/// nodes[k] to nodes[k+1 mod n]). Outer loops are counter-clockwise
/// (signed_area > 0), holes clockwise (signed_area < 0).
struct BoundaryLoop {
  std::vector<int> nodes;
  std::vector<int> segments;  ///< indices into boundary_segments(), in order
  double signed_area = 0.0;
  bool is_hole = false;
};

/// Delaunay triangulation of the nodes cut by the alpha-shape criterion, with
/// its edges, boundary loops, nodal spacing h and quadrature points.
/// 2-D is implemented; the interface (Dim, Cell, Points) is the 3-D one, as
/// MaxEntBasis<Dim> is templated on the dimension.
template <int Dim = 2>
class IntegrationMesh {
 public:
  static constexpr int dim = Dim;
  static_assert(dim == 2,
                "maxentflow: IntegrationMesh is implemented in 2-D only (3-D: "
                "Delaunay_triangulation_3 with the same alpha cut is future work)");
  using Points = Eigen::Matrix<double, Dim, Eigen::Dynamic>;  ///< one column per point
  using Point = Eigen::Matrix<double, Dim, 1>;
  using Cell = std::array<int, dim + 1>;
  using Edge = MeshEdge;
  using Quadrature = BasicQuadraturePoints<dim>;

  struct params {
    /// Keep a triangle when circumradius <= alpha * h (see the file comment).
    double alpha = 1.3;
    /// Points of the default cell rule (cell_rule()): 1, 3, 6, 7 or 12.
    int triangle_points = 6;
    /// Points of the default edge rule (edge_rule()): 1..8.
    int segment_points = 3;
    /// Drop triangles with area <= sliver_tolerance * (longest edge)^2
    /// (a computed area <= 0 is dropped in any case).
    bool drop_slivers = true;
    double sliver_tolerance = 1e-10;
    /// Start spacing: median of this many shortest Delaunay edges (0: all).
    int cut_neighbours = 4;
    /// Re-cuts with h from the kept triangles, until the kept set repeats
    /// (0: a single cut with the start spacing).
    int cut_iterations = 4;
    /// With set_solid(): drop triangles whose centroid lies deeper than this
    /// times h_T inside a solid.
    double solid_tolerance = 0.1;
  };
  /// Depth of a point inside solid obstacles (rigid tools): > 0 inside.
  using SolidDepth = std::function<double(const Eigen::Vector2d&)>;
  /// Whether the segment between two points passes through a solid from one
  /// side to another (a solid thinner than the node spacing).
  using SolidCrossing = std::function<bool(const Eigen::Vector2d&, const Eigen::Vector2d&)>;

  IntegrationMesh() = default;
  explicit IntegrationMesh(const params& p) : prm_(p) { check_params(); }
  explicit IntegrationMesh(const Points& nodes) { build(nodes); }
  IntegrationMesh(const Points& nodes, const params& p) : prm_(p) { build(nodes); }

  const params& parameters() const { return prm_; }
  void set_parameters(const params& p) {
    prm_ = p;
    check_params();
  }

  /// Triangulates `nodes`, applies the alpha cut and builds edges, boundary
  /// and h. O(N log N); buffers are reused across calls. Throws Error for
  /// fewer than 3 nodes, non-finite or coincident nodes, all nodes collinear,
  /// an empty mesh after the cut, or a boundary that is not closed loops;
  /// the mesh is then empty().
  void build(const Points& nodes);
  /// Solids the material cannot occupy (the tools), for the next builds: the
  /// alpha cut keeps a Delaunay triangle that bridges a tool's convex corner
  /// (a square die's corner between a node on the face and one on the land),
  /// so an interior node of that triangle could flow into the tool unseen by
  /// contact, which treats boundary nodes only. Such triangles are dropped,
  /// and with `crossing` those with an edge through a solid thinner than the
  /// spacing (a die land of 3 with nodes 10 apart), whose centroid may lie
  /// outside it or shallower than solid_tolerance: material on both sides
  /// would be joined through the solid and flow across it unseen by contact.
  void set_solid(SolidDepth depth, SolidCrossing crossing = {}) {
    solid_ = std::move(depth);
    crossing_ = std::move(crossing);
  }
  /// Triangles the last build dropped as inside or across a solid.
  int solid_dropped() const { return solid_dropped_; }
  /// No mesh (before the first build, or after a failed one).
  bool empty() const { return triangles_.empty(); }

  // --- the mesh ---
  const Points& nodes() const { return nodes_; }
  Eigen::Index number_of_nodes() const { return nodes_.cols(); }
  /// Kept triangles, counter-clockwise.
  const std::vector<Cell>& triangles() const { return triangles_; }
  Eigen::Index number_of_triangles() const { return static_cast<Eigen::Index>(triangles_.size()); }
  double area(int t) const { return area_[static_cast<std::size_t>(t)]; }
  const std::vector<double>& areas() const { return area_; }
  double total_area() const { return total_area_; }
  /// Triangles of the full Delaunay triangulation (before the cut).
  Eigen::Index number_of_delaunay_triangles() const {
    return static_cast<Eigen::Index>(dt_.tri.size());
  }
  /// Neighbour across the edge opposite local vertex i of kept triangle t (-1: none).
  int neighbour(int t, int i) const {
    return knbr_[static_cast<std::size_t>(t)][static_cast<std::size_t>(i)];
  }
  /// Index into edges() of the edge opposite local vertex i of triangle t.
  int triangle_edge(int t, int i) const {
    return tri_edge_[static_cast<std::size_t>(t)][static_cast<std::size_t>(i)];
  }

  // --- spacing ---
  /// Final h_a: natural-neighbour mean on the kept mesh (orphans: cut spacing).
  const Eigen::VectorXd& h() const { return h_; }
  /// The spacing the last alpha cut used (see the file comment).
  const Eigen::VectorXd& cut_spacing() const { return h_cut_; }
  /// Re-cuts the last build() made (0 .. params::cut_iterations).
  int cut_iterations_done() const { return iterations_; }
  /// Nodes in no kept triangle (e.g. a node expelled from the material).
  const std::vector<int>& orphan_nodes() const { return orphans_; }

  // --- edges and boundary ---
  /// Unique edges; interior edges run as in their left triangle, boundary
  /// edges have right = -1 and run counter-clockwise around the material.
  const std::vector<Edge>& edges() const { return edges_; }
  /// Boundary segments, loop by loop, in loop order.
  const std::vector<BoundarySegment>& boundary_segments() const { return segments_; }
  const std::vector<BoundaryLoop>& boundary_loops() const { return loops_; }
  bool is_boundary_node(int a) const { return boundary_flag_[static_cast<std::size_t>(a)] != 0; }
  /// Boundary nodes, ascending.
  const std::vector<int>& boundary_nodes() const { return boundary_nodes_; }
  /// Nodes on the convex hull of all nodes.
  bool is_convex_hull_node(int a) const { return hull_flag_[static_cast<std::size_t>(a)] != 0; }
  double perimeter() const { return perimeter_; }

  // --- quadrature ---
  const TriangleRule& cell_rule() const { return triangle_rule(prm_.triangle_points); }
  const SegmentRule& edge_rule() const { return segment_rule(prm_.segment_points); }

  /// Points of `rule` in every kept triangle; w includes the area and, when
  /// axisymmetric, 2 pi r (r = x(0)).
  Quadrature cell_quadrature(const TriangleRule& rule, bool axisymmetric = false) const {
    Quadrature q;
    cell_quadrature(rule, q, axisymmetric);
    return q;
  }
  /// The same into `q`, reusing its storage.
  void cell_quadrature(const TriangleRule& rule, Quadrature& q, bool axisymmetric = false) const;

  /// Points of `rule` on every edge (each once), x = x_a + t (x_b - x_a),
  /// w = length * weight (* 2 pi r), cell = edge index, normal = the unit
  /// normal out of the edge's left triangle (into the right one).
  Quadrature edge_quadrature(const SegmentRule& rule, bool axisymmetric = false) const {
    Quadrature q;
    edge_quadrature(rule, q, axisymmetric);
    return q;
  }
  void edge_quadrature(const SegmentRule& rule, Quadrature& q, bool axisymmetric = false) const;

  /// Points of `rule` on the boundary segments, cell = segment index,
  /// normal = outward unit normal.
  Quadrature boundary_quadrature(const SegmentRule& rule, bool axisymmetric = false) const {
    Quadrature q;
    boundary_quadrature(rule, q, axisymmetric);
    return q;
  }
  void boundary_quadrature(const SegmentRule& rule, Quadrature& q, bool axisymmetric = false) const;

 private:
  void build_mesh(const Points& nodes);
  void clear();
  void check_params() const;
  void compute_cut_spacing();
  void kept_radius_spacing();
  void alpha_cut(const std::string& where);
  void build_edges();
  void build_boundary(const std::string& where);
  int next_boundary_edge(int e, const std::string& where) const;
  void add_loop(std::size_t first, const std::string& where);
  template <class Rule, class Segments>
  void segment_points(const Rule& rule, const Segments& segs, Quadrature& q, bool axisymmetric,
                      const char* where) const;

  params prm_;
  SolidDepth solid_;
  SolidCrossing crossing_;
  int solid_dropped_ = 0;
  Points nodes_;
  detail::Delaunay2 dt_;
  std::vector<Cell> triangles_;
  std::vector<double> area_;
  double total_area_ = 0.0;
  std::vector<std::array<int, 3>> knbr_, tri_edge_;
  std::vector<int> dt2kept_, kept2dt_, previous_;
  int iterations_ = 0;
  std::vector<Edge> edges_;
  std::vector<char> edge_local_;  // local index (opposite vertex) of an edge in its left triangle
  std::vector<BoundarySegment> segments_;
  std::vector<BoundaryLoop> loops_;
  std::vector<char> boundary_flag_, hull_flag_;
  std::vector<int> boundary_nodes_, orphans_;
  double perimeter_ = 0.0;
  Eigen::VectorXd h_, h_cut_;
  Eigen::Matrix2Xd cc_;
  // scratch, kept for reuse across builds
  std::vector<MeshEdge> dt_edges_;
  std::vector<int> offset_, count_, out_count_, in_count_, out_edge_, next_, pos_, path_;
  std::vector<double> lengths_, radius_;
  std::vector<char> visited_;
};

// ---------------------------------------------------------------------------

template <int D>
void IntegrationMesh<D>::check_params() const {
  const std::string where = "IntegrationMesh::params";
  if (!(std::isfinite(prm_.alpha) && prm_.alpha > 0.0))
    throw Error(detail::cat("alpha = ", prm_.alpha, " must be positive and finite"), where);
  triangle_rule(prm_.triangle_points);  // throws for a count without a rule
  segment_rule(prm_.segment_points);
  if (!(prm_.sliver_tolerance >= 0.0 && prm_.sliver_tolerance < 0.1))
    throw Error(detail::cat("sliver_tolerance = ", prm_.sliver_tolerance, " outside [0, 0.1)"),
                where);
  if (prm_.cut_neighbours < 0 || prm_.cut_neighbours == 1)
    throw Error(detail::cat("cut_neighbours = ", prm_.cut_neighbours, " must be 0 or >= 2"), where);
  if (prm_.cut_iterations < 0)
    throw Error(detail::cat("cut_iterations = ", prm_.cut_iterations, " must be >= 0"), where);
  if (!(prm_.solid_tolerance >= 0.0 && std::isfinite(prm_.solid_tolerance)))
    throw Error(detail::cat("solid_tolerance = ", prm_.solid_tolerance, " must be >= 0 and finite"), where);
}

template <int D>
void IntegrationMesh<D>::build(const Points& nodes) {
  try {
    build_mesh(nodes);
  } catch (...) {
    clear();  // no half-built state: a failed build leaves an empty mesh
    throw;
  }
}

template <int D>
void IntegrationMesh<D>::clear() {
  nodes_.resize(2, 0);
  dt_.tri.clear();
  dt_.nbr.clear();
  triangles_.clear();
  area_.clear();
  total_area_ = 0.0;
  knbr_.clear();
  tri_edge_.clear();
  kept2dt_.clear();
  iterations_ = 0;
  edges_.clear();
  edge_local_.clear();
  segments_.clear();
  loops_.clear();
  boundary_flag_.clear();
  hull_flag_.clear();
  boundary_nodes_.clear();
  orphans_.clear();
  solid_dropped_ = 0;
  perimeter_ = 0.0;
  h_.resize(0);
  h_cut_.resize(0);
}

template <int D>
void IntegrationMesh<D>::build_mesh(const Points& nodes) {
  const std::string where = "IntegrationMesh::build";
  check_params();
  nodes_ = nodes;
  detail::delaunay_2(nodes_, dt_, where);  // checks count, finiteness, coincidence, collinearity
  compute_cut_spacing();
  alpha_cut(where);
  // Fixed point: h_a from the kept triangles at a, cut again, until the kept
  // set repeats (usually after one re-cut).
  iterations_ = 0;
  for (int it = 0; it < prm_.cut_iterations; ++it) {
    kept_radius_spacing();
    h_cut_.swap(h_);
    previous_.swap(kept2dt_);
    alpha_cut(where);
    ++iterations_;
    if (kept2dt_ == previous_) break;
  }
  build_edges();
  build_boundary(where);

  // Final h: the paper's natural-neighbour mean, on the kept mesh.
  detail::circumcentres(nodes_, triangles_, cc_);
  detail::natural_neighbour_spacing(nodes_, edges_, cc_, voronoi_tolerance, h_, count_);
  orphans_.clear();
  for (Eigen::Index a = 0; a < nodes_.cols(); ++a)
    if (count_[static_cast<std::size_t>(a)] == 0) {
      orphans_.push_back(static_cast<int>(a));
      h_[a] = h_cut_[a];
    }
}

template <int D>
void IntegrationMesh<D>::compute_cut_spacing() {
  const auto n = static_cast<std::size_t>(nodes_.cols());
  detail::edges_from_neighbours(dt_.tri, dt_.nbr, dt_edges_);
  // Incident edge lengths per node, compressed rows.
  offset_.assign(n + 1, 0);
  for (const auto& e : dt_edges_) {
    ++offset_[static_cast<std::size_t>(e.a) + 1];
    ++offset_[static_cast<std::size_t>(e.b) + 1];
  }
  for (std::size_t a = 0; a < n; ++a) offset_[a + 1] += offset_[a];
  lengths_.resize(static_cast<std::size_t>(offset_[n]));
  count_.assign(n, 0);
  for (const auto& e : dt_edges_) {
    const double len = (nodes_.col(e.b) - nodes_.col(e.a)).norm();
    for (int a : {e.a, e.b}) {
      const auto k = static_cast<std::size_t>(a);
      lengths_[static_cast<std::size_t>(offset_[k] + count_[k]++)] = len;
    }
  }
  h_cut_.resize(nodes_.cols());
  hull_flag_.assign(n, 0);
  for (std::size_t t = 0; t < dt_.tri.size(); ++t)
    for (std::size_t i = 0; i < 3; ++i)
      if (dt_.nbr[t][i] < 0) {
        hull_flag_[static_cast<std::size_t>(dt_.tri[t][(i + 1) % 3])] = 1;
        hull_flag_[static_cast<std::size_t>(dt_.tri[t][(i + 2) % 3])] = 1;
      }
  const auto k_max = static_cast<std::ptrdiff_t>(prm_.cut_neighbours);
  for (std::size_t a = 0; a < n; ++a) {
    auto first = lengths_.begin() + offset_[a];
    auto last = lengths_.begin() + offset_[a + 1];
    if (k_max > 0 && last - first > k_max) {
      std::nth_element(first, first + (k_max - 1), last);
      last = first + k_max;
    }
    std::sort(first, last);  // a handful of values
    const auto m = last - first;
    h_cut_[static_cast<Eigen::Index>(a)] =
        m % 2 ? first[m / 2] : 0.5 * (first[m / 2 - 1] + first[m / 2]);
  }
  // A convex corner next to a void has only 2 material edges, so its own
  // median may be a bridging edge: cap it by the median over its neighbours.
  std::fill(count_.begin(), count_.end(), 0);
  for (const auto& e : dt_edges_) {
    const auto a = static_cast<std::size_t>(e.a), b = static_cast<std::size_t>(e.b);
    lengths_[static_cast<std::size_t>(offset_[a] + count_[a]++)] = h_cut_[e.b];
    lengths_[static_cast<std::size_t>(offset_[b] + count_[b]++)] = h_cut_[e.a];
  }
  for (std::size_t a = 0; a < n; ++a) {
    const auto first = lengths_.begin() + offset_[a];
    const auto m = offset_[a + 1] - offset_[a];
    std::nth_element(first, first + m / 2, first + m);
    double median = first[m / 2];
    if (m % 2 == 0) median = 0.5 * (median + *std::max_element(first, first + m / 2));
    auto& h = h_cut_[static_cast<Eigen::Index>(a)];
    h = std::min(h, median);
  }
}

// h_a = sqrt 2 * median circumradius of the kept triangles at a (a regular
// grid: exactly h), into h_; nodes in no kept triangle keep h_cut_.
template <int D>
void IntegrationMesh<D>::kept_radius_spacing() {
  const auto n = static_cast<std::size_t>(nodes_.cols());
  offset_.assign(n + 1, 0);
  for (const auto& t : triangles_)
    for (int a : t) ++offset_[static_cast<std::size_t>(a) + 1];
  for (std::size_t a = 0; a < n; ++a) offset_[a + 1] += offset_[a];
  lengths_.resize(static_cast<std::size_t>(offset_[n]));
  count_.assign(n, 0);
  for (std::size_t k = 0; k < triangles_.size(); ++k) {
    const double R = radius_[static_cast<std::size_t>(kept2dt_[k])];
    for (int a : triangles_[k]) {
      const auto i = static_cast<std::size_t>(a);
      lengths_[static_cast<std::size_t>(offset_[i] + count_[i]++)] = R;
    }
  }
  h_.resize(nodes_.cols());
  for (std::size_t a = 0; a < n; ++a) {
    const auto m = offset_[a + 1] - offset_[a];
    if (m == 0) {
      h_[static_cast<Eigen::Index>(a)] = h_cut_[static_cast<Eigen::Index>(a)];
      continue;
    }
    const auto first = lengths_.begin() + offset_[a];
    std::nth_element(first, first + m / 2, first + m);
    double median = first[m / 2];
    if (m % 2 == 0) median = 0.5 * (median + *std::max_element(first, first + m / 2));
    h_[static_cast<Eigen::Index>(a)] = std::sqrt(2.0) * median;
  }
}

template <int D>
void IntegrationMesh<D>::alpha_cut(const std::string& where) {
  const std::size_t nt = dt_.tri.size();
  dt2kept_.assign(nt, -1);
  radius_.assign(nt, std::numeric_limits<double>::infinity());
  kept2dt_.clear();
  triangles_.clear();
  area_.clear();
  kept2dt_.reserve(nt);
  triangles_.reserve(nt);
  area_.reserve(nt);
  total_area_ = 0.0;
  solid_dropped_ = 0;
  for (std::size_t t = 0; t < nt; ++t) {
    const auto& v = dt_.tri[t];
    const Eigen::Vector2d p = nodes_.col(v[0]), q = nodes_.col(v[1]), r = nodes_.col(v[2]);
    const double A = detail::signed_area(p, q, r);
    const double la = (q - r).norm(), lb = (r - p).norm(), lc = (p - q).norm();
    const double lmax = std::max({la, lb, lc});
    if (!(A > 0.0)) continue;
    if (prm_.drop_slivers && A <= prm_.sliver_tolerance * lmax * lmax) continue;
    const double R = la * lb * lc / (4.0 * A);
    radius_[t] = R;
    const double h = (h_cut_[v[0]] + h_cut_[v[1]] + h_cut_[v[2]]) / 3.0;
    if (R > prm_.alpha * h) continue;
    if ((solid_ && solid_((p + q + r) / 3.0) > prm_.solid_tolerance * h) ||
        (crossing_ && (crossing_(p, q) || crossing_(q, r) || crossing_(r, p)))) {
      ++solid_dropped_;
      continue;
    }
    dt2kept_[t] = static_cast<int>(triangles_.size());
    kept2dt_.push_back(static_cast<int>(t));
    triangles_.push_back({v[0], v[1], v[2]});
    area_.push_back(A);
    total_area_ += A;
  }
  if (triangles_.empty())
    throw Error(detail::cat("the alpha-shape (alpha = ", prm_.alpha, ") keeps none of the ", nt,
                            " Delaunay triangles"),
                where);
  knbr_.resize(triangles_.size());
  for (std::size_t k = 0; k < triangles_.size(); ++k)
    for (std::size_t i = 0; i < 3; ++i) {
      const int n = dt_.nbr[static_cast<std::size_t>(kept2dt_[k])][i];
      knbr_[k][i] = n < 0 ? -1 : dt2kept_[static_cast<std::size_t>(n)];
    }
}

template <int D>
void IntegrationMesh<D>::build_edges() {
  edges_.clear();
  edge_local_.clear();
  edges_.reserve(2 * triangles_.size() + 16);
  edge_local_.reserve(2 * triangles_.size() + 16);
  tri_edge_.resize(triangles_.size());
  for (std::size_t t = 0; t < triangles_.size(); ++t)
    for (std::size_t i = 0; i < 3; ++i) {
      const int n = knbr_[t][i];
      if (n >= 0 && n < static_cast<int>(t)) continue;  // emitted from n
      const int e = static_cast<int>(edges_.size());
      edges_.push_back(
          {triangles_[t][(i + 1) % 3], triangles_[t][(i + 2) % 3], static_cast<int>(t), n});
      edge_local_.push_back(static_cast<char>(i));
      tri_edge_[t][i] = e;
      if (n >= 0) {
        const auto& g = knbr_[static_cast<std::size_t>(n)];
        const std::size_t j = g[0] == static_cast<int>(t) ? 0 : g[1] == static_cast<int>(t) ? 1 : 2;
        tri_edge_[static_cast<std::size_t>(n)][j] = e;
      }
    }
}

// The outgoing boundary edge that follows boundary edge e at its end node v:
// the unique one, or at a pinch node (several), the one reached by turning
// around v through kept triangles from e's triangle, so that each loop closes
// around one fan of triangles.
template <int D>
int IntegrationMesh<D>::next_boundary_edge(int e, const std::string& where) const {
  const int v = edges_[static_cast<std::size_t>(e)].b;
  if (out_count_[static_cast<std::size_t>(v)] == 1) return out_edge_[static_cast<std::size_t>(v)];
  int t = edges_[static_cast<std::size_t>(e)].left;
  for (std::size_t guard = 0; guard <= triangles_.size(); ++guard) {
    const auto& c = triangles_[static_cast<std::size_t>(t)];
    const std::size_t j = c[0] == v ? 0 : c[1] == v ? 1 : 2;
    const std::size_t k = (j + 2) % 3;  // edge from v to c[j+1]
    const int n = knbr_[static_cast<std::size_t>(t)][k];
    if (n < 0) return tri_edge_[static_cast<std::size_t>(t)][k];
    t = n;
  }
  throw Error(detail::cat("boundary is not a set of closed simple loops: no way around node ", v),
              detail::cat(where, ", node ", v));
}

template <int D>
void IntegrationMesh<D>::build_boundary(const std::string& where) {
  const auto n = static_cast<std::size_t>(nodes_.cols());
  out_count_.assign(n, 0);
  in_count_.assign(n, 0);
  out_edge_.assign(n, -1);
  for (std::size_t e = 0; e < edges_.size(); ++e)
    if (edges_[e].right < 0) {
      const auto a = static_cast<std::size_t>(edges_[e].a),
                 b = static_cast<std::size_t>(edges_[e].b);
      ++out_count_[a];
      ++in_count_[b];
      out_edge_[a] = static_cast<int>(e);
    }
  for (std::size_t a = 0; a < n; ++a)
    if (out_count_[a] != in_count_[a])
      throw Error(detail::cat("boundary is not a set of closed loops: node ", a, " starts ",
                              out_count_[a], " and ends ", in_count_[a], " boundary edges"),
                  detail::cat(where, ", node ", a));

  next_.assign(edges_.size(), -1);
  for (std::size_t e = 0; e < edges_.size(); ++e)
    if (edges_[e].right < 0) next_[e] = next_boundary_edge(static_cast<int>(e), where);

  // Walk each cycle of next_; split it where it revisits a node (a hole
  // touching the outer boundary) so that every loop is simple.
  segments_.clear();
  loops_.clear();
  perimeter_ = 0.0;
  visited_.assign(edges_.size(), 0);
  pos_.assign(n, -1);
  for (std::size_t e0 = 0; e0 < edges_.size(); ++e0) {
    if (edges_[e0].right >= 0 || visited_[e0]) continue;
    path_.clear();
    pos_[static_cast<std::size_t>(edges_[e0].a)] = 0;
    int e = static_cast<int>(e0);
    int w = -1;
    for (;;) {
      visited_[static_cast<std::size_t>(e)] = 1;
      path_.push_back(e);
      w = edges_[static_cast<std::size_t>(e)].b;
      const int p = pos_[static_cast<std::size_t>(w)];
      if (p >= 0) {
        add_loop(static_cast<std::size_t>(p), where);
        path_.resize(static_cast<std::size_t>(p));
      }
      pos_[static_cast<std::size_t>(w)] = static_cast<int>(path_.size());
      e = next_[static_cast<std::size_t>(e)];
      if (visited_[static_cast<std::size_t>(e)]) break;
    }
    pos_[static_cast<std::size_t>(w)] = -1;
    if (!path_.empty() || e != static_cast<int>(e0))
      throw Error("boundary is not a set of closed simple loops (open walk)",
                  detail::cat(where, ", boundary edge ", e0));
  }

  boundary_flag_.assign(n, 0);
  boundary_nodes_.clear();
  for (const auto& s : segments_) {
    if (!boundary_flag_[static_cast<std::size_t>(s.a)]) boundary_nodes_.push_back(s.a);
    boundary_flag_[static_cast<std::size_t>(s.a)] = 1;
  }
  std::sort(boundary_nodes_.begin(), boundary_nodes_.end());
}

// Appends path_[first..] as a loop with its segments.
template <int D>
void IntegrationMesh<D>::add_loop(std::size_t first, const std::string& where) {
  BoundaryLoop loop;
  const int index = static_cast<int>(loops_.size());
  const std::size_t m = path_.size() - first;
  loop.nodes.reserve(m);
  loop.segments.reserve(m);
  const Eigen::Vector2d x0 = nodes_.col(edges_[static_cast<std::size_t>(path_[first])].a);
  double twice_area = 0.0;
  for (std::size_t k = first; k < path_.size(); ++k) {
    const auto& e = edges_[static_cast<std::size_t>(path_[k])];
    pos_[static_cast<std::size_t>(e.a)] = -1;
    const Eigen::Vector2d xa = nodes_.col(e.a), xb = nodes_.col(e.b);
    const Eigen::Vector2d d = xb - xa;
    twice_area += (xa.x() - x0.x()) * (xb.y() - x0.y()) - (xa.y() - x0.y()) * (xb.x() - x0.x());
    BoundarySegment s;
    s.a = e.a;
    s.b = e.b;
    s.length = d.norm();
    s.normal = Eigen::Vector2d(d.y(), -d.x()) / s.length;
    const auto t = static_cast<std::size_t>(kept2dt_[static_cast<std::size_t>(e.left)]);
    s.on_convex_hull =
        dt_.nbr[t][static_cast<std::size_t>(edge_local_[static_cast<std::size_t>(path_[k])])] < 0;
    s.loop = index;
    s.edge = path_[k];
    loop.nodes.push_back(e.a);
    loop.segments.push_back(static_cast<int>(segments_.size()));
    perimeter_ += s.length;
    segments_.push_back(s);
  }
  if (m < 3)
    throw Error(detail::cat("boundary is not a set of closed simple loops: a loop of ", m,
                            " segments through node ", loop.nodes.front()),
                detail::cat(where, ", node ", loop.nodes.front()));
  loop.signed_area = 0.5 * twice_area;
  loop.is_hole = loop.signed_area < 0.0;
  loops_.push_back(std::move(loop));
}

template <int D>
void IntegrationMesh<D>::cell_quadrature(const TriangleRule& rule, Quadrature& q,
                                         bool axisymmetric) const {
  const auto np = static_cast<Eigen::Index>(rule.weight.size());
  const auto total = np * number_of_triangles();
  q.x.resize(2, total);
  q.w.resize(total);
  q.cell.resize(static_cast<std::size_t>(total));
  q.normal.resize(2, 0);
  constexpr double two_pi = 6.283185307179586476925;
  Eigen::Index k = 0;
  for (std::size_t t = 0; t < triangles_.size(); ++t) {
    const auto& v = triangles_[t];
    for (Eigen::Index i = 0; i < np; ++i, ++k) {
      const auto& b = rule.bary[static_cast<std::size_t>(i)];
      q.x.col(k) = b[0] * nodes_.col(v[0]) + b[1] * nodes_.col(v[1]) + b[2] * nodes_.col(v[2]);
      double w = area_[t] * rule.weight[static_cast<std::size_t>(i)];
      if (axisymmetric) {
        if (q.x(0, k) < 0.0)
          throw Error(detail::cat("axisymmetric quadrature point at r = ", q.x(0, k),
                                  " < 0: the mesh crosses the axis"),
                      detail::cat("IntegrationMesh::cell_quadrature, triangle ", t));
        w *= two_pi * q.x(0, k);
      }
      q.w[k] = w;
      q.cell[static_cast<std::size_t>(k)] = static_cast<int>(t);
    }
  }
}

template <int D>
template <class Rule, class Segments>
void IntegrationMesh<D>::segment_points(const Rule& rule, const Segments& segs, Quadrature& q,
                                        bool axisymmetric, const char* where) const {
  const auto np = static_cast<Eigen::Index>(rule.weight.size());
  const auto total = np * static_cast<Eigen::Index>(segs.size());
  q.x.resize(2, total);
  q.w.resize(total);
  q.cell.resize(static_cast<std::size_t>(total));
  q.normal.resize(2, total);
  constexpr double two_pi = 6.283185307179586476925;
  Eigen::Index k = 0;
  for (std::size_t s = 0; s < segs.size(); ++s) {
    const Eigen::Vector2d xa = nodes_.col(segs[s].a), xb = nodes_.col(segs[s].b);
    const Eigen::Vector2d d = xb - xa;
    const double len = d.norm();
    const Eigen::Vector2d n(d.y() / len, -d.x() / len);
    for (Eigen::Index i = 0; i < np; ++i, ++k) {
      const double t = rule.t[static_cast<std::size_t>(i)];
      // x_a + t (x_b - x_a): on an axis-parallel edge (plates, symmetry lines)
      // the constant coordinate is reproduced bit-exactly; (1-t) x_a + t x_b
      // would round it.
      q.x.col(k) = xa + t * d;
      double w = len * rule.weight[static_cast<std::size_t>(i)];
      if (axisymmetric) {
        if (q.x(0, k) < 0.0)
          throw Error(detail::cat("axisymmetric quadrature point at r = ", q.x(0, k),
                                  " < 0: the mesh crosses the axis"),
                      detail::cat("IntegrationMesh::", where, ", segment ", s));
        w *= two_pi * q.x(0, k);
      }
      q.w[k] = w;
      q.cell[static_cast<std::size_t>(k)] = static_cast<int>(s);
      q.normal.col(k) = n;
    }
  }
}

template <int D>
void IntegrationMesh<D>::edge_quadrature(const SegmentRule& rule, Quadrature& q,
                                         bool axisymmetric) const {
  segment_points(rule, edges_, q, axisymmetric, "edge_quadrature");
}

template <int D>
void IntegrationMesh<D>::boundary_quadrature(const SegmentRule& rule, Quadrature& q,
                                             bool axisymmetric) const {
  segment_points(rule, segments_, q, axisymmetric, "boundary_quadrature");
}

}  // namespace maxentflow
