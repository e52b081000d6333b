// maxentflow: an integration mesh as a .vtu file (the mesh layer itself
// does no I/O).
#pragma once

#include <cstddef>
#include <filesystem>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/io/vtk.hpp>
#include <maxentflow/mesh/integration_mesh.hpp>

namespace maxentflow {

/// Writes the kept mesh as .vtu (whole, through a temporary file): per node the
/// boundary flag, h, the cut spacing, the convex-hull and orphan flags; per
/// triangle its area.
template <int Dim>
void write_vtu(const std::filesystem::path& path, const IntegrationMesh<Dim>& mesh) {
  const auto n = static_cast<std::size_t>(mesh.number_of_nodes());
  std::vector<int> boundary(n), hull(n), orphan(n, 0);
  for (std::size_t a = 0; a < n; ++a) {
    boundary[a] = mesh.is_boundary_node(static_cast<int>(a)) ? 1 : 0;
    hull[a] = mesh.is_convex_hull_node(static_cast<int>(a)) ? 1 : 0;
  }
  for (int a : mesh.orphan_nodes()) orphan[static_cast<std::size_t>(a)] = 1;
  const auto& area = mesh.areas();
  VtuWriter w;
  w.points(mesh.nodes())
      .triangles(mesh.triangles())
      .point_scalar("boundary", boundary)
      .point_scalar("h", mesh.h())
      .point_scalar("h_cut", mesh.cut_spacing())
      .point_scalar("on_convex_hull", hull)
      .point_scalar("orphan", orphan)
      .cell_scalar("area", Eigen::Map<const Eigen::VectorXd>(area.data(), static_cast<Eigen::Index>(area.size())));
  w.write(path);
}

}  // namespace maxentflow
