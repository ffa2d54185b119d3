#!/usr/bin/env bash
# make bench: run every benchmark in bench/ and collect JSON + markdown under bench/results/.
# Run from the repository root (bench_sh and bench_render_tr load scenes/*.json).
# Within a benchmark, the configurations compared are timed interleaved (A, B, A, B, ...) and
# reported as medians with their min-max, so every ratio comes from one run under one load.
# The load average before each benchmark is written at the top of its markdown: on a shared
# machine absolute times move, ratios much less (docs/benchmarks.md).
set -euo pipefail
. "$(dirname "$0")/machine.sh"
bench_machine_note
BUILD=${1:-build}
OUT=bench/results
mkdir -p "$OUT"
QUICK=${BENCH_QUICK:+--quick}
for b in "$BUILD"/bench/*; do
  [ -x "$b" ] || continue
  name=$(basename "$b")
  echo "== $name" >&2
  { echo "load average before the run: $(cut -d' ' -f1-3 /proc/loadavg)"; echo;
    "$b" $QUICK --json "$OUT/$name.json"; } | tee "$OUT/$name.md"
done
echo "results in $OUT/" >&2
