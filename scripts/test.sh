#!/usr/bin/env bash
# One command for a fresh Debian machine: install what is missing, configure,
# build (release), and run the tests (labels unit, verification, example).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake --preset release
cmake --build --preset release -j"$(nproc)"
ctest --preset release -j"$(nproc)" "$@"
