#!/usr/bin/env bash
# make bench: run every benchmark in bench/ and collect JSON + markdown under bench/results/.
# Figures are medians of repeated timings taken in one run on this machine (docs/benchmarks.md).
set -euo pipefail
BUILD=${1:-build}
OUT=bench/results
mkdir -p "$OUT"
QUICK=${BENCH_QUICK:+--quick}
for b in "$BUILD"/bench/*; do
  [ -x "$b" ] || continue
  name=$(basename "$b")
  echo "== $name" >&2
  "$b" $QUICK --json "$OUT/$name.json" | tee "$OUT/$name.md"
done
echo "results in $OUT/" >&2
