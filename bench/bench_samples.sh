#!/usr/bin/env bash
# bench_samples.sh: samples per camera ray (march.samples, the N_mean of eq. 17) against
# efficiency, for the three placements (issue 9; run by hand; docs/guided-marching.md).
# Calibration data only: run it on scenes other than the benchmark's (default, beam), so the
# setting it picks is not tuned on the scenes that judge it.
#
# For each scene: one bake (the cache beside the renders, shared by every run, so the time
# compared is the render's own, `render_seconds`); then K runs (seeds 101..100+K) of
# guided, transmittance and uniform at every N in NS, interleaved; bench_march_stats with
# --time-key render_seconds gives variance (against each group's own mean image), render time
# and efficiency 1/(var x time) per group. A short delta reference is rendered only because
# the stats tool wants one (its bias columns are not used here).
#
#   bench/bench_samples.sh [BUILD]   environment: SCENES ("cloud smoke-vdb"), NS ("1 2 4 8"),
#                                    K (4), RES (120,90), SPP (4), THREADS (1)
set -euo pipefail
. "$(dirname "$0")/machine.sh"
bench_machine_note
BUILD=${1:-build}
SCENES=${SCENES:-cloud smoke-vdb}
NS=${NS:-1 2 4 8}
K=${K:-4}
RES=${RES:-120,90}
SPP=${SPP:-4}
THREADS=${THREADS:-1}
OUT=bench/results/samples
BIN="$BUILD/photonmarch"
STATS="$BUILD/bench/bench_march_stats"
METHODS="guided transmittance uniform"
[ -x "$BIN" ] && [ -x "$STATS" ] || make -s "$BIN" "$STATS"

render() { # scene method out [extra args...]
  local scene=$1 method=$2 out=$3
  shift 3
  "$BIN" render "scenes/$scene.json" --method "$method" --threads "$THREADS" -q \
    --set "camera.resolution=[$RES]" -o "$out" "$@"
}

for scene in $SCENES; do
  d="$OUT/$scene"
  mkdir -p "$d"
  [ -f "$d/ref.exr" ] || render "$scene" delta "$d/ref.exr" --seed 7777 --time 30 --spp 16777216
  for k in $(seq 1 "$K"); do
    for n in $NS; do
      for m in $METHODS; do
        echo "== $scene run $k: $m, N = $n" >&2
        render "$scene" "$m" "$d/$m-n$n-$k.exr" --seed $((100 + k)) --spp "$SPP" --set "march.samples=$n"
      done
    done
  done
  args=()
  for m in $METHODS; do
    for n in $NS; do
      args+=(--group "$m-n$n" $(for k in $(seq 1 "$K"); do echo "$d/$m-n$n-$k.exr"; done))
    done
  done
  {
    echo "### $scene: samples per ray, $RES px, $SPP spp, K = $K, $THREADS thread(s), render time only"
    echo
    "$STATS" --ref "$d/ref.exr" --time-key render_seconds "${args[@]}"
    echo
    echo "| group | shadow rays / path | collisions / path | lookups / path | samples / ray |"
    echo "|---|---|---|---|---|"
    for m in $METHODS; do
      for n in $NS; do
        python3 - "$m-n$n" "$d/$m-n$n-1.json" <<'PY'
import json, sys
j = json.load(open(sys.argv[2]))
print("| %s | %.2f | %.1f | %.1f | %.2f |" % (sys.argv[1], j["shadow_rays"] / j["paths"],
      j["collisions_per_path"], j["lookups_per_path"], j["march"]["samples_per_ray"]))
PY
      done
    done
    echo
  } | tee "$d/stats.md"
done
