// maxentflow: the one traits parameter (dimension, scalar, index) and the
// exchange types derived from it.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace maxentflow {

/// Dimension, scalar and index types of a problem. Components take this one
/// parameter (as CGAL algorithms take a geometric traits class) and derive the
/// rest; users name only the dimension in most cases: `Traits<2>`.
template <int Dim_, class Scalar_ = double, class Index_ = int>
struct Traits {
  static_assert(Dim_ >= 1 && Dim_ <= 3, "maxentflow: dimension must be 1, 2 or 3");
  static constexpr int dim = Dim_;
  using Scalar = Scalar_;
  using Index = Index_;
  using Point = Eigen::Matrix<Scalar, Dim_, 1>;
  using Tensor = Eigen::Matrix<Scalar, Dim_, Dim_>;
  /// Node or point coordinates, one column per point.
  using Points = Eigen::Matrix<Scalar, Dim_, Eigen::Dynamic>;
  using Vector = Eigen::Matrix<Scalar, Eigen::Dynamic, 1>;
  using SparseMatrix = Eigen::SparseMatrix<Scalar, Eigen::ColMajor, Index>;
};

}  // namespace maxentflow
