#!/usr/bin/env bash
# bench_gu.sh: issue 10's benchmark of guided-unbiased against delta, part by part (run by
# hand; docs/guided-unbiased.md has the method and the figures). For each scene:
#   K independent runs (seeds 101..100+K) of each configuration below, TIME seconds of wall
#   time each, bake included: guided-unbiased bakes afresh in every run (--no-cache), so
#   each run pays its photon map and guide; runs are interleaved (run k of every configuration
#   before run k+1 of any), so load from other users of the machine falls on all alike.
#     delta        the reference method
#     dist         guided-unbiased, guided distances only (directions and roulette off)
#     dist+dir     ... plus guided directions
#     all          the default: guided directions, roulette and splitting (guided distances
#                  off since session 46, docs/guided-unbiased.md)
#     all+dist     ... plus guided distances (the default before session 46)
#     all-nosplit  the default with guide.split_max = 1 (roulette without splitting)
#     dir          guided directions alone
#     rr           roulette and splitting alone
#     gu:K=V+K=V   guided-unbiased with those scene keys set (calibration sweeps)
#   then bench_march_stats: per configuration the variance of the K runs against their own
#   mean (both methods are unbiased, so no reference is needed for the variance; the
#   reference only checks that the means agree), the time, the efficiency 1/(var x time) and
#   its ratio delta / other, from all runs and from each half (the spread).
#
#   bench/bench_gu.sh [BUILD]    environment: K (4), TIME (20), RES (160,120), THREADS (1),
#                                SCENES ("default beam cloud-env homogeneous"), CONFIGS (all
#                                of the above), REF_TIME (60)
# cloud-env is scenes/cloud.json with its point light replaced by a uniform environment of
# radiance 1 (the issue's "diffuse, evenly lit smoke").
set -euo pipefail
. "$(dirname "$0")/machine.sh"
bench_machine_note
BUILD=${1:-build}
K=${K:-4}
TIME=${TIME:-20}
RES=${RES:-160,120}
THREADS=${THREADS:-1}
SCENES=${SCENES:-default beam cloud-env homogeneous}
CONFIGS=${CONFIGS:-delta dist dist+dir all all-nosplit dir rr}
REF_TIME=${REF_TIME:-60}
OUT=${OUT:-bench/results/gu}
BIN="$BUILD/photonmarch"
STATS="$BUILD/bench/bench_march_stats"
make -s BUILD="$BUILD" "$BIN" "$STATS"
mkdir -p "$OUT"

config_args() { # configuration -> method and settings
  case $1 in
    delta) echo delta ;;
    dist) echo guided-unbiased --set guide.distances=true --set guide.directions=false --set guide.roulette=false ;;
    dist+dir) echo guided-unbiased --set guide.distances=true --set guide.roulette=false ;;
    all) echo guided-unbiased ;;
    all+dist) echo guided-unbiased --set guide.distances=true ;;
    all-nosplit) echo guided-unbiased --set guide.split_max=1 ;;
    dir) echo guided-unbiased --set guide.distances=false --set guide.roulette=false ;;
    rr) echo guided-unbiased --set guide.distances=false --set guide.directions=false ;;
    gu:*) echo guided-unbiased $(tr '+' '\n' <<< "${1#gu:}" | sed 's/^/--set /') ;;
    *) echo "bench_gu: unknown configuration $1" >&2; exit 2 ;;
  esac
}
render() { # scene config out [extra args...]
  local scene=$1 config=$2 out=$3 file="scenes/$1.json" ca extra=()
  shift 3
  if [ "$scene" = cloud-env ]; then
    file=scenes/cloud.json
    extra=(--set 'lights=[{"type":"environment","radiance":[1,1,1]}]')
  fi
  read -r -a ca <<< "$(config_args "$config")"
  "$BIN" render "$file" "${extra[@]}" --method "${ca[0]}" "${ca[@]:1}" --threads "$THREADS" -q \
    --no-cache --set "camera.resolution=[$RES]" -o "$out" "$@"
}

for scene in $SCENES; do
  d="$OUT/$scene"
  mkdir -p "$d"
  echo "== $scene: delta reference, ${REF_TIME} s" >&2
  [ -f "$d/ref.exr" ] || render "$scene" delta "$d/ref.exr" --seed 7777 --time "$REF_TIME" --spp 16777216
  for k in $(seq 1 "$K"); do
    for c in $CONFIGS; do
      echo "== $scene run $k: $c" >&2
      render "$scene" "$c" "$d/$c-$k.exr" --seed $((100 + k)) --time "$TIME" --spp 16777216
    done
  done
  args=()
  for c in $CONFIGS; do
    args+=(--group "$c" $(for k in $(seq 1 "$K"); do echo "$d/$c-$k.exr"; done))
  done
  { echo "### $scene, $RES px, ${TIME} s per run (bake included), K = $K, $THREADS thread(s)"; echo
    "$STATS" --ref "$d/ref.exr" "${args[@]}"; echo; } | tee "$d/stats.md"
done
echo "results in $OUT/" >&2
