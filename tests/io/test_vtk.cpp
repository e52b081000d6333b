// Atomic file writes and the VTU / PVD writers.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <unistd.h>

#include <maxentflow/io/atomic_file.hpp>
#include <maxentflow/io/checkpoint.hpp>
#include <maxentflow/io/csv.hpp>
#include <maxentflow/io/vtk.hpp>

namespace fs = std::filesystem;
using maxentflow::Error;

namespace {

// A fresh directory per test case, removed afterwards.
struct TempDir {
  fs::path path;
  explicit TempDir(const std::string& name)
      : path(fs::temp_directory_path() /
             ("maxentflow_io_" + name + "_" + std::to_string(::getpid()))) {
    fs::remove_all(path);
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  // Files whose name contains ".tmp" anywhere below the directory.
  int stray_tmp() const {
    int n = 0;
    if (!fs::exists(path)) return 0;
    for (const auto& f : fs::recursive_directory_iterator(path))
      n += f.path().filename().string().find(".tmp") != std::string::npos;
    return n;
  }
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string attribute(const std::string& xml, const std::string& name, std::size_t from = 0) {
  const auto k = xml.find(" " + name + "=\"", from);
  if (k == std::string::npos) return "";
  const auto b = k + name.size() + 3;
  return xml.substr(b, xml.find('"', b) - b);
}

// The values of the DataArray named `name` (the Points array has no name: "").
std::vector<double> values(const std::string& xml, const std::string& name) {
  std::size_t k = 0;
  if (name.empty()) {
    k = xml.find("<Points>");
    k = xml.find("<DataArray", k);
  } else {
    k = xml.find("Name=\"" + name + "\"");
  }
  if (k == std::string::npos) return {};
  const auto b = xml.find('>', k) + 1, e = xml.find("</DataArray>", b);
  std::istringstream s(xml.substr(b, e - b));
  std::vector<double> v;
  std::string tok;
  while (s >> tok) v.push_back(std::strtod(tok.c_str(), nullptr));
  return v;
}

}  // namespace

TEST_CASE("write_file_atomic writes, replaces, creates directories, leaves no temp", "[io]") {
  TempDir dir("atomic");
  const fs::path p = dir.path / "a" / "b" / "file.txt";
  maxentflow::write_file_atomic(p, "first\n");
  CHECK(slurp(p) == "first\n");
  maxentflow::write_file_atomic(p, std::string(100000, 'x'));  // replaces
  CHECK(slurp(p) == std::string(100000, 'x'));
  CHECK(dir.stray_tmp() == 0);

  maxentflow::AtomicFile f(dir.path / "streamed.txt");
  f << "one "
    << "two";
  f.buffer() += " three";
  CHECK(!fs::exists(f.path()));  // nothing before commit
  f.commit();
  CHECK(f.committed());
  CHECK(slurp(f.path()) == "one two three");
  CHECK_THROWS_AS(f.commit(), Error);
  {
    maxentflow::AtomicFile dropped(dir.path / "never.txt");
    dropped << "lost";
  }
  CHECK(!fs::exists(dir.path / "never.txt"));
  CHECK(dir.stray_tmp() == 0);
}

TEST_CASE("write_file_atomic failures throw Error and clean up", "[io]") {
  TempDir dir("atomic_fail");
  fs::create_directories(dir.path / "is_a_dir");
  // The target is a directory: rename fails, the temporary is removed.
  try {
    maxentflow::write_file_atomic(dir.path / "is_a_dir", "x");
    FAIL("no throw");
  } catch (const Error& e) {
    CHECK(e.description().find("cannot rename") != std::string::npos);
    CHECK(e.where().find("is_a_dir") != std::string::npos);
  }
  CHECK(dir.stray_tmp() == 0);
  // A parent that is a regular file cannot become a directory.
  maxentflow::write_file_atomic(dir.path / "plain", "x");
  CHECK_THROWS_WITH(maxentflow::write_file_atomic(dir.path / "plain" / "child.txt", "y"),
                    Catch::Contains("cannot create directory"));
  CHECK_THROWS_WITH(maxentflow::write_file_atomic(dir.path / "", "y"),
                    Catch::Contains("no file name"));
}

TEST_CASE("VtuWriter writes a grid ParaView reads, doubles round-trip exactly", "[io]") {
  TempDir dir("vtu");
  Eigen::Matrix2Xd x(2, 4);
  x << 0.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0 / 3.0;
  Eigen::VectorXd h(4);
  h << 0.1, 1e-300, -2.5e17, 0.30000000000000004;
  Eigen::Matrix2Xd v(2, 4);
  v << 1, 2, 3, 4, 5, 6, 7, 8;
  Eigen::VectorXd area(2);
  area << 0.5, 1.0 / 3.0;
  maxentflow::VtuWriter w;
  w.points(x)
      .triangles({{0, 1, 2}, {0, 2, 3}})
      .point_scalar("h", h)
      .point_scalar("flag", std::vector<int>{1, 0, 1, 0})
      .point_vector("velocity", v)
      .cell_scalar("area", area);
  CHECK(w.number_of_points() == 4);
  CHECK(w.number_of_cells() == 2);
  const fs::path p = dir.path / "out" / "grid.vtu";
  w.write(p);
  const std::string xml = slurp(p);
  CHECK(xml.rfind("<?xml", 0) == 0);
  CHECK(attribute(xml, "type") == "UnstructuredGrid");
  CHECK(attribute(xml, "NumberOfPoints") == "4");
  CHECK(attribute(xml, "NumberOfCells") == "2");
  const auto pts = values(xml, "");
  REQUIRE(pts.size() == 12u);
  CHECK(pts[10] == 1.0 / 3.0);  // bit-exact
  CHECK(pts[11] == 0.0);
  CHECK(pts[2] == 0.0);  // z = 0
  const auto hv = values(xml, "h");
  REQUIRE(hv.size() == 4u);
  for (int a = 0; a < 4; ++a) CHECK(hv[static_cast<std::size_t>(a)] == h[a]);
  CHECK(values(xml, "flag") == std::vector<double>{1, 0, 1, 0});
  CHECK(values(xml, "velocity") == std::vector<double>{1, 5, 0, 2, 6, 0, 3, 7, 0, 4, 8, 0});
  CHECK(values(xml, "area") == std::vector<double>{0.5, 1.0 / 3.0});
  CHECK(values(xml, "connectivity") == std::vector<double>{0, 1, 2, 0, 2, 3});
  CHECK(values(xml, "offsets") == std::vector<double>{3, 6});
  CHECK(values(xml, "types") == std::vector<double>{5, 5});
  CHECK(xml.find("Name=\"flag\" NumberOfComponents=\"1\"") != std::string::npos);
  CHECK(xml.find("type=\"Int32\" Name=\"flag\"") != std::string::npos);
  CHECK(dir.stray_tmp() == 0);
}

TEST_CASE("VtuWriter point clouds and 3-D points", "[io]") {
  Eigen::Matrix3Xd x = Eigen::Matrix3Xd::Random(3, 5);
  maxentflow::VtuWriter w;
  w.points(x).vertex_cells();
  const std::string xml = w.str();
  CHECK(attribute(xml, "NumberOfCells") == "5");
  CHECK(values(xml, "types") == std::vector<double>(5, 1.0));
  CHECK(values(xml, "").size() == 15u);
  CHECK(values(xml, "")[14] == x(2, 4));
}

TEST_CASE("VtuWriter checks names, sizes and indices", "[io]") {
  Eigen::Matrix2Xd x = Eigen::Matrix2Xd::Zero(2, 3);
  x(0, 1) = 1.0;
  x(1, 2) = 1.0;
  maxentflow::VtuWriter w;
  w.points(x).triangles({{0, 1, 2}});
  w.point_scalar("short", Eigen::VectorXd::Zero(2));
  CHECK_THROWS_WITH(w.str(), Catch::Contains("point array 'short' has 2 entries for 3 points"));

  maxentflow::VtuWriter c;
  c.points(x).triangles({{0, 1, 2}}).cell_scalar("a", Eigen::VectorXd::Zero(3));
  CHECK_THROWS_WITH(c.str(), Catch::Contains("cell array 'a' has 3 entries for 1 cells"));

  maxentflow::VtuWriter d;
  d.points(x).point_scalar("h", Eigen::VectorXd::Zero(3));
  CHECK_THROWS_WITH(d.point_scalar("h", Eigen::VectorXd::Zero(3)),
                    Catch::Contains("'h' given twice"));
  CHECK_THROWS_AS(d.point_scalar("", Eigen::VectorXd::Zero(3)), Error);
  CHECK_THROWS_AS(d.point_scalar("a<b", Eigen::VectorXd::Zero(3)), Error);
  CHECK_THROWS_AS(d.point_vector("v", Eigen::MatrixXd::Zero(4, 3)), Error);
  CHECK_THROWS_AS(d.points(Eigen::MatrixXd::Zero(1, 3)), Error);

  maxentflow::VtuWriter e;
  e.points(x).triangles({{0, 1, 3}});
  CHECK_THROWS_WITH(e.str(), Catch::Contains("cell 0 refers to point 3"));
  CHECK_THROWS_WITH(maxentflow::VtuWriter().str(), Catch::Contains("no points"));
}

TEST_CASE("PvdCollection lists the steps of a time series", "[io]") {
  TempDir dir("pvd");
  maxentflow::PvdCollection c(dir.path / "run.pvd");
  for (int k = 0; k < 3; ++k) c.add(0.1 * k, "step_000" + std::to_string(k) + ".vtu");
  c.add(0.3, "odd & \"name\".vtu");
  c.write();
  const std::string xml = slurp(dir.path / "run.pvd");
  CHECK(attribute(xml, "type") == "Collection");
  std::size_t count = 0, k = 0;
  while ((k = xml.find("<DataSet", k)) != std::string::npos) {
    ++count;
    ++k;
  }
  CHECK(count == 4u);
  const auto second = xml.find("<DataSet", xml.find("<DataSet") + 1);
  CHECK(std::strtod(attribute(xml, "timestep", second).c_str(), nullptr) == 0.1);
  CHECK(attribute(xml, "file", second) == "step_0001.vtu");
  CHECK(xml.find("file=\"odd &amp; &quot;name&quot;.vtu\"") != std::string::npos);
  CHECK(c.size() == 4u);
  CHECK_THROWS_AS(c.add(std::numeric_limits<double>::infinity(), "x.vtu"), Error);
  CHECK_THROWS_AS(c.add(1.0, ""), Error);
  CHECK(dir.stray_tmp() == 0);
}

TEST_CASE("read_csv: numbers under a header; ragged, non-numeric and non-finite input refused", "[io]") {
  auto read = [](const std::string& text) {
    std::istringstream in(text);
    return maxentflow::read_csv(in, "test");
  };
  const auto d = read("x, y\n1, 2.5\n\n-3e2,4\n");
  REQUIRE(d.header == std::vector<std::string>{"x", "y"});
  REQUIRE(d.rows.size() == 2);
  CHECK(d.rows[1][0] == -300.0);
  CHECK(d.values("y") == std::vector<double>{2.5, 4.0});
  CHECK_THROWS_AS(d.values("z"), Error);
  CHECK_THROWS_AS(read(""), Error);
  CHECK_THROWS_AS(read("x,y\n1\n"), Error);
  CHECK_THROWS_AS(read("x,y\n1,2,3\n"), Error);
  CHECK_THROWS_AS(read("x,y\n1,abc\n"), Error);
  CHECK_THROWS_AS(read("x,y\n1,\n"), Error);
  for (const char* bad : {"nan", "inf", "-inf", "1e400"})
    CHECK_THROWS_WITH(read(std::string("x\n") + bad + "\n"), Catch::Contains("not finite"));
}

TEST_CASE("checkpoint archive: values come back in order; another format, damage, truncation refused", "[io][checkpoint]") {
  using namespace maxentflow;
  Eigen::MatrixXd m(2, 3);
  m << 1, 2, 3, 4, 5, std::nextafter(6.0, 7.0);
  CheckpointOut out;
  out.put(0.1).put(-7).put(true).put("a name, with spaces").put(m).put(std::vector<int>{3, -1, 0});
  out.put(std::map<std::string, double>{{"worst", 1e-300}}).put(std::map<std::string, std::string>{{"a", ""}});
  const std::string bytes = out.bytes();
  {
    CheckpointIn in(bytes, "memory");
    CHECK(in.get_double() == 0.1);
    CHECK(in.get_int() == -7);
    CHECK(in.get_bool());
    CHECK(in.get_string() == "a name, with spaces");
    CHECK(in.get_matrix() == m);  // bitwise
    CHECK(in.get_ints() == std::vector<int>{3, -1, 0});
    CHECK(in.get_numbers().at("worst") == 1e-300);
    CHECK(in.get_texts().at("a").empty());
    in.expect_end();
  }
  SECTION("a reader expecting other values") {
    CheckpointIn in(bytes, "memory");
    CHECK_THROWS_WITH(in.get_int(), Catch::Contains("expected an integer") && Catch::Contains("memory"));
    CheckpointIn partly(bytes, "memory");
    partly.get_double();
    CHECK_THROWS_WITH(partly.expect_end(), Catch::Contains("bytes left unread"));
  }
  SECTION("damage, truncation, another format, not a checkpoint") {
    std::string damaged = bytes;
    damaged[CheckpointFormat::header + 5] ^= 0x20;
    CHECK_THROWS_WITH(CheckpointIn(damaged, "x"), Catch::Contains("checksum mismatch"));
    CHECK_THROWS_WITH(CheckpointIn(bytes.substr(0, bytes.size() - 1), "x"), Catch::Contains("truncated"));
    std::string other = bytes;
    other[16] = 99;  // the format version
    CHECK_THROWS_WITH(CheckpointIn(other, "x"), Catch::Contains("format version 99"));
    CHECK_THROWS_WITH(CheckpointIn("step,time\n1,0\n", "x"), Catch::Contains("not a maxentflow checkpoint"));
    CHECK_THROWS_WITH(CheckpointIn(std::filesystem::path("/nonexistent/checkpoint.mxf")), Catch::Contains("cannot open"));
  }
  SECTION("a CSV table and a PVD series go on where they were") {
    CsvTable t({"step", "f"}), u({"step", "f"}), v({"other"});
    t.row({1, 2.5});
    PvdCollection p("a.pvd"), q("a.pvd");
    p.add(0.5, "s_0001.vtu");
    CheckpointOut o;
    t.save(o);
    p.save(o);
    t.save(o);
    CheckpointIn in(o.bytes(), "memory");
    u.load(in);
    q.load(in);
    CHECK_THROWS_WITH(v.load(in), Catch::Contains("another header"));
    u.row({2, 3.0});
    t.row({2, 3.0});
    CHECK(u.str() == t.str());
    CHECK(u.rows() == 2);
    CHECK(q.str() == p.str());
  }
}
