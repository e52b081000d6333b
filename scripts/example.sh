#!/usr/bin/env bash
# One command for a fresh Debian machine: install what is missing, configure,
# build (release), and run the main example, E1 upsetting (100 steps,
# axisymmetric); its results land in results/upsetting/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake --preset release
cmake --build --preset release -j"$(nproc)" --target upsetting
./build/release/examples/upsetting/upsetting --out-dir results/upsetting "$@"
