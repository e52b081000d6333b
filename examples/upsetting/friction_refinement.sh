#!/usr/bin/env bash
# Refinement study of E1 with friction: the first step's plate force over the
# frictionless exact one, and the barrelling, on 21 x 25, 41 x 49 and 81 x 97
# nodes (the last takes minutes and about 1.4 GB). Rows go to
# results/upsetting_friction/refinement.csv.
#   examples/upsetting/friction_refinement.sh                # sticking
#   examples/upsetting/friction_refinement.sh --friction-m 0.5
set -euo pipefail
bin=${UPSETTING:-build/release/examples/upsetting/upsetting}
law=("$@")
[ ${#law[@]} -eq 0 ] && law=(--sticking)
out=results/upsetting_friction
mkdir -p "$out"
rm -f "$out/refinement.csv"
for level in "21 25" "41 49" "81 97"; do
  set -- $level
  "$bin" --no-plots --steps 1 --nx "$1" --ny "$2" "${law[@]}" --out-dir "$out/${1}x${2}" | tail -n 3
  if [ ! -f "$out/refinement.csv" ]; then cp "$out/${1}x${2}/summary.csv" "$out/refinement.csv";
  else tail -n +2 "$out/${1}x${2}/summary.csv" >> "$out/refinement.csv"; fi
done
cat "$out/refinement.csv"
