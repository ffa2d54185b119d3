#!/usr/bin/env bash
# bench_calibrate.sh: one setting of a method tried against its default on the calibration
# scenes, at equal time (run by hand; docs/benchmarks.md says which settings were chosen so).
# The calibration scenes are not in the benchmark's tables, so a default picked here is not
# tuned on the scenes that judge it.
#
# For each scene NAME and each seed: one `compare` of delta and METHOD at their defaults
# (RUNS runs of BUDGET seconds, the bake charged), then one `compare` of METHOD alone with
# every --set of VARIANT, on the same seed, resolution and reference; it prints METHOD's
# efficiency over delta's, default then variant (delta's from the first compare: the two
# compares follow each other, on a quiet machine). Resolution and reference are the gallery's
# (scripts/make-gallery.sh): the scene's resolution / 2 (/ 4 when that is over 160 wide) and the
# 60-s reference of out/gallery/NAME when there is one, else a reference of REF_TIME seconds
# rendered by the first compare.
#
#   bench/bench_calibrate.sh METHOD 'KEY=VALUE [KEY=VALUE...]' [BUILD]
#       environment: SCENES (the seven below), SEEDS ("1"), BUDGET (10), RUNS (2),
#                    REF_TIME (60), OUT (bench/results/calibrate)
#   e.g. bench/bench_calibrate.sh guided 'march.paths=0.5'
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/machine.sh
bench_machine_note
METHOD=${1:?usage: bench/bench_calibrate.sh METHOD 'KEY=VALUE ...' [BUILD]}
VARIANT=${2:?usage: bench/bench_calibrate.sh METHOD 'KEY=VALUE ...' [BUILD]}
BUILD=${3:-build}
# glass-fog (session 21): its spot lights the fog by way of glass, so the marchers' march.ls
# defaults to nee+beams with progressive passes there (docs/scene-format.md) and `compare`
# renders a photon reference unless one is given; to measure nee+paths there as before, name
# it in the variant (march.ls=nee+paths) or leave glass-fog out of SCENES.
SCENES=${SCENES:-cloud smoke-vdb glass-fog sphere-in-fog hetero-forward noise-block beam-vdb}
SEEDS=${SEEDS:-1}
BUDGET=${BUDGET:-10}
RUNS=${RUNS:-2}
REF_TIME=${REF_TIME:-60}
OUT=${OUT:-bench/results/calibrate}
BIN="$BUILD/photonmarch"
make -s BUILD="$BUILD" "$BIN"
sets=()
for kv in $VARIANT; do sets+=(--set "$kv"); done
tag=$(echo "$METHOD $VARIANT" | tr -c 'A-Za-z0-9.=\n' '_')

eff() { # efficiency of method $2 in compare output $1
  jq -r --arg m "$2" '.methods[] | select(.label == $m) | .efficiency' "$1/metrics.json"
}

printf '%-16s %5s %10s %10s\n' scene seed default variant
for name in $SCENES; do
  scene=scenes/$name.json
  w=$(jq '.camera.resolution[0]' "$scene")
  h=$(jq '.camera.resolution[1]' "$scene")
  d=2
  [ $((w / 2)) -gt 160 ] && d=4
  res="[$((w / d)),$((h / d))]"
  ref=()
  gal=out/gallery/$name/metrics.json
  if [ -f "$gal" ] && [ -f "$(jq -r .reference.source "$gal")" ]; then
    ref=(--reference "$(jq -r .reference.source "$gal")")
  else
    ref=(--ref-time "$REF_TIME" --ref-spp 1000000)
  fi
  for seed in $SEEDS; do
    o=$OUT/$name-$seed
    mkdir -p "$o"
    "$BIN" compare "$scene" --methods "delta,$METHOD" --budget "$BUDGET" --runs "$RUNS" \
        --set "camera.resolution=$res" "${ref[@]}" --seed "$seed" -q -o "$o/default-$METHOD"
    # the first compare's reference, when it rendered one, serves the variant too
    r2=("${ref[@]}")
    [ "${ref[0]}" = --reference ] || r2=(--reference "$(jq -r .reference.source "$o/default-$METHOD/metrics.json")")
    "$BIN" compare "$scene" --methods "$METHOD" --budget "$BUDGET" --runs "$RUNS" \
        --set "camera.resolution=$res" "${sets[@]}" "${r2[@]}" --seed "$seed" -q -o "$o/$tag"
    e_d=$(eff "$o/default-$METHOD" delta)
    e_m=$(eff "$o/default-$METHOD" "$METHOD")
    e_v=$(eff "$o/$tag" "$METHOD")
    printf '%-16s %5s %9.3fx %9.3fx\n' "$name" "$seed" \
        "$(echo "$e_m / $e_d" | bc -l)" "$(echo "$e_v / $e_d" | bc -l)"
  done
done
