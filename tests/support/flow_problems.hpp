// Flow problems for the tests: a rectangular block of nodes with its mesh,
// basis, discretization and system, owned together (the system refers to them).
#pragma once

#include <maxentflow/maxentflow.hpp>

#include <memory>
#include <random>

namespace maxentflow::test {

/// nx x ny nodes on [0, W] x [0, H]; perturbed: interior nodes moved up to
/// 0.3 h each way, boundary nodes only along their side (the block stays a rectangle).
inline Eigen::Matrix2Xd block_nodes(int nx, int ny, double W, double H, bool perturbed,
                                    unsigned seed = 5) {
  Eigen::Matrix2Xd x(2, nx * ny);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  const double hx = W / (nx - 1), hy = H / (ny - 1);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      double s = i * hx, t = j * hy;
      if (perturbed) {
        if (i > 0 && i < nx - 1) s += u(rng) * hx;
        if (j > 0 && j < ny - 1) t += u(rng) * hy;
      }
      x.col(j * nx + i) << s, t;
    }
  return x;
}

template <class Material>
struct FlowProblem {
  IntegrationMesh<> mesh;
  std::unique_ptr<MaxEntBasis<2>> basis;
  FlowDiscretization disc;
  std::unique_ptr<FlowSystem<Material>> system;

  FlowProblem(const Eigen::Matrix2Xd& nodes, Geometry g, Material m, double gamma = 1.6,
              typename StabilizedFlowAssembler<Material>::params ap = {},
              FlowDiscretization::params dp = {})
      : mesh(nodes) {
    MaxEntBasis<2>::params bp;
    bp.gamma = gamma;
    basis = std::make_unique<MaxEntBasis<2>>(nodes, mesh.h(), bp);
    disc.build(mesh, *basis, g, dp);
    system = std::make_unique<FlowSystem<Material>>(mesh, disc, m, ap);
  }
  ConstraintSet& constraints() { return system->constraints(); }
  void velocity(const SegmentSelector& s, Eigen::Vector2d dir, double value, const std::string& name) {
    system->constraints().add_velocity(mesh, disc, s, dir, [value](const Eigen::Vector2d&) { return value; },
                                       name);
  }
};

}  // namespace maxentflow::test
