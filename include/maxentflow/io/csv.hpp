// maxentflow: CSV tables for curves (forces, profiles, basis values), written
// whole (temporary file + rename).
#pragma once

#include <maxentflow/core/error.hpp>
#include <maxentflow/io/atomic_file.hpp>
#include <maxentflow/io/checkpoint.hpp>

#include <charconv>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

namespace maxentflow {

/// A CSV table with a fixed header; cells are numbers (shortest text that reads
/// back to the same double) or plain strings. Rows must have one cell per column.
class CsvTable {
 public:
  explicit CsvTable(std::vector<std::string> header) : columns_(header.size()) {
    require(!header.empty(), "a CSV table needs at least one column", "CsvTable");
    for (std::size_t i = 0; i < header.size(); ++i) {
      if (i) text_ += ',';
      text_ += header[i];
    }
    text_ += '\n';
  }

  /// Starts a row; cells follow with cell(), the row ends with end_row().
  CsvTable& cell(double v) {
    separator();
    if (!std::isfinite(v)) {
      text_ += std::isnan(v) ? "nan" : (v > 0 ? "inf" : "-inf");
      return *this;
    }
    char buf[32];
    const auto res = std::to_chars(buf, buf + sizeof buf, v);
    text_.append(buf, res.ptr);
    return *this;
  }
  CsvTable& cell(int v) { return cell(static_cast<long long>(v)); }
  CsvTable& cell(long v) { return cell(static_cast<long long>(v)); }
  CsvTable& cell(long long v) {
    separator();
    text_ += std::to_string(v);
    return *this;
  }
  CsvTable& cell(std::string_view s) {
    separator();
    text_ += s;
    return *this;
  }
  CsvTable& cell(const char* s) { return cell(std::string_view(s)); }

  void end_row() {
    MAXENTFLOW_REQUIRE(in_row_ == columns_,
                       detail::cat("CSV row has ", in_row_, " cells, the header has ", columns_), "CsvTable");
    text_ += '\n';
    in_row_ = 0;
    ++rows_;
  }

  /// A whole numeric row.
  void row(std::initializer_list<double> values) {
    for (double v : values) cell(v);
    end_row();
  }
  void row(const std::vector<double>& values) {
    for (double v : values) cell(v);
    end_row();
  }

  std::size_t rows() const { return rows_; }
  const std::string& str() const { return text_; }
  /// The rows so far, for a checkpoint; load() refuses a table of another header.
  void save(CheckpointOut& out) const {
    MAXENTFLOW_REQUIRE(in_row_ == 0, "a CSV table is saved between rows", "CsvTable::save");
    out.put(text_).put(static_cast<std::int64_t>(rows_));
  }
  void load(CheckpointIn& in) {
    std::string text = in.get_string();
    const auto rows = static_cast<std::size_t>(in.get_count());
    const std::string header = text_.substr(0, text_.find('\n') + 1);
    if (text.compare(0, header.size(), header) != 0)
      in.fail(detail::cat("a CSV table with another header than ", header.substr(0, header.size() - 1)));
    text_ = std::move(text);
    rows_ = rows;
    in_row_ = 0;
  }
  void write(const std::filesystem::path& path) const {
    require(in_row_ == 0, "CSV table written with an unfinished row", "CsvTable::write");
    write_file_atomic(path, text_);
  }

 private:
  void separator() {
    MAXENTFLOW_REQUIRE(in_row_ < columns_, detail::cat("CSV row has more than ", columns_, " cells"), "CsvTable");
    if (in_row_++) text_ += ',';
  }

  std::size_t columns_;
  std::size_t in_row_ = 0;
  std::size_t rows_ = 0;
  std::string text_;
};

/// A numeric CSV file read whole: a header line of column names, then rows of
/// finite numbers. Bad input (missing file, ragged row, non-number, NaN/inf) gives an Error that
/// names the file and line.
struct CsvData {
  std::vector<std::string> header;
  std::vector<std::vector<double>> rows;

  /// Index of a column, or -1.
  int column(std::string_view name) const {
    for (std::size_t i = 0; i < header.size(); ++i)
      if (header[i] == name) return static_cast<int>(i);
    return -1;
  }
  /// A required column's values.
  std::vector<double> values(std::string_view name, const std::string& file = {}) const {
    const int c = column(name);
    require(c >= 0, detail::cat("CSV column '", name, "' is missing"), detail::cat("read_csv, ", file));
    std::vector<double> v;
    v.reserve(rows.size());
    for (const auto& r : rows) v.push_back(r[static_cast<std::size_t>(c)]);
    return v;
  }
};

/// The same from a stream; `where` names the source in errors.
inline CsvData read_csv(std::istream& in, const std::string& where) {
  CsvData d;
  std::string line;
  auto split = [](const std::string& l) {
    std::vector<std::string> cells;
    std::string cell;
    std::istringstream s(l);
    while (std::getline(s, cell, ',')) {
      const auto b = cell.find_first_not_of(" \t\r"), e = cell.find_last_not_of(" \t\r");
      cells.push_back(b == std::string::npos ? std::string() : cell.substr(b, e - b + 1));
    }
    return cells;
  };
  require(static_cast<bool>(std::getline(in, line)), "empty CSV file (no header)", where);
  d.header = split(line);
  for (int number = 2; std::getline(in, line); ++number) {
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const auto cells = split(line);
    require(cells.size() == d.header.size(),
            detail::cat("line ", number, " has ", cells.size(), " cells, the header has ", d.header.size()),
            where);
    std::vector<double> row;
    row.reserve(cells.size());
    for (const auto& c : cells) {
      char* end = nullptr;
      const double v = std::strtod(c.c_str(), &end);
      require(!c.empty() && end == c.c_str() + c.size(),
              detail::cat("line ", number, ": '", c, "' is not a number"), where);
      require(std::isfinite(v), detail::cat("line ", number, ": '", c, "' is not finite"), where);
      row.push_back(v);
    }
    d.rows.push_back(std::move(row));
  }
  return d;
}

inline CsvData read_csv(const std::filesystem::path& path) {
  const std::string where = detail::cat("read_csv, ", path.string());
  std::ifstream in(path);
  require(static_cast<bool>(in), "cannot open CSV file", where);
  return read_csv(in, where);
}

}  // namespace maxentflow
