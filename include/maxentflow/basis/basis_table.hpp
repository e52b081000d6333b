// maxentflow: the basis at a set of points, in a compact layout an assembler
// streams through (one run of entries per point, like a CSR matrix row).
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <memory>
#include <new>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

namespace maxentflow {

namespace detail {

/// An allocator whose value-initialization is default-initialization, so that
/// resizing a large output array does not first write zeros over it.
template <class T>
struct default_init_allocator : std::allocator<T> {
  template <class U>
  struct rebind {
    using other = default_init_allocator<U>;
  };
  default_init_allocator() = default;
  template <class U>
  default_init_allocator(const default_init_allocator<U>&) noexcept {}
  template <class U>
  void construct(U* ptr) noexcept(std::is_nothrow_default_constructible_v<U>) {
    ::new (static_cast<void*>(ptr)) U;
  }
  template <class U, class... Args>
  void construct(U* ptr, Args&&... args) {
    ::new (static_cast<void*>(ptr)) U(std::forward<Args>(args)...);
  }
};

template <class T>
using buffer = std::vector<T, default_init_allocator<T>>;

}  // namespace detail

/// p_a(x_i) and grad p_a(x_i) for every point i and every node a in the support
/// of x_i (|x_i - x_a| within the cut-off radius). Entries of point i are
/// [offset[i], offset[i+1]), with node indices ascending. On a convex-hull facet
/// the nodes off the facet keep their entry with p = 0 (their gradient is not 0).
template <int Dim>
struct BasisTable {
  detail::buffer<int> offset = detail::buffer<int>(1, 0);
  detail::buffer<int> node;
  detail::buffer<double> p;
  detail::buffer<double> grad;            // Dim values per entry; empty if values only
  detail::buffer<int> iterations;         // Newton iterations per point
  detail::buffer<unsigned char> on_hull;  // 1 if the point lies on a convex-hull facet

  int size() const { return static_cast<int>(offset.size()) - 1; }
  std::size_t entries() const { return node.size(); }
  bool has_gradients() const { return grad.size() == node.size() * Dim; }

  int count(int i) const { return offset[i + 1] - offset[i]; }
  std::span<const int> nodes(int i) const {
    return {node.data() + offset[i], static_cast<std::size_t>(count(i))};
  }
  std::span<const double> values(int i) const {
    return {p.data() + offset[i], static_cast<std::size_t>(count(i))};
  }
  /// Column j holds grad p of the j-th entry of point i.
  Eigen::Map<const Eigen::Matrix<double, Dim, Eigen::Dynamic>> gradients(int i) const {
    return {grad.data() + static_cast<std::size_t>(offset[i]) * Dim, Dim, count(i)};
  }

  double mean_iterations() const {
    if (iterations.empty()) return 0;
    double s = 0;
    for (int k : iterations) s += k;
    return s / static_cast<double>(iterations.size());
  }
  int max_iterations() const {
    int m = 0;
    for (int k : iterations) m = k > m ? k : m;
    return m;
  }
};

}  // namespace maxentflow
