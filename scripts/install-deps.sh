#!/usr/bin/env bash
# Installs the Debian packages maxentflow needs, skipping those already present.
set -euo pipefail
packages=(cmake g++ make libeigen3-dev libcgal-dev libsuitesparse-dev catch2 libcli11-dev
          python3-matplotlib libopenblas0-pthread libmumps-seq-dev)
# `install-deps.sh fuzz`: also clang and its libFuzzer runtime (scripts/fuzz.sh).
[ "${1:-}" = fuzz ] && packages+=(clang libclang-rt-14-dev)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "installing: ${missing[*]}"
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
