#!/usr/bin/env bash
# bench_suites.sh: every method on the hard-light suite and the easy suite (issue 21 item 5;
# docs/scenes.md, "The suites") at equal time, with one command. For each scene one
# `photonmarch compare` run (docs/compare.md): every method in METHODS, RUNS independent runs of
# BUDGET seconds each (wall time per run, the bake of a photon-map method charged to every one
# of its runs), measured against one reference rendered by delta (with settings.equiangular
# "tiles" where the scene has a point or spot light and does not name the key: docs/compare.md)
# for REF_TIME seconds (a cap;
# REF_SPP is set high so that the time decides), whose own per-pixel variance compare removes
# from bias^2 and this script's table removes from the MSE. Each scene's report folder is
# OUT/SCENE/ (index.html, metrics.json, images) with compare's own table in OUT/SCENE.txt; the
# summary, bench/suites_table.py over every metrics.json, is OUT/summary.md: per scene and
# method the efficiency 1/((MSE - ref_var) x seconds) as a ratio to delta's in the same compare
# run, and the bias share bias^2 / (MSE - ref_var).
#
#   bench/bench_suites.sh [BUILD]
#   environment (defaults):
#     SUITE     hard | easy | all (all)
#     SCENES    scene names without .json, instead of the suite's
#     METHODS   delta,guided,guided-unbiased,uniform,transmittance
#     BUDGET    seconds per run (60)          RUNS     runs per method (4)
#     RES       W,H (160,120)                 THREADS  worker threads (2)
#     REF_TIME  reference seconds (20 x BUDGET)  REF_SPP  reference spp cap (16777216)
#     SEED      base seed of the runs (1)     OUT      bench/results/suites
# The references are cached in OUT/cache (keyed by the scene, resolution, REF_TIME and REF_SPP:
# docs/compare.md), so a second pass over the same scenes renders only the runs. At the
# defaults one scene takes 5 x 4 x 60 s + 1200 s = 40 min, both suites 4.7 hours.
# Run it on a quiet machine (bench/machine.sh; docs/benchmarks.md): the methods of a scene run
# one after another, so load that changes during the run moves the ratios.
set -euo pipefail
. "$(dirname "$0")/machine.sh"
bench_machine_note
BUILD=${1:-build}
SUITE=${SUITE:-all}
HARD="hard-narrow-spot hard-window-beam hard-lens-caustic hard-dense-block"
EASY="default homogeneous plume-env"
case "$SUITE" in
  hard) suite_scenes=$HARD ;;
  easy) suite_scenes=$EASY ;;
  all) suite_scenes="$HARD $EASY" ;;
  *) echo "bench_suites: SUITE must be hard, easy or all, not '$SUITE'" >&2; exit 2 ;;
esac
SCENES=${SCENES:-$suite_scenes}
METHODS=${METHODS:-delta,guided,guided-unbiased,uniform,transmittance}
BUDGET=${BUDGET:-60}
RUNS=${RUNS:-4}
RES=${RES:-160,120}
THREADS=${THREADS:-2}
REF_TIME=${REF_TIME:-$(awk -v b="$BUDGET" 'BEGIN { print 20 * b }')}
REF_SPP=${REF_SPP:-16777216}
SEED=${SEED:-1}
OUT=${OUT:-bench/results/suites}
BIN="$BUILD/photonmarch"
make -s BUILD="$BUILD" "$BIN"
mkdir -p "$OUT"
n_methods=$(echo "$METHODS" | tr ',' '\n' | grep -c .)
n_scenes=$(echo $SCENES | wc -w)
{
  echo "bench_suites: $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg)"
  echo "commit $(git rev-parse --short HEAD 2>/dev/null || echo '?'), nice $(nice)"
  echo "SUITE=$SUITE SCENES=\"$SCENES\""
  echo "METHODS=$METHODS BUDGET=$BUDGET RUNS=$RUNS RES=$RES THREADS=$THREADS SEED=$SEED"
  echo "reference: delta, REF_TIME=$REF_TIME REF_SPP=$REF_SPP (cached in $OUT/cache)"
  echo "planned: $n_scenes scenes x ($n_methods methods x $RUNS runs x $BUDGET s + a reference of up to $REF_TIME s)"
} > "$OUT/machine.txt"
cat "$OUT/machine.txt" >&2

metrics=()
failed=()
for scene in $SCENES; do
  file="scenes/$scene.json"
  echo "== $scene: compare $METHODS, $RUNS x $BUDGET s, reference delta $REF_TIME s" >&2
  if "$BIN" compare "$file" --methods "$METHODS" --equal time --budget "$BUDGET" --runs "$RUNS" \
       --ref-spp "$REF_SPP" --ref-time "$REF_TIME" --cache "$OUT/cache" --seed "$SEED" \
       --threads "$THREADS" --set "camera.resolution=[$RES]" -q -o "$OUT/$scene" > "$OUT/$scene.txt"; then
    cat "$OUT/$scene.txt"
    metrics+=("$OUT/$scene/metrics.json")
  else
    echo "bench_suites: $scene: compare failed (exit $?); left out of the summary" >&2
    failed+=("$scene")
  fi
done
if [ ${#metrics[@]} -gt 0 ]; then
  python3 "$(dirname "$0")/suites_table.py" --machine "$OUT/machine.txt" --hard "$HARD" --easy "$EASY" \
    "${metrics[@]}" | tee "$OUT/summary.md"
fi
echo "results in $OUT/ (summary.md; a report folder per scene)" >&2
if [ ${#failed[@]} -gt 0 ]; then
  echo "bench_suites: failed: ${failed[*]}" >&2
  exit 1
fi
