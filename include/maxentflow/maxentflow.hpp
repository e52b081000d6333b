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
#include <maxentflow/io/csv.hpp>
#include <maxentflow/material/norton_hoff.hpp>
#include <maxentflow/flow/flow_discretization.hpp>
#include <maxentflow/flow/stabilized_flow.hpp>
#include <maxentflow/flow/constraints.hpp>
#include <maxentflow/flow/flow_system.hpp>
#include <maxentflow/solver/krylov_solver.hpp>
#include <maxentflow/solver/linear_solver.hpp>
#include <maxentflow/solver/nonlinear_solver.hpp>
#include <maxentflow/contact/rigid_tool.hpp>
#include <maxentflow/contact/contact.hpp>
#include <maxentflow/stepper/node_adaptivity.hpp>
#include <maxentflow/stepper/stepper.hpp>
#include <maxentflow/stepper/results_writer.hpp>
