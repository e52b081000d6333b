// maxentflow: the one exception type, and checks that raise it.
#pragma once

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace maxentflow {

/// Every failure the library reports: `what` says what went wrong, `where` says
/// where (component, function, and the offending point/node/step).
class Error : public std::runtime_error {
 public:
  Error(const std::string& what, std::string where)
      : std::runtime_error("maxentflow: " + what + (where.empty() ? "" : " [at " + where + "]")),
        what_(what),
        where_(std::move(where)) {}

  /// The description alone, without the location.
  const std::string& description() const noexcept { return what_; }
  /// The location: component, function and the offending entity.
  const std::string& where() const noexcept { return where_; }

 private:
  std::string what_;
  std::string where_;
};

namespace detail {

/// Concatenates anything streamable into a string (for messages).
template <class... Args>
std::string cat(Args&&... args) {
  std::ostringstream s;
  s.precision(17);
  (s << ... << std::forward<Args>(args));
  return s.str();
}

}  // namespace detail

/// Throws `Error(what, where)` unless `condition` holds. The message arguments are
/// built before the call: in loops over nodes or points use MAXENTFLOW_REQUIRE,
/// which builds them only on failure.
inline void require(bool condition, const std::string& what, const std::string& where) {
  if (!condition) throw Error(what, where);
}

/// MAXENTFLOW_REQUIRE(condition, what, where): like require(), but `what` and
/// `where` (e.g. detail::cat(...) with coordinates) are evaluated only on failure.
#define MAXENTFLOW_REQUIRE(condition, what, where) \
  do {                                             \
    if (!(condition)) throw ::maxentflow::Error((what), (where)); \
  } while (false)

/// True if every coefficient of an Eigen expression is finite.
template <class Derived>
bool all_finite(const Derived& m) {
  return m.allFinite();
}

}  // namespace maxentflow
