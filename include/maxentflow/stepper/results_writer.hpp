// maxentflow: what a forming run leaves on disk: a VTU per output step with a
// PVD time series (ParaView), forces.csv, power.csv (the power balance),
// tools.csv (tool outlines for plots).
// Every file is written whole (temporary file + rename).
#pragma once

#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/core/error.hpp>
#include <maxentflow/io/csv.hpp>
#include <maxentflow/io/vtk.hpp>

namespace maxentflow {

class ResultsWriter {
 public:
  explicit ResultsWriter(std::filesystem::path dir, std::string prefix = "step")
      : dir_(std::move(dir)), prefix_(std::move(prefix)), pvd_(dir_ / (prefix_ + ".pvd")),
        forces_({"step", "time", "tool", "stroke", "fx", "fy"}),
        power_({"step", "time", "tool_power", "delivered_power", "plastic_power", "stabilization_power"}),
        tools_({"step", "tool", "x", "y"}) {
    std::filesystem::create_directories(dir_);
  }

  const std::filesystem::path& directory() const { return dir_; }

  /// After a step: appends the tool forces (on the configuration the step
  /// solved) and, if `vtu`, writes that configuration with its fields.
  template <class Stepper>
  void record(const Stepper& s, bool vtu) {
    const auto& r = s.history().back();
    const double t0 = r.time - r.dt;  // the solved configuration is the step's start
    for (std::size_t k = 0; k < s.tools().size(); ++k) {
      forces_.cell(r.step).cell(t0).cell(s.tools()[k].name()).cell(r.tool_stroke[k]);
      forces_.cell(r.tool_force[k].x()).cell(r.tool_force[k].y());
      forces_.end_row();
    }
    forces_.write(dir_ / "forces.csv");
    // What the tools deliver, what the whole boundary delivers, and where it
    // goes (StepRecord::power): a check of the loads, and the stabilization's
    // share of them.
    power_.cell(r.step).cell(t0).cell(r.tool_power).cell(r.power.delivered());
    power_.cell(r.power.plastic).cell(r.power.volumetric).end_row();
    power_.write(dir_ / "power.csv");
    if (!vtu) return;
    char name[64];
    std::snprintf(name, sizeof name, "%s_%04d.vtu", prefix_.c_str(), r.step);
    const auto& mesh = s.mesh();
    const auto n = s.nodes_solved().cols();
    std::vector<int> boundary(static_cast<std::size_t>(n), 0);
    for (int a : mesh.boundary_nodes()) boundary[static_cast<std::size_t>(a)] = 1;
    VtuWriter w;
    w.points(s.nodes_solved()).triangles(mesh.triangles());
    // The nodal fields marked for output (velocity, pressure, strain rate,
    // effective strain, and those a law or the user registered).
    for (const auto& f : s.nodal_fields().fields()) {
      if (!f.output) continue;
      const auto& v = f.values;
      if (v.rows() == 1)
        w.point_scalar(f.name, Eigen::Map<const Eigen::VectorXd>(v.data(), v.cols()));
      else if (v.rows() <= 3)
        w.point_vector(f.name, v);
      else
        for (Eigen::Index c = 0; c < v.rows(); ++c) w.point_scalar(detail::cat(f.name, "_", c), v.row(c).transpose());
    }
    w.point_scalar("boundary", boundary)
        .point_scalar("contact", s.contact_flags())
        .point_scalar("h", mesh.h());
    w.write(dir_ / name);
    pvd_.add(t0, name);
    pvd_.write();
    // Tool outlines in the same (step start) position.
    for (std::size_t k = 0; k < s.tools().size(); ++k) {
      const auto& tool = s.tools()[k];
      const Eigen::Matrix2Xd p = tool.polyline(mesh.h().mean());
      const Eigen::Vector2d back = -s.history().back().dt * tool.velocity();
      for (Eigen::Index i = 0; i < p.cols(); ++i) {
        tools_.cell(r.step).cell(tool.name()).cell(p(0, i) + back.x()).cell(p(1, i) + back.y());
        tools_.end_row();
      }
    }
    tools_.write(dir_ / "tools.csv");
  }

  /// What the writer has recorded so far (PVD entries, CSV rows), for a
  /// checkpoint: a restarted run appends to the same series.
  void save(CheckpointOut& out) const {
    pvd_.save(out);
    forces_.save(out);
    power_.save(out);
    tools_.save(out);
  }
  void load(CheckpointIn& in) {
    pvd_.load(in);
    forces_.load(in);
    power_.load(in);
    tools_.load(in);
  }

 private:
  std::filesystem::path dir_;
  std::string prefix_;
  PvdCollection pvd_;
  CsvTable forces_, power_, tools_;
};

}  // namespace maxentflow
