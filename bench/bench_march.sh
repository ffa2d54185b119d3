#!/usr/bin/env bash
# bench_march.sh: issue 9's benchmark of guided marching against its baselines (run by hand;
# docs/guided-marching.md has the method and the figures). For each scene:
#   1. a long `delta` reference (its own seed; its noise is in REF-stderr.exr);
#   2. K independent runs (seeds 101..100+K) of guided, transmittance and uniform (SPP samples
#      per pixel each, or with TIME set, TIME seconds each, bake included: equal time), for
#      march.ls = nee+photons (the default) and photons, interleaved (run k of every
#      configuration before run k+1 of any), so load from other users of the machine falls on
#      all methods alike;
#   3. bench_march_stats: variance, time, efficiency 1/(var x time), bias^2 against the
#      reference, noise homogeneity, and the ratios guided/other with their half-split spread;
#   4. equal-time RMSE, guided vs delta, at the budgets in BUDGETS (--time, bake included;
#      BUDGETS="" skips it);
#   5. with SWEEP=1, guided alone on each scene over the guide's SH bands (guide.bands = 2, 4,
#      6, uniform grid) and the adaptive grid (bands 4), K runs each, march.ls = nee+photons.
# Every render's time includes its bake (photon map + guide), which each run repeats.
#
#   bench/bench_march.sh [BUILD]      environment: K (4), RES (160,120), SPP (4), REF_TIME (120),
#                                     BUDGETS ("10 30"), SCENES ("default beam"), THREADS (2),
#                                     SWEEP (0), RUNS (1: 0 skips steps 2-3), TIME (unset),
#                                     LS ("nee+photons photons")
# A reference already at $OUT/SCENE/ref.exr (with ref-stderr.exr) is used as it is.
set -euo pipefail
. "$(dirname "$0")/machine.sh"
bench_machine_note
BUILD=${1:-build}
K=${K:-4}
RES=${RES:-160,120}
SPP=${SPP:-4}
REF_TIME=${REF_TIME:-120}
BUDGETS=${BUDGETS-10 30}  # empty: no equal-time step
SCENES=${SCENES:-default beam}
THREADS=${THREADS:-2}
SWEEP=${SWEEP:-0}
RUNS=${RUNS:-1}
TIME=${TIME:-}
LS=${LS:-nee+photons photons}
if [ -n "$TIME" ]; then BUDGET=(--time "$TIME" --spp 16777216); TAG="${TIME} s each"
else BUDGET=(--spp "$SPP"); TAG="$SPP spp"; fi
OUT=bench/results/march
BIN="$BUILD/photonmarch"
STATS="$BUILD/bench/bench_march_stats"
make -s "$BIN" "$STATS"
mkdir -p "$OUT"

render() { # scene method out [extra args...]
  local scene=$1 method=$2 out=$3
  shift 3
  "$BIN" render "scenes/$scene.json" --method "$method" --threads "$THREADS" -q \
    --set "camera.resolution=[$RES]" -o "$out" "$@"
}

for scene in $SCENES; do
  d="$OUT/$scene"
  mkdir -p "$d"
  echo "== $scene: delta reference, ${REF_TIME} s" >&2
  [ -f "$d/ref.exr" ] || render "$scene" delta "$d/ref.exr" --seed 7777 --time "$REF_TIME" --spp 16777216
  for k in $(seq 1 "$K"); do
    [ "$RUNS" = 1 ] || break
    for ls in $LS; do
      for m in guided transmittance uniform; do
        echo "== $scene run $k: $m, ls $ls" >&2
        render "$scene" "$m" "$d/$m-$ls-$k.exr" --seed $((100 + k)) "${BUDGET[@]}" --set "march.ls=$ls"
      done
    done
  done
  for ls in $LS; do
    [ "$RUNS" = 1 ] || break
    args=()
    for m in guided transmittance uniform; do
      args+=(--group "$m" $(for k in $(seq 1 "$K"); do echo "$d/$m-$ls-$k.exr"; done))
    done
    { echo "### $scene, march.ls = $ls, $RES px, $TAG, K = $K, $THREADS thread(s)"; echo
      "$STATS" --ref "$d/ref.exr" "${args[@]}"; echo; } | tee "$d/stats-$ls.md"
  done
  imgs=()
  for T in $BUDGETS; do
    for m in guided delta; do
      echo "== $scene equal time: $m, $T s" >&2
      render "$scene" "$m" "$d/time-$m-$T.exr" --seed 55 --time "$T" --spp 16777216
      imgs+=("$d/time-$m-$T.exr")
    done
  done
  if [ -n "$BUDGETS" ]; then
    { echo "### $scene, equal time, RMSE against the reference"; echo
      "$STATS" --rmse "$d/ref.exr" "${imgs[@]}"; echo; } | tee "$d/equal-time.md"
  fi
  [ "$SWEEP" = 1 ] || continue
  configs="bands2:guide.bands=2 bands4:guide.bands=4 bands6:guide.bands=6 bands8:guide.bands=8 adaptive8:guide.grid=adaptive"
  for k in $(seq 1 "$K"); do
    for c in $configs; do
      echo "== $scene sweep run $k: guided, ${c#*:}" >&2
      render "$scene" guided "$d/sweep-${c%%:*}-$k.exr" --seed $((100 + k)) --spp "$SPP" --set "${c#*:}"
    done
  done
  args=()
  for c in $configs; do
    args+=(--group "${c%%:*}" $(for k in $(seq 1 "$K"); do echo "$d/sweep-${c%%:*}-$k.exr"; done))
  done
  { echo "### $scene, guided, guide sweep, march.ls = nee+photons, $RES px, $SPP spp, K = $K"; echo
    "$STATS" --ref "$d/ref.exr" "${args[@]}"; echo; } | tee "$d/sweep.md"
done
echo "results in $OUT/" >&2
