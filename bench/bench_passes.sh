#!/usr/bin/env bash
# bench_passes.sh: the size of a progressive photon pass at equal time (run by hand;
# docs/benchmarks.md quotes its tables). For each scene one `compare` of delta, then one per
# pass size and source (LS: nee+photons, nee+beams) of `guided` with `photons.progressive`
# on (size `fixed`: off, one fixed map), all on the
# same seed, resolution and reference; it prints per pass size the efficiency over delta's,
# the samples per pixel, bias^2 and variance (the pass size trades photons traced per pass
# against camera samples rendered with them: docs/guided-marching.md "Progressive photon
# passes").
#
#   bench/bench_passes.sh [BIN]
#       environment: SCENES (calibration scenes: cloud smoke-vdb glass-fog sphere-in-fog),
#                    SIZES (pass_count x pass_spp, or fixed: "20000x1 20000x4 50000x4 200000x1 200000x4"),
#                    LS (the sources to measure, each at every size: nee+photons),
#                    BUDGET (10), RUNS (2), SEED (1), RES (160,120), METHOD (guided),
#                    REFS (/work/ref: the reference of NAME is the first REFS/NAME-*ref.exr),
#                    SET (more --set overrides for the method's runs, space-separated:
#                    SET='settings.select="tiles"'), OUT (bench/results/passes)
# References as bench/bench_ab.sh describes them.
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/machine.sh
bench_machine_note
BIN=${1:-build/photonmarch}
SCENES=${SCENES:-cloud smoke-vdb glass-fog sphere-in-fog}
SIZES=${SIZES:-20000x1 20000x4 50000x4 200000x1 200000x4}
BUDGET=${BUDGET:-10}
RUNS=${RUNS:-2}
SEED=${SEED:-1}
RES=${RES:-160,120}
METHOD=${METHOD:-guided}
LS=${LS:-nee+photons}
REFS=${REFS:-/work/ref}
OUT=${OUT:-bench/results/passes}
more=()
set -f # the overrides are words, not patterns (camera.resolution=[160,120])
for kv in ${SET:-}; do more+=(--set "$kv"); done
set +f

field() { # field $3 of method $2 in compare folder $1
  jq -r --arg m "$2" --arg f "$3" '.methods[] | select(.label == $m) | .[$f]' "$1/metrics.json"
}

printf '%-16s %-12s %-10s %8s %8s %10s %10s\n' scene ls size "x delta" spp bias2 variance
for name in $SCENES; do
  ref=$(bench_reference bench_passes "$name")
  common=(--budget "$BUDGET" --runs "$RUNS" --seed "$SEED" --set "camera.resolution=[$RES]" --reference "$ref")
  mkdir -p "$OUT"
  bench_compare bench_passes "$OUT/$name-delta.txt" "$BIN" compare "scenes/$name.json" --methods delta "${common[@]}" -o "$OUT/$name-delta"
  d=$(field "$OUT/$name-delta" delta efficiency)
  for size in $SIZES; do for ls in $LS; do
    if [ "$size" = fixed ]; then
      pass=(--set photons.progressive=false)
    else
      pass=(--set photons.progressive=true --set "photons.pass_count=${size%x*}" --set "photons.pass_spp=${size#*x}")
    fi
    o="$OUT/$name-$ls-$size"
    bench_compare bench_passes "$o.txt" "$BIN" compare "scenes/$name.json" --methods "$METHOD" "${common[@]}" \
      --set "march.ls=$ls" "${pass[@]}" "${more[@]}" -o "$o"
    printf '%-16s %-12s %-10s %8.3f %8.1f %10.3g %10.3g\n' "$name" "$ls" "$size" \
      "$(awk -v x="$(field "$o" "$METHOD" efficiency)" -v d="$d" 'BEGIN { print x / d }')" \
      "$(field "$o" "$METHOD" spp)" "$(field "$o" "$METHOD" bias2)" "$(field "$o" "$METHOD" variance)"
  done; done
done
