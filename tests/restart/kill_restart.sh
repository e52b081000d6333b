#!/usr/bin/env bash
# Restart after a crash (issue 19): runs an example uninterrupted, runs it
# again and kills it with SIGKILL at a random step between checkpoints,
# resumes it with --restart, and requires every result file to equal the
# uninterrupted run's byte for byte. While the killed run is writing, every
# file in its folder under its final name must be whole at every moment (a
# VTU/PVD ends with </VTKFile>, a CSV with a newline). A damaged checkpoint
# and a restart with other options must be refused.
# Usage: kill_restart.sh WORK KILL_MIN KILL_MAX OTHER_OPTION EXE [OPTIONS...]
#   kills after the progress line of a step in [KILL_MIN, KILL_MAX];
#   OTHER_OPTION: "--name value" that changes the case (must be refused).
set -uo pipefail
work=$1 kmin=$2 kmax=$3 other=$4
shift 4
exe=("$@")
fail() { echo "FAIL: $*"; exit 1; }
rm -rf "$work" && mkdir -p "$work" || fail "cannot make $work"

"${exe[@]}" --out-dir "$work/ref" >"$work/ref.log" 2>&1 || fail "uninterrupted run failed: $(tail -3 "$work/ref.log")"

kill_at=$((kmin + RANDOM % (kmax - kmin + 1)))
echo "killing the second run after step $kill_at"
"${exe[@]}" --out-dir "$work/run" >"$work/run.log" 2>&1 &
pid=$!
partial=""
whole() {  # a result file under its final name is complete
  case "$1" in
    *.tmp.*) return 0 ;;
    *.vtu | *.pvd) [ "$(tail -c 11 "$1")" = "</VTKFile>" ] || [ "$(tail -c 12 "$1" | head -c 10)" = "</VTKFile>" ] ;;
    *.csv) [ ! -s "$1" ] && return 1; [ "$(tail -c 1 "$1" | od -An -c | tr -d ' ')" = '\n' ] ;;
    *) return 0 ;;
  esac
}
while kill -0 "$pid" 2>/dev/null; do
  for f in "$work/run"/*; do
    [ -f "$f" ] || continue
    whole "$f" || { [ -f "$f" ] && partial="$partial $(basename "$f")"; }
  done
  if grep -qE "^step +$kill_at " "$work/run.log"; then
    kill -9 "$pid"
    break
  fi
  sleep 0.01
done
wait "$pid" 2>/dev/null
status=$?
[ -z "$partial" ] || fail "partial files seen while running:$partial"
[ "$status" -eq 137 ] || fail "the run ended (status $status) before it was killed; lower KILL_MAX"
grep -q "results in" "$work/run.log" && fail "the killed run had finished"
last=$(grep -E "^step +[0-9]+ " "$work/run.log" | tail -1 | awk '{print $2}')
echo "killed after step ${last}"

# Refused: a damaged checkpoint, a checkpoint of another case.
cp -r "$work/run" "$work/damaged"
size=$(stat -c %s "$work/damaged/checkpoint.mxf")
# The middle byte inverted (a fixed byte could be the one already there).
byte=$(od -An -tu1 -j $((size / 2)) -N 1 "$work/damaged/checkpoint.mxf" | tr -d ' ')
printf "\\x$(printf %02x $((255 - byte)))" | dd of="$work/damaged/checkpoint.mxf" bs=1 seek=$((size / 2)) conv=notrunc status=none
"${exe[@]}" --restart "$work/damaged" >"$work/damaged.log" 2>&1 && fail "a damaged checkpoint was accepted"
grep -q "checksum mismatch" "$work/damaged.log" || fail "damaged checkpoint: $(tail -2 "$work/damaged.log")"
cp -r "$work/run" "$work/other"
# shellcheck disable=SC2086
"${exe[@]}" $other --restart "$work/other" >"$work/other.log" 2>&1 && fail "a restart with $other was accepted"
grep -q "written by another case" "$work/other.log" || fail "other case: $(tail -2 "$work/other.log")"

"${exe[@]}" --restart "$work/run" >"$work/restart.log" 2>&1 || fail "restart failed: $(tail -3 "$work/restart.log")"
from=$(sed -n 's/^restarted from .* after step \([0-9]*\)$/\1/p' "$work/restart.log")
[ -n "$from" ] && [ "$from" -le "$last" ] || fail "no restart from a checkpoint at or before step $last: $(head -2 "$work/restart.log")"
echo "restarted from the checkpoint after step $from"
ls "$work/run" | grep -q '\.tmp\.' && fail "temporary files left: $(ls "$work/run")"
n=0
for f in "$work/ref"/*; do
  b=$(basename "$f")
  [ "$b" = checkpoint.mxf ] && continue  # holds wall times
  cmp -s "$f" "$work/run/$b" || fail "$b differs from the uninterrupted run's"
  n=$((n + 1))
done
[ "$(ls "$work/run" | wc -l)" -eq "$(ls "$work/ref" | wc -l)" ] || fail "the restarted run left other files: $(ls "$work/run")"
echo "OK: $n result files equal to the uninterrupted run's, bitwise"
