// Shared by the libFuzzer targets: what counts as a finding.
#pragma once

#include <cstdio>
#include <cstdlib>

#include <maxentflow/core/error.hpp>

namespace maxentflow::fuzz {

/// Runs f; a maxentflow::Error is the expected answer to bad input, anything
/// else that escapes (another exception type) is a finding, as is a crash or
/// a sanitizer report inside f.
template <class F>
void expect_error_or_success(F&& f) {
  try {
    f();
  } catch (const Error&) {
  }
}

/// A property a successful call must have; a violation aborts (a finding).
inline void require(bool ok, const char* what) {
  if (ok) return;
  std::fprintf(stderr, "fuzz property violated: %s\n", what);
  std::abort();
}

}  // namespace maxentflow::fuzz
