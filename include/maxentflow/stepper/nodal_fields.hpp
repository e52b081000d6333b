// maxentflow: named per-node arrays that travel with the nodes: saved and
// restored with a step, carried to the new numbering on rezoning, written to
// the VTU (docs/architecture.md).
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/core/error.hpp>
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
