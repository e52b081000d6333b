#!/usr/bin/env bash
# One command for a fresh Debian machine: install what is missing, configure,
# build (release), and run the main example; its results land in results/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake --preset release
cmake --build --preset release -j"$(nproc)" --target basis_functions
./build/release/examples/basis_functions/basis_functions --out-dir results/basis_functions "$@"
