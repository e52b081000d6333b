// maxentflow: VTK XML output for ParaView: an UnstructuredGrid (.vtu) of points
// with triangle (or vertex) cells and point/cell arrays, and a .pvd collection
// for time series. ASCII with the shortest round-trip form of each double
// (std::to_chars), so values read back bit-identical. Files are written atomically.
#pragma once

#include <array>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/core/error.hpp>
#include <maxentflow/io/atomic_file.hpp>
#include <maxentflow/io/checkpoint.hpp>

namespace maxentflow {

namespace detail {

inline void append_number(std::string& s, double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  s.append(buf, r.ptr);
}

inline void append_number(std::string& s, long long v) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  s.append(buf, r.ptr);
}

/// Escapes the five XML special characters of an attribute value.
inline std::string xml_escape(std::string_view in) {
  std::string out;
  out.reserve(in.size());
  for (char c : in) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

}  // namespace detail

/// Writes one .vtu file: points (2-D gets z = 0), cells, and named arrays.
/// Array sizes are checked against the points/cells when written.
///   VtuWriter w; w.points(x).triangles(t).point_scalar("h", h).write("out/mesh.vtu");
class VtuWriter {
 public:
  /// Point coordinates, one column per point, 2 or 3 rows.
  VtuWriter& points(const Eigen::Ref<const Eigen::MatrixXd>& x) {
    if (x.rows() != 2 && x.rows() != 3)
      throw Error(detail::cat("points need 2 or 3 rows, got ", x.rows()), "VtuWriter::points");
    points_.setZero(3, x.cols());
    points_.topRows(x.rows()) = x;
    has_points_ = true;
    return *this;
  }

  /// Triangle cells (VTK_TRIANGLE), node indices into points().
  VtuWriter& triangles(const std::vector<std::array<int, 3>>& t) {
    conn_.clear();
    conn_.reserve(3 * t.size());
    for (const auto& c : t) conn_.insert(conn_.end(), c.begin(), c.end());
    cell_size_ = 3;
    cell_type_ = 5;
    return *this;
  }

  /// One VTK_VERTEX cell per point (a point cloud ParaView can render).
  VtuWriter& vertex_cells() {
    if (!has_points_) throw Error("set points() before vertex_cells()", "VtuWriter::vertex_cells");
    conn_.resize(static_cast<std::size_t>(points_.cols()));
    for (std::size_t a = 0; a < conn_.size(); ++a) conn_[a] = static_cast<int>(a);
    cell_size_ = 1;
    cell_type_ = 1;
    return *this;
  }

  VtuWriter& point_scalar(const std::string& name, const Eigen::Ref<const Eigen::VectorXd>& v) {
    return add(point_data_, name, v.data(), v.size(), 1, "point_scalar");
  }
  VtuWriter& point_scalar(const std::string& name, const std::vector<int>& v) {
    return add_int(point_data_, name, v, "point_scalar");
  }
  /// 2 or 3 components per point (2 are written as 3 with z = 0).
  VtuWriter& point_vector(const std::string& name, const Eigen::Ref<const Eigen::MatrixXd>& v) {
    return add_vector(point_data_, name, v, "point_vector");
  }
  VtuWriter& cell_scalar(const std::string& name, const Eigen::Ref<const Eigen::VectorXd>& v) {
    return add(cell_data_, name, v.data(), v.size(), 1, "cell_scalar");
  }
  VtuWriter& cell_scalar(const std::string& name, const std::vector<int>& v) {
    return add_int(cell_data_, name, v, "cell_scalar");
  }
  VtuWriter& cell_vector(const std::string& name, const Eigen::Ref<const Eigen::MatrixXd>& v) {
    return add_vector(cell_data_, name, v, "cell_vector");
  }

  Eigen::Index number_of_points() const { return has_points_ ? points_.cols() : 0; }
  Eigen::Index number_of_cells() const {
    return cell_size_ ? static_cast<Eigen::Index>(conn_.size()) / cell_size_ : 0;
  }

  /// The whole file as a string (checks sizes and indices first).
  std::string str() const {
    check();
    const Eigen::Index np = number_of_points(), nc = number_of_cells();
    std::string s;
    s.reserve(static_cast<std::size_t>(64 * np + 32 * nc + 1024));
    s += "<?xml version=\"1.0\"?>\n";
    s += "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\">\n";
    s += "<UnstructuredGrid>\n<Piece NumberOfPoints=\"";
    detail::append_number(s, static_cast<long long>(np));
    s += "\" NumberOfCells=\"";
    detail::append_number(s, static_cast<long long>(nc));
    s += "\">\n<PointData>\n";
    for (const auto& a : point_data_) write_array(s, a);
    s += "</PointData>\n<CellData>\n";
    for (const auto& a : cell_data_) write_array(s, a);
    s += "</CellData>\n<Points>\n";
    write_values(s, "", 3, points_.data(), static_cast<std::size_t>(3 * np));
    s += "</Points>\n<Cells>\n<DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
    for (std::size_t k = 0; k < conn_.size(); ++k) {
      detail::append_number(s, static_cast<long long>(conn_[k]));
      s += (k + 1) % 12 ? ' ' : '\n';
    }
    s += "\n</DataArray>\n<DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
    for (Eigen::Index c = 0; c < nc; ++c) {
      detail::append_number(s, static_cast<long long>((c + 1) * cell_size_));
      s += (c + 1) % 12 ? ' ' : '\n';
    }
    s += "\n</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">\n";
    for (Eigen::Index c = 0; c < nc; ++c) {
      detail::append_number(s, static_cast<long long>(cell_type_));
      s += (c + 1) % 24 ? ' ' : '\n';
    }
    s += "\n</DataArray>\n</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
    return s;
  }

  /// Writes str() to `path` atomically (parent directories are created).
  void write(const std::filesystem::path& path) const { write_file_atomic(path, str()); }

 private:
  struct Array {
    std::string name;
    int components = 1;
    std::vector<double> real;
    std::vector<int> integer;
    bool is_int = false;
    std::size_t size() const { return is_int ? integer.size() : real.size(); }
  };

  static void check_name(const std::vector<Array>& arrays, const std::string& name,
                         const char* where) {
    if (name.empty()) throw Error("array name is empty", detail::cat("VtuWriter::", where));
    if (name.find_first_of("<>&\"'") != std::string::npos)
      throw Error(detail::cat("array name '", name, "' has an XML special character"),
                  detail::cat("VtuWriter::", where, ", ", name));
    for (const auto& a : arrays)
      if (a.name == name)
        throw Error(detail::cat("array '", name, "' given twice"),
                    detail::cat("VtuWriter::", where, ", ", name));
  }

  VtuWriter& add(std::vector<Array>& arrays, const std::string& name, const double* data,
                 Eigen::Index n, int components, const char* where) {
    check_name(arrays, name, where);
    arrays.push_back(
        {name, components, std::vector<double>(data, data + n * components), {}, false});
    return *this;
  }

  VtuWriter& add_int(std::vector<Array>& arrays, const std::string& name, const std::vector<int>& v,
                     const char* where) {
    check_name(arrays, name, where);
    arrays.push_back({name, 1, {}, v, true});
    return *this;
  }

  VtuWriter& add_vector(std::vector<Array>& arrays, const std::string& name,
                        const Eigen::Ref<const Eigen::MatrixXd>& v, const char* where) {
    if (v.rows() != 2 && v.rows() != 3)
      throw Error(detail::cat("vector array '", name, "' needs 2 or 3 rows, got ", v.rows()),
                  detail::cat("VtuWriter::", where, ", ", name));
    Eigen::Matrix3Xd v3 = Eigen::Matrix3Xd::Zero(3, v.cols());
    v3.topRows(v.rows()) = v;
    return add(arrays, name, v3.data(), v3.cols(), 3, where);
  }

  void check() const {
    if (!has_points_) throw Error("no points set", "VtuWriter::write");
    const Eigen::Index np = points_.cols(), nc = number_of_cells();
    for (std::size_t k = 0; k < conn_.size(); ++k)
      if (conn_[k] < 0 || conn_[k] >= np)
        throw Error(
            detail::cat("cell ", static_cast<Eigen::Index>(k) / cell_size_, " refers to point ",
                        conn_[k], ", outside [0, ", np, ")"),
            detail::cat("VtuWriter::write, cell ", static_cast<Eigen::Index>(k) / cell_size_));
    const auto check_sizes = [](const std::vector<Array>& arrays, Eigen::Index n,
                                const char* what) {
      for (const auto& a : arrays)
        if (static_cast<Eigen::Index>(a.size()) != n * a.components)
          throw Error(detail::cat(what, " array '", a.name, "' has ",
                                  static_cast<Eigen::Index>(a.size()) / a.components,
                                  " entries for ", n, " ", what, "s"),
                      detail::cat("VtuWriter::write, ", a.name));
    };
    check_sizes(point_data_, np, "point");
    check_sizes(cell_data_, nc, "cell");
  }

  static void write_header(std::string& s, const std::string& name, int components,
                           const char* type) {
    s += "<DataArray type=\"";
    s += type;
    s += '"';
    if (!name.empty()) {
      s += " Name=\"";
      s += name;
      s += '"';
    }
    s += " NumberOfComponents=\"";
    detail::append_number(s, static_cast<long long>(components));
    s += "\" format=\"ascii\">\n";
  }

  template <class T>
  static void write_values(std::string& s, const std::string& name, int components, const T* v,
                           std::size_t n) {
    write_header(s, name, components, std::is_same_v<T, int> ? "Int32" : "Float64");
    const std::size_t per_line = components == 3 ? 6 : 8;
    for (std::size_t k = 0; k < n; ++k) {
      if constexpr (std::is_same_v<T, int>)
        detail::append_number(s, static_cast<long long>(v[k]));
      else
        detail::append_number(s, v[k]);
      s += (k + 1) % per_line ? ' ' : '\n';
    }
    s += "\n</DataArray>\n";
  }

  static void write_array(std::string& s, const Array& a) {
    if (a.is_int)
      write_values(s, a.name, a.components, a.integer.data(), a.integer.size());
    else
      write_values(s, a.name, a.components, a.real.data(), a.real.size());
  }

  Eigen::Matrix3Xd points_;
  bool has_points_ = false;
  std::vector<int> conn_;
  int cell_size_ = 0;
  int cell_type_ = 0;
  std::vector<Array> point_data_, cell_data_;
};

/// A ParaView collection (.pvd) of time steps; file names are stored as given,
/// relative to the .pvd's directory (ParaView's convention).
///   PvdCollection c("out/run.pvd"); c.add(0.0, "step_0000.vtu"); c.write();
class PvdCollection {
 public:
  explicit PvdCollection(std::filesystem::path path) : path_(std::move(path)) {}

  PvdCollection& add(double time, const std::string& file) {
    if (!std::isfinite(time))
      throw Error(detail::cat("time ", time, " is not finite"),
                  detail::cat("PvdCollection::add, ", file));
    if (file.empty()) throw Error("empty file name", "PvdCollection::add");
    steps_.push_back({time, file});
    return *this;
  }

  std::size_t size() const { return steps_.size(); }
  const std::filesystem::path& path() const { return path_; }

  std::string str() const {
    std::string s = "<?xml version=\"1.0\"?>\n";
    s +=
        "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n<Collection>\n";
    for (const auto& st : steps_) {
      s += "<DataSet timestep=\"";
      detail::append_number(s, st.time);
      s += "\" group=\"\" part=\"0\" file=\"";
      s += detail::xml_escape(st.file);
      s += "\"/>\n";
    }
    s += "</Collection>\n</VTKFile>\n";
    return s;
  }

  /// Writes the collection atomically (rewrite after each add for a live series).
  void write() const { write_file_atomic(path_, str()); }

  /// The entries so far, for a checkpoint.
  void save(CheckpointOut& out) const {
    out.put(static_cast<std::int64_t>(steps_.size()));
    for (const auto& s : steps_) out.put(s.time).put(s.file);
  }
  void load(CheckpointIn& in) {
    steps_.clear();
    for (auto n = in.get_count(); n > 0; --n) {
      const double t = in.get_double();
      steps_.push_back({t, in.get_string()});
    }
  }

 private:
  struct Step {
    double time;
    std::string file;
  };
  std::filesystem::path path_;
  std::vector<Step> steps_;
};

}  // namespace maxentflow
