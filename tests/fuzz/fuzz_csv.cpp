// libFuzzer target: read_csv on arbitrary bytes. Either an Error or a table
// whose rows all have the header's width and finite numbers.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include <maxentflow/io/csv.hpp>

#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace maxentflow;
  fuzz::expect_error_or_success([&] {
    std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
    const CsvData d = read_csv(in, "fuzz");
    for (const auto& row : d.rows) {
      fuzz::require(row.size() == d.header.size(), "a row as wide as the header");
      for (double v : row) fuzz::require(std::isfinite(v), "finite cells");
    }
  });
  return 0;
}
