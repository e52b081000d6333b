// maxentflow: named per-node arrays that travel with the nodes: saved and
// restored with a step, carried to the new numbering on rezoning, written to
// the VTU (docs/architecture.md).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/core/error.hpp>
#include <maxentflow/io/checkpoint.hpp>
#include <maxentflow/stepper/node_adaptivity.hpp>

namespace maxentflow {

/// Fields of the nodes: each a components x nodes matrix under a name. A
/// field with a state (effective strain, temperature) or a result (velocity,
/// pressure) is registered once; the stepper then saves it with a step (a
/// failed step restores it), transfers it on rezoning (kept nodes keep their
/// values, an inserted node gets the mean of its edge's ends) and writes the
/// fields marked `output` to each VTU.
class NodalFields {
 public:
  struct Field {
    std::string name;
    Eigen::MatrixXd values;  ///< components x nodes
    bool output = true;      ///< written to the VTU (1 component: scalar, 2: vector)
  };

  explicit NodalFields(Eigen::Index nodes = 0) : nodes_(nodes) {}

  /// Registers a field of `components` values per node, all `init`; returns its index.
  int add(std::string name, int components, bool output = true, double init = 0.0) {
    require(!name.empty() && components > 0,
            detail::cat("a nodal field needs a name and at least one component (got '", name, "', ",
                        components, ")"),
            "NodalFields::add");
    require(find(name) < 0, detail::cat("nodal field '", name, "' is already registered"), "NodalFields::add");
    fields_.push_back({std::move(name), Eigen::MatrixXd::Constant(components, nodes_, init), output});
    return static_cast<int>(fields_.size()) - 1;
  }
  /// The index of a field, -1 if there is none of that name.
  int find(const std::string& name) const {
    for (std::size_t k = 0; k < fields_.size(); ++k)
      if (fields_[k].name == name) return static_cast<int>(k);
    return -1;
  }
  /// The index of a field; throws naming the registered ones if there is none.
  int index(const std::string& name) const {
    const int k = find(name);
    if (k < 0) {
      std::string known;
      for (const auto& f : fields_) known += " '" + f.name + "'";
      throw Error(detail::cat("no nodal field '", name, "'; registered:", known), "NodalFields::index");
    }
    return k;
  }

  Eigen::MatrixXd& operator[](int k) { return fields_[static_cast<std::size_t>(k)].values; }
  const Eigen::MatrixXd& operator[](int k) const { return fields_[static_cast<std::size_t>(k)].values; }
  Eigen::MatrixXd& operator[](const std::string& name) { return (*this)[index(name)]; }
  const Eigen::MatrixXd& operator[](const std::string& name) const { return (*this)[index(name)]; }
  /// A field as one vector, a node's components consecutive (e.g. the velocity
  /// and pressure coefficients v_x, v_y, p of node a at 3a, 3a + 1, 3a + 2).
  Eigen::Map<Eigen::VectorXd> flat(int k) {
    auto& v = (*this)[k];
    return {v.data(), v.size()};
  }
  Eigen::Map<const Eigen::VectorXd> flat(int k) const {
    const auto& v = (*this)[k];
    return {v.data(), v.size()};
  }

  const std::vector<Field>& fields() const { return fields_; }
  Eigen::Index nodes() const { return nodes_; }

  /// Every field's values, for a checkpoint. load() needs the same fields
  /// registered (same names, components, order), as the run that wrote it had.
  void save(CheckpointOut& out) const {
    out.put(static_cast<std::int64_t>(nodes_)).put(static_cast<std::int64_t>(fields_.size()));
    for (const auto& f : fields_) out.put(f.name).put(f.values);
  }
  void load(CheckpointIn& in) {
    const auto nodes = static_cast<Eigen::Index>(in.get_count());
    const auto n = static_cast<std::size_t>(in.get_count());
    if (n != fields_.size())
      in.fail(detail::cat(n, " nodal fields, this run registers ", fields_.size()));
    std::vector<Eigen::MatrixXd> values;
    for (const auto& f : fields_) {
      const std::string name = in.get_string();
      Eigen::MatrixXd v = in.get_matrix();
      if (name != f.name || v.rows() != f.values.rows() || v.cols() != nodes)
        in.fail(detail::cat("nodal field '", name, "' (", v.rows(), " x ", v.cols(), ") where this run has '", f.name,
                            "' with ", f.values.rows(), " components for ", nodes, " nodes"));
      values.push_back(std::move(v));
    }
    for (std::size_t k = 0; k < n; ++k) fields_[k].values = std::move(values[k]);
    nodes_ = nodes;
  }

  /// Carries every field to the cloud after a rezoning.
  void transfer(const NodeAdaptation& a) {
    for (auto& f : fields_) f.values = a.transfer(f.values);
    nodes_ = nodes_ - static_cast<Eigen::Index>(a.removed.size()) + a.added();
  }

 private:
  Eigen::Index nodes_ = 0;
  std::vector<Field> fields_;
};

}  // namespace maxentflow
