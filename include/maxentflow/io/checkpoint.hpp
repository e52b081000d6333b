// maxentflow: the binary archive a checkpoint is written in: typed values in
// order, a format version and a checksum, so that a checkpoint from another
// format or a damaged one is refused instead of read as garbage.
#pragma once

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include <maxentflow/core/error.hpp>
#include <maxentflow/io/atomic_file.hpp>

namespace maxentflow {

/// Layout: magic (16 bytes), format version (u32), payload size (u64), FNV-1a
/// checksum of the payload (u64), payload. Each value in the payload is a tag
/// byte and its bytes (little-endian host order), so a reader that expects a
/// different sequence fails at the first mismatch and says where.
struct CheckpointFormat {
  static constexpr char magic[17] = "maxentflow-ckpt\n";
  static constexpr std::uint32_t version = 3;
  static constexpr std::size_t header = 16 + 4 + 8 + 8;
  static std::uint64_t checksum(const char* p, std::size_t n) {
    std::uint64_t h = 1469598103934665603ull;  // FNV-1a, 64 bit
    for (std::size_t i = 0; i < n; ++i) h = (h ^ static_cast<unsigned char>(p[i])) * 1099511628211ull;
    return h;
  }
};

/// Values written in order; write() puts the file on disk whole (temporary
/// file + rename).
class CheckpointOut {
 public:
  CheckpointOut& put(double v) { return tagged('d', &v, sizeof v); }
  CheckpointOut& put(std::int64_t v) { return tagged('i', &v, sizeof v); }
  CheckpointOut& put(int v) { return put(static_cast<std::int64_t>(v)); }
  CheckpointOut& put(bool v) { return put(static_cast<std::int64_t>(v)); }
  CheckpointOut& put(const std::string& s) {
    const auto n = static_cast<std::int64_t>(s.size());
    tagged('s', &n, sizeof n);
    data_.append(s);
    return *this;
  }
  CheckpointOut& put(const char* s) { return put(std::string(s)); }
  template <class Derived>
  CheckpointOut& put(const Eigen::DenseBase<Derived>& m) {
    const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic> a = m.template cast<double>();
    const std::int64_t rc[2] = {static_cast<std::int64_t>(a.rows()), static_cast<std::int64_t>(a.cols())};
    tagged('m', rc, sizeof rc);
    data_.append(reinterpret_cast<const char*>(a.data()), static_cast<std::size_t>(a.size()) * sizeof(double));
    return *this;
  }
  CheckpointOut& put(const std::vector<int>& v) {
    put(static_cast<std::int64_t>(v.size()));
    for (int x : v) put(x);
    return *this;
  }
  CheckpointOut& put(const std::map<std::string, double>& m) {
    put(static_cast<std::int64_t>(m.size()));
    for (const auto& [k, v] : m) put(k).put(v);
    return *this;
  }
  CheckpointOut& put(const std::map<std::string, std::string>& m) {
    put(static_cast<std::int64_t>(m.size()));
    for (const auto& [k, v] : m) put(k).put(v);
    return *this;
  }

  /// The whole file's bytes (header and payload).
  std::string bytes() const {
    std::string out(CheckpointFormat::magic, 16);
    const std::uint32_t version = CheckpointFormat::version;
    const std::uint64_t size = data_.size(), sum = CheckpointFormat::checksum(data_.data(), data_.size());
    out.append(reinterpret_cast<const char*>(&version), sizeof version);
    out.append(reinterpret_cast<const char*>(&size), sizeof size);
    out.append(reinterpret_cast<const char*>(&sum), sizeof sum);
    return out + data_;
  }
  void write(const std::filesystem::path& path) const { write_file_atomic(path, bytes()); }

 private:
  CheckpointOut& tagged(char tag, const void* p, std::size_t n) {
    data_ += tag;
    data_.append(static_cast<const char*>(p), n);
    return *this;
  }
  std::string data_;
};

/// Reads what CheckpointOut wrote, in the same order. The constructor checks
/// the magic, the format version, the size and the checksum; each get checks
/// its tag and the bounds. Every failure is an Error naming the file.
class CheckpointIn {
 public:
  explicit CheckpointIn(std::filesystem::path path) : path_(std::move(path)) {
    std::ifstream in(path_, std::ios::binary);
    if (!in) fail("cannot open the checkpoint");
    std::ostringstream ss;
    ss << in.rdbuf();
    from_bytes(ss.str());
  }
  /// From bytes in memory (`name` for messages).
  CheckpointIn(std::string bytes, std::filesystem::path name) : path_(std::move(name)) { from_bytes(std::move(bytes)); }

  double get_double() {
    double v;
    tagged('d', &v, sizeof v, "a number");
    return v;
  }
  std::int64_t get_int() {
    std::int64_t v;
    tagged('i', &v, sizeof v, "an integer");
    return v;
  }
  bool get_bool() { return get_int() != 0; }
  std::string get_string() {
    std::int64_t n;
    tagged('s', &n, sizeof n, "a string");
    if (n < 0 || static_cast<std::uint64_t>(n) > data_.size() - pos_) fail("a string runs past the end");
    std::string s = data_.substr(pos_, static_cast<std::size_t>(n));
    pos_ += static_cast<std::size_t>(n);
    return s;
  }
  Eigen::MatrixXd get_matrix() {
    std::int64_t rc[2];
    tagged('m', rc, sizeof rc, "a matrix");
    if (rc[0] < 0 || rc[1] < 0 || (rc[0] > 0 && static_cast<std::uint64_t>(rc[1]) > (data_.size() - pos_) / 8 / static_cast<std::uint64_t>(rc[0])))
      fail(detail::cat("a ", rc[0], " x ", rc[1], " matrix runs past the end"));
    Eigen::MatrixXd m(rc[0], rc[1]);
    const std::size_t bytes = static_cast<std::size_t>(m.size()) * sizeof(double);
    if (bytes) std::memcpy(m.data(), data_.data() + pos_, bytes);
    pos_ += bytes;
    return m;
  }
  std::int64_t get_count(std::int64_t max = std::int64_t{1} << 40) {
    const std::int64_t n = get_int();
    if (n < 0 || n > max) fail(detail::cat("a count of ", n, " is out of range"));
    return n;
  }
  std::vector<int> get_ints() {
    std::vector<int> v(static_cast<std::size_t>(get_count(static_cast<std::int64_t>(data_.size()))));
    for (auto& x : v) x = static_cast<int>(get_int());
    return v;
  }
  std::map<std::string, double> get_numbers() {
    std::map<std::string, double> m;
    for (auto n = get_count(static_cast<std::int64_t>(data_.size())); n > 0; --n) {
      std::string k = get_string();
      m[k] = get_double();
    }
    return m;
  }
  std::map<std::string, std::string> get_texts() {
    std::map<std::string, std::string> m;
    for (auto n = get_count(static_cast<std::int64_t>(data_.size())); n > 0; --n) {
      std::string k = get_string();
      m[k] = get_string();
    }
    return m;
  }
  /// Throws unless every value was read (a reader that expects fewer values
  /// than were written is another format).
  void expect_end() const {
    if (pos_ != data_.size()) fail(detail::cat(data_.size() - pos_, " bytes left unread"));
  }
  [[noreturn]] void fail(const std::string& what) const {
    throw Error(detail::cat("checkpoint '", path_.string(), "': ", what, " (at byte ", pos_, ")"), "CheckpointIn");
  }

 private:
  void from_bytes(std::string bytes) {
    const std::size_t h = CheckpointFormat::header;
    if (bytes.size() < h || std::memcmp(bytes.data(), CheckpointFormat::magic, 16) != 0)
      fail("not a maxentflow checkpoint");
    std::uint32_t version;
    std::uint64_t size, sum;
    std::memcpy(&version, bytes.data() + 16, sizeof version);
    std::memcpy(&size, bytes.data() + 20, sizeof size);
    std::memcpy(&sum, bytes.data() + 28, sizeof sum);
    if (version != CheckpointFormat::version)
      fail(detail::cat("format version ", version, ", this build reads version ", CheckpointFormat::version));
    if (size != bytes.size() - h) fail(detail::cat("truncated or extended: ", bytes.size() - h, " payload bytes, the header says ", size));
    data_ = bytes.substr(h);
    if (CheckpointFormat::checksum(data_.data(), data_.size()) != sum) fail("checksum mismatch (the file is damaged)");
  }
  void tagged(char tag, void* p, std::size_t n, const char* what) {
    if (pos_ + 1 + n > data_.size()) fail(detail::cat("ends where ", what, " was expected"));
    if (data_[pos_] != tag) fail(detail::cat("expected ", what, ", found tag '", data_[pos_], "'"));
    std::memcpy(p, data_.data() + pos_ + 1, n);
    pos_ += 1 + n;
  }
  std::filesystem::path path_;
  std::string data_;
  std::size_t pos_ = 0;
};

}  // namespace maxentflow
