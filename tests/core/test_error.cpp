#include <catch2/catch.hpp>

#include <maxentflow/core/error.hpp>

using maxentflow::Error;

TEST_CASE("Error carries what and where", "[core]") {
  try {
    maxentflow::require(false, "coincident nodes 3 and 7", "IntegrationMesh::build");
    FAIL("require(false) did not throw");
  } catch (const Error& e) {
    CHECK(e.description() == "coincident nodes 3 and 7");
    CHECK(e.where() == "IntegrationMesh::build");
    CHECK(std::string(e.what()) ==
          "maxentflow: coincident nodes 3 and 7 [at IntegrationMesh::build]");
  }
  CHECK_NOTHROW(maxentflow::require(true, "never", "nowhere"));
  CHECK(maxentflow::detail::cat("x=", 0.5, " n=", 3) == "x=0.5 n=3");
}
