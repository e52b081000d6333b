#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (ASan + UBSan) and runs each for
# SECONDS (default 60) from its corpus in tests/fuzz/corpus/<target>/. A crash,
# a sanitizer report, an exception other than maxentflow::Error, or a violated
# property stops the run with the input that caused it (fuzz-<target>-crash-*).
# Usage: scripts/fuzz.sh [SECONDS]
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
bash scripts/install-deps.sh fuzz
build=build/fuzz
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ \
  -DMAXENTFLOW_BUILD_FUZZERS=ON -DMAXENTFLOW_BUILD_TESTS=OFF -DMAXENTFLOW_BUILD_EXAMPLES=OFF \
  -DMAXENTFLOW_BUILD_BENCHMARKS=OFF -DMAXENTFLOW_USE_OPENMP=OFF -DMAXENTFLOW_NATIVE=OFF >/dev/null
cmake --build "$build" -j"$(nproc)"
for t in csv rigid_tool basis; do
  work=$(mktemp -d)  # new inputs found in this run; the committed corpus stays as it is
  echo "== fuzz_$t for $seconds s"
  status=0
  "$build/tests/fuzz/fuzz_$t" -max_total_time="$seconds" -timeout=20 -rss_limit_mb=2048 \
    -artifact_prefix="$build/fuzz-$t-" -print_final_stats=1 "$work" "tests/fuzz/corpus/$t" \
    >"$build/fuzz-$t.log" 2>&1 || status=$?
  grep -E "stat::number_of_executed_units|stat::peak_rss_mb|Done [0-9]+ runs" "$build/fuzz-$t.log" || true
  if [ "$status" -ne 0 ]; then
    tail -n 40 "$build/fuzz-$t.log"
    echo "fuzz_$t found a failing input (status $status): $build/fuzz-$t-*"
    exit 1
  fi
  rm -rf "$work"
done
