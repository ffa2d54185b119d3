#!/usr/bin/env bash
# bench_strongdelta.sh: `delta` with each of its thin-media strategies against plain `delta` at
# equal time (issue 21 item 4; docs/free-path.md "Measured"), on the easy suite (default,
# homogeneous, the environment-lit plume) and a thin fog crossed by a narrow spot
# (bench/scenes/thin-spot.json). Run from the repository root after
#     make build/photonmarch build/bench/bench_strongdelta
#   bench/bench_strongdelta.sh [OUTDIR]        (default out/strongdelta)
# Environment: RUN_SECONDS (10), RUNS (4), REF_SECONDS (240), THREADS (2).
# References are rendered once into OUTDIR by `delta` (the thin-spot one with equiangular
# sampling: same expectation, far less noise there), 24x a run's time, and reused when present;
# bench_strongdelta subtracts their own variance (their -stderr.exr) from every MSE. The first
# variant is plain `delta` (settings.equiangular false); `default` is `delta`'s default since
# session 72, "tiles" with the epochs' shares (docs/free-path.md "The default"). The references
# draw every sample (settings.adaptive false), so that they hold no block cut by the clock.
set -euo pipefail
. "$(dirname "$0")/machine.sh"
bench_machine_note
OUT=${1:-out/strongdelta}
RUN_SECONDS=${RUN_SECONDS:-10}
RUNS=${RUNS:-4}
REF_SECONDS=${REF_SECONDS:-240}
THREADS=${THREADS:-2}
mkdir -p "$OUT"
# name | scene | resolution | extra --set of the reference
cases=(
  "default|scenes/default.json|[160,120]|"
  "homogeneous|scenes/homogeneous.json|[100,100]|"
  "plume-env|scenes/plume-env.json|[128,96]|"
  "thin-spot|bench/scenes/thin-spot.json|[160,120]|settings.equiangular=true"
)
for c in "${cases[@]}"; do
  IFS='|' read -r name scene res refset <<< "$c"
  ref="$OUT/ref-$name.exr"
  if [ ! -f "$ref" ]; then
    extra=()
    [ -n "$refset" ] && extra=(--set "$refset")
    build/photonmarch render "$scene" --set "camera.resolution=$res" --set settings.adaptive=false "${extra[@]}" --time "$REF_SECONDS" \
      --seed 99 --threads "$THREADS" -q -o "$ref"
  fi
  echo "load average before $name: $(cut -d' ' -f1-3 /proc/loadavg)"
  build/bench/bench_strongdelta "$scene" --reference "$ref" --set "camera.resolution=$res" \
    --seconds "$RUN_SECONDS" --runs "$RUNS" --threads "$THREADS" \
    --variant delta --set settings.equiangular=false \
    --variant default \
    --variant equiangular --set settings.equiangular=true \
    --variant equiangular-camera --set settings.equiangular=camera \
    --variant equiangular-auto --set settings.equiangular=auto \
    --variant thin_bias-0.5 --set settings.thin_bias=0.5 \
    --variant both --set settings.equiangular=true --set settings.thin_bias=0.5
done
