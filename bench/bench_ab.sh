#!/usr/bin/env bash
# bench_ab.sh: two builds of the guided methods at equal time against the same delta, scene by
# scene (run by hand; docs/benchmarks.md quotes its tables). For each scene one `compare` by
# build B of delta and METHODS, then one `compare` by build A of METHODS alone, on the same
# seed, resolution and reference, one right after the other; it prints each method's efficiency
# over delta's (delta's from B's compare: delta is the same code in both builds when only the
# guided methods changed; check that with bench/bench_speed.sh), A then B.
#
#   bench/bench_ab.sh A_BIN B_BIN
#       environment: SCENES (the benchmark's eight), METHODS (guided,guided-unbiased),
#                    BUDGET (10), RUNS (4), SEED (7), RES (160,120),
#                    REFS (/work/ref: the reference of NAME is the first REFS/NAME-*ref.exr),
#                    OUT (bench/results/ab),
#                    SET (scene overrides for both builds' runs, space-separated KEY=VALUE:
#                    e.g. "march.ls=nee+photons photons.progressive=true")
#   e.g. bench/bench_ab.sh /tmp/old/photonmarch build/photonmarch
# A reference is an image of the scene at RES from a long render (e.g. `render --method delta
# --time 200 --spp 16777216 --seed 99 --set camera.resolution=[160,120] -o REFS/NAME-dref.exr`,
# 20x the budget); compare removes its own variance and says when it is too noisy to rank.
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/machine.sh
bench_machine_note
A=${1:?usage: bench/bench_ab.sh A_BIN B_BIN}
B=${2:?usage: bench/bench_ab.sh A_BIN B_BIN}
SCENES=${SCENES:-$BENCH_EIGHT}
METHODS=${METHODS:-guided,guided-unbiased}
BUDGET=${BUDGET:-10}
RUNS=${RUNS:-4}
SEED=${SEED:-7}
RES=${RES:-160,120}
REFS=${REFS:-/work/ref}
OUT=${OUT:-bench/results/ab}
SET=${SET:-}

eff() { # efficiency of method $2 in compare folder $1
  jq -r --arg m "$2" '.methods[] | select(.label == $m) | .efficiency' "$1/metrics.json"
}

printf '%-18s %-16s %8s %8s\n' scene method A B
for name in $SCENES; do
  ref=$(bench_reference bench_ab "$name")
  common=(--budget "$BUDGET" --runs "$RUNS" --seed "$SEED" --set "camera.resolution=[$RES]" --reference "$ref")
  read -ra sets <<< "$SET" # split on spaces only: a value such as [320,240] is no glob
  for kv in "${sets[@]}"; do common+=(--set "$kv"); done
  mkdir -p "$OUT"
  bench_compare bench_ab "$OUT/$name-B.txt" "$B" compare "scenes/$name.json" --methods "delta,$METHODS" "${common[@]}" -o "$OUT/$name-B"
  bench_compare bench_ab "$OUT/$name-A.txt" "$A" compare "scenes/$name.json" --methods "$METHODS" "${common[@]}" -o "$OUT/$name-A"
  d=$(eff "$OUT/$name-B" delta)
  for m in ${METHODS//,/ }; do
    printf '%-18s %-16s %8.3f %8.3f\n' "$name" "$m" \
      "$(awk -v x="$(eff "$OUT/$name-A" "$m")" -v d="$d" 'BEGIN { print x / d }')" \
      "$(awk -v x="$(eff "$OUT/$name-B" "$m")" -v d="$d" 'BEGIN { print x / d }')"
  done
done
