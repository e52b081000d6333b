// maxentflow: umbrella header (every component).
#pragma once

#include <maxentflow/core/error.hpp>
#include <maxentflow/core/parallel.hpp>
#include <maxentflow/core/traits.hpp>
#include <maxentflow/basis/basis_table.hpp>
#include <maxentflow/basis/maxent_basis.hpp>
#include <maxentflow/io/atomic_file.hpp>
#include <maxentflow/io/vtk.hpp>
#include <maxentflow/mesh/integration_mesh.hpp>
#include <maxentflow/mesh/nodal_spacing.hpp>
#include <maxentflow/mesh/quadrature.hpp>
