// maxentflow: whole-file writes that are atomic: a reader (ParaView polling a
// time series, a restart) sees the old file or the new one, never a torn one.
#pragma once

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>

#include <fcntl.h>
#include <unistd.h>

#include <maxentflow/core/error.hpp>

namespace maxentflow {

namespace detail {

inline std::string errno_text(int err) {
  return std::error_code(err, std::generic_category()).message();
}

/// Writes all of `data` to `fd`, retrying partial writes and EINTR.
inline bool write_all(int fd, std::string_view data) {
  while (!data.empty()) {
    const ::ssize_t k = ::write(fd, data.data(), data.size());
    if (k < 0) {
      if (errno == EINTR) continue;
      return false;
    }
    data.remove_prefix(static_cast<std::size_t>(k));
  }
  return true;
}

}  // namespace detail

/// Writes `contents` to `path` atomically: into `<path>.tmp.<pid>` in the same
/// directory, fsync, then rename over `path` (atomic within a file system on
/// POSIX). Creates missing parent directories. Throws Error on any failure and
/// leaves no temporary file behind.
inline void write_file_atomic(const std::filesystem::path& path, std::string_view contents) {
  namespace fs = std::filesystem;
  const std::string where = detail::cat("write_file_atomic, ", path.string());
  if (path.empty() || !path.has_filename())
    throw Error(detail::cat("no file name in path '", path.string(), "'"), where);
  std::error_code ec;
  const fs::path parent = path.parent_path();
  if (!parent.empty()) {
    fs::create_directories(parent, ec);
    if (ec)
      throw Error(detail::cat("cannot create directory '", parent.string(), "': ", ec.message()),
                  where);
  }
  fs::path tmp = path;
  tmp += detail::cat(".tmp.", ::getpid());

  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0)
    throw Error(detail::cat("cannot create '", tmp.string(), "': ", detail::errno_text(errno)),
                where);
  const bool written = detail::write_all(fd, contents);
  int err = written ? 0 : errno;
  // fsync before rename: after a crash the new name never points to lost data.
  if (written && ::fsync(fd) != 0) err = errno;
  if (::close(fd) != 0 && err == 0) err = errno;
  if (err != 0) {
    fs::remove(tmp, ec);
    throw Error(detail::cat("cannot write '", tmp.string(), "': ", detail::errno_text(err)), where);
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(tmp, ignored);
    throw Error(
        detail::cat("cannot rename '", tmp.string(), "' to '", path.string(), "': ", ec.message()),
        where);
  }
}

/// A file assembled in memory and written atomically by commit(); destroyed
/// uncommitted, it leaves the target untouched.
class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path path) : path_(std::move(path)) {}

  /// The contents so far (append to it directly).
  std::string& buffer() { return buffer_; }
  AtomicFile& operator<<(std::string_view s) {
    buffer_ += s;
    return *this;
  }
  const std::filesystem::path& path() const { return path_; }

  /// Writes the buffer to path() atomically (write_file_atomic); once only.
  void commit() {
    if (committed_)
      throw Error("file already committed", detail::cat("AtomicFile::commit, ", path_.string()));
    write_file_atomic(path_, buffer_);
    committed_ = true;
  }
  bool committed() const { return committed_; }

 private:
  std::filesystem::path path_;
  std::string buffer_;
  bool committed_ = false;
};

}  // namespace maxentflow
