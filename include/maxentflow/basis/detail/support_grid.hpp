// maxentflow: a cell grid that answers "which nodes' supports contain x".
#pragma once

#include <maxentflow/basis/detail/convex_hull.hpp>
#include <maxentflow/core/error.hpp>

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

namespace maxentflow::detail {

/// Uniform cell grid over the nodes' bounding box. Node a is registered in every
/// cell its support disc |x - x_a| <= R_a meets, so a query is one cell lookup
/// plus a distance filter, and node-dependent radii (graded clouds) cost nothing
/// extra. Cells are half the median radius wide: a query then filters about
/// (pi + 2 + 1/4) (R/h)^2 candidates (46 at R = 2.94 h) instead of the 9 (R/h)^2
/// (78) of cells a radius wide that register whole support boxes. Cells also
/// know where the convex hull is: cells that meet a hull facet carry the facet
/// list; the other cells are wholly inside or wholly outside.
template <int D>
class SupportGrid {
 public:
  using Point = Eigen::Matrix<double, D, 1>;
  enum class Cell : std::uint8_t { interior, boundary, exterior };
  /// The nodes a cell sees, as parallel arrays (a query's distance filter runs
  /// over them in SIMD lanes): coordinates, support radius squared, index; and
  /// beta and h of every node, by node index.
  struct Candidates {
    std::array<const double*, D> x;
    const double* r2;
    const int* node;
    int size;
    const double* node_beta;
    const double* node_h;
  };

  SupportGrid() = default;

  /// radius(a) may be +inf (a uniform prior: global support).
  void build(const Eigen::Matrix<double, D, Eigen::Dynamic>& nodes, const Eigen::VectorXd& radius,
             const Eigen::VectorXd& beta, const Eigen::VectorXd& h,
             const std::vector<HalfSpace<D>>& hull, double hull_pad) {
    const Eigen::Index N = nodes.cols();
    lo_ = nodes.rowwise().minCoeff();
    hi_ = nodes.rowwise().maxCoeff();
    // Cell size: half the median finite support radius, grown if the grid would be huge.
    std::vector<double> finite;
    finite.reserve(static_cast<std::size_t>(N));
    for (Eigen::Index a = 0; a < N; ++a)
      if (std::isfinite(radius(a))) finite.push_back(radius(a));
    const double extent = std::max((hi_ - lo_).maxCoeff(), std::numeric_limits<double>::min());
    double size = extent;
    if (!finite.empty()) {
      auto mid = finite.begin() + static_cast<std::ptrdiff_t>(finite.size() / 2);
      std::nth_element(finite.begin(), mid, finite.end());
      size = std::min(extent, 0.5 * *mid);
    }
    const double max_cells = 4.0 * static_cast<double>(N) + 64.0;
    for (;;) {
      double cells = 1;
      for (int k = 0; k < D; ++k) cells *= std::max(1.0, std::ceil((hi_(k) - lo_(k)) / size));
      if (cells <= max_cells) break;
      size *= 1.25;
    }
    size_ = size;
    total_ = 1;
    for (int k = 0; k < D; ++k) {
      n_[k] = std::max(1, static_cast<int>(std::ceil((hi_(k) - lo_(k)) / size_)));
      stride_[k] = total_;
      total_ *= n_[k];
    }
    // Registration in two passes (count, fill): CSR arrays, nodes ascending per cell.
    start_.assign(static_cast<std::size_t>(total_) + 1, 0);
    for (int pass = 0; pass < 2; ++pass) {
      std::vector<int> fill;
      if (pass == 1) {
        for (int c = 0; c < total_; ++c) start_[c + 1] += start_[c];
        const auto n = static_cast<std::size_t>(start_[total_]);
        for (auto& v : x_) v.resize(n);
        r2_.resize(n);
        node_.resize(n);
        fill.assign(start_.begin(), start_.end() - 1);
      }
      for (Eigen::Index a = 0; a < N; ++a) {
        std::array<int, D> first, last;
        const Point xa = nodes.col(a);
        box_cells(xa, radius(a), first, last);
        // Slack: registration must not miss a node that the query's own
        // floating-point distance test takes.
        const double reach2 = radius(a) * radius(a) * (1.0 + 1e-12);
        for_each_cell(first, last, [&](int c) {
          if (std::isfinite(reach2) && distance2_to_cell(xa, c) > reach2) return;
          if (pass == 0) {
            ++start_[c + 1];
            return;
          }
          const auto i = static_cast<std::size_t>(fill[c]++);
          for (int k = 0; k < D; ++k) x_[k][i] = nodes(k, a);
          r2_[i] = radius(a) * radius(a);
          node_[i] = static_cast<int>(a);
        });
      }
    }
    beta_.assign(beta.data(), beta.data() + N);
    h_.assign(h.data(), h.data() + N);
    classify(hull, hull_pad);
  }

  /// Cell that holds x (clamped to the grid).
  int cell_of(const Point& x) const {
    int c = 0;
    for (int k = 0; k < D; ++k) {
      int i = static_cast<int>(std::floor((x(k) - lo_(k)) / size_));
      c += std::clamp(i, 0, n_[k] - 1) * stride_[k];
    }
    return c;
  }

  /// Nodes whose support box overlaps cell c (a superset of the support of any x
  /// in c), ascending.
  Candidates candidates(int c) const {
    const auto i = static_cast<std::size_t>(start_[c]);
    Candidates out;
    for (int k = 0; k < D; ++k) out.x[k] = x_[k].data() + i;
    out.r2 = r2_.data() + i;
    out.node = node_.data() + i;
    out.size = start_[c + 1] - start_[c];
    out.node_beta = beta_.data();
    out.node_h = h_.data();
    return out;
  }

  Cell status(int c) const { return status_[static_cast<std::size_t>(c)]; }

  /// Hull facets that meet cell c (only for boundary cells).
  std::span<const int> facets(int c) const {
    return {facet_entries_.data() + facet_start_[c],
            static_cast<std::size_t>(facet_start_[c + 1] - facet_start_[c])};
  }

  /// True if x lies in the nodes' bounding box grown by pad.
  bool in_box(const Point& x, double pad) const {
    return ((x - lo_).array() >= -pad).all() && ((hi_ - x).array() >= -pad).all();
  }

  int cell_count() const { return total_; }
  double cell_size() const { return size_; }
  std::size_t registrations() const { return node_.size(); }

 private:
  // Squared distance from x to cell c; the border cells reach out to infinity
  // (queries just outside the bounding box fall in them).
  double distance2_to_cell(const Point& x, int c) const {
    double d2 = 0;
    for (int k = 0; k < D; ++k) {
      const int i = (c / stride_[k]) % n_[k];
      const double lo = lo_(k) + i * size_, hi = lo_(k) + (i + 1) * size_;
      double d = 0;
      if (x(k) < lo && i > 0) d = lo - x(k);
      if (x(k) > hi && i < n_[k] - 1) d = x(k) - hi;
      d2 += d * d;
    }
    return d2;
  }

  void box_cells(const Point& x, double r, std::array<int, D>& first, std::array<int, D>& last) const {
    for (int k = 0; k < D; ++k) {
      if (!std::isfinite(r)) {
        first[k] = 0;
        last[k] = n_[k] - 1;
        continue;
      }
      first[k] = std::clamp(static_cast<int>(std::floor((x(k) - r - lo_(k)) / size_)), 0, n_[k] - 1);
      last[k] = std::clamp(static_cast<int>(std::floor((x(k) + r - lo_(k)) / size_)), 0, n_[k] - 1);
    }
  }

  template <class F>
  void for_each_cell(const std::array<int, D>& first, const std::array<int, D>& last, F&& f) const {
    std::array<int, D> i = first;
    for (;;) {
      int c = 0;
      for (int k = 0; k < D; ++k) c += i[k] * stride_[k];
      f(c);
      int k = 0;
      while (k < D && ++i[k] > last[k]) {
        i[k] = first[k];
        ++k;
      }
      if (k == D) return;
    }
  }

  // Cells meeting a facet's (padded) bounding box are boundary cells; the rest is
  // split into interior and exterior by a flood fill from the grid's border (an
  // unmarked border cell cannot be inside the hull: the hull touches the bounding
  // box only along facets, which mark the cells they cross).
  void classify(const std::vector<HalfSpace<D>>& hull, double pad) {
    status_.assign(static_cast<std::size_t>(total_), Cell::interior);
    std::vector<int> count(static_cast<std::size_t>(total_) + 1, 0);
    for (int pass = 0; pass < 2; ++pass) {
      std::vector<int> fill;
      if (pass == 1) {
        facet_start_.assign(static_cast<std::size_t>(total_) + 1, 0);
        for (int c = 0; c < total_; ++c) facet_start_[c + 1] = facet_start_[c] + count[c];
        facet_entries_.resize(static_cast<std::size_t>(facet_start_[total_]));
        fill.assign(facet_start_.begin(), facet_start_.end() - 1);
      }
      for (std::size_t f = 0; f < hull.size(); ++f) {
        std::array<int, D> first, last;
        for (int k = 0; k < D; ++k) {
          first[k] = std::clamp(static_cast<int>(std::floor((hull[f].lo(k) - pad - lo_(k)) / size_)), 0, n_[k] - 1);
          last[k] = std::clamp(static_cast<int>(std::floor((hull[f].hi(k) + pad - lo_(k)) / size_)), 0, n_[k] - 1);
        }
        for_each_cell(first, last, [&](int c) {
          if (pass == 0) {
            ++count[c];
            status_[c] = Cell::boundary;
          } else {
            facet_entries_[static_cast<std::size_t>(fill[c]++)] = static_cast<int>(f);
          }
        });
      }
    }
    std::vector<int> stack;
    for (int c = 0; c < total_; ++c) {
      if (status_[c] != Cell::interior || !on_border(c)) continue;
      status_[c] = Cell::exterior;
      stack.push_back(c);
    }
    while (!stack.empty()) {
      const int c = stack.back();
      stack.pop_back();
      for (int k = 0; k < D; ++k) {
        const int i = (c / stride_[k]) % n_[k];
        for (int s : {-1, 1}) {
          if (i + s < 0 || i + s >= n_[k]) continue;
          const int nb = c + s * stride_[k];
          if (status_[nb] != Cell::interior) continue;
          status_[nb] = Cell::exterior;
          stack.push_back(nb);
        }
      }
    }
  }

  bool on_border(int c) const {
    for (int k = 0; k < D; ++k) {
      const int i = (c / stride_[k]) % n_[k];
      if (i == 0 || i == n_[k] - 1) return true;
    }
    return false;
  }

  Point lo_ = Point::Zero(), hi_ = Point::Zero();
  double size_ = 1;
  std::array<int, D> n_{}, stride_{};
  int total_ = 0;
  std::vector<int> start_;
  std::array<std::vector<double>, D> x_;
  std::vector<double> r2_;
  std::vector<int> node_;
  std::vector<double> beta_, h_;  // by node
  std::vector<Cell> status_;
  std::vector<int> facet_start_, facet_entries_;
};

}  // namespace maxentflow::detail
