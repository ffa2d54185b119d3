#!/usr/bin/env bash
# bench_fig5.sh: seed 001's Fig. 5 comparison (its Sec. 4: uniform marching, marching by
# transmittance, the guided method, at equal time, on experiment 1 and experiment 2), made with
# `photonmarch compare` and widened to the project's two path tracers (issue 14). For each scene
# one `compare` run: every method in METHODS, RUNS runs of BUDGET seconds each (equal time, the
# bake charged to every run of a method that needs one: docs/compare.md), measured against one
# reference; compare's table (RMSE, bias^2, variance, efficiency 1/(MSE x s), homogeneity) is
# written to OUT/SCENE/table.txt and summarised by bench/fig5_table.py into OUT/fig5.md, with
# each efficiency as a ratio to one method's in the same compare run (the figure we quote).
#
# The reference. In these scenes a point or directional light reaches the medium inside the
# glass only along refracted paths; shadow rays stop at a dielectric, so `delta` and
# `guided-unbiased` cannot sample that light and converge to an image without it (the volume
# caustic is missing: docs/surfaces.md). The photon-map methods carry it. So:
#   REF=delta    compare renders its own reference with delta (REF_SPP, capped at REF_TIME s):
#                unbiased for the light delta can sample; the marchers then show the missing
#                light as bias^2.
#   REF=uniform  (or guided, transmittance) the reference is that marcher's render with
#                REF_PHOTONS photons, REF_SPP samples per pixel capped at REF_TIME seconds: it
#                holds the refracted light, but it is the photon-map estimator itself (biased,
#                consistent as the photon count grows), so it shares the marchers' structure
#                and favours them; delta and guided-unbiased then show the light they cannot
#                sample as bias^2.
# Neither is the exact image; the bias^2 and variance columns say which part of each method's
# error is which.
#
#   bench/bench_fig5.sh [BUILD]
#   environment: SCENES ("exp1-point exp2-directional"), METHODS
#                (uniform,transmittance,guided,guided-unbiased,delta), RES (160,120),
#                BUDGET (15 s per run), RUNS (2), THREADS (2), REF (uniform), REF_SPP (4096),
#                REF_TIME (300), REF_PHOTONS (1000000), RATIO_TO (uniform), OUT
#                (bench/results/fig5-REF)
# Run it under `nice -n 19` on a shared machine; quote the ratios within one compare run. The
# methods run one after another (each method's K runs together), so load that changes during
# the run moves the ratios: compare two passes before trusting a ratio near 1.
set -euo pipefail
. "$(dirname "$0")/machine.sh"
bench_machine_note
BUILD=${1:-build}
SCENES=${SCENES:-exp1-point exp2-directional}
METHODS=${METHODS:-uniform,transmittance,guided,guided-unbiased,delta}
RES=${RES:-160,120}
BUDGET=${BUDGET:-15}
RUNS=${RUNS:-2}
THREADS=${THREADS:-2}
REF=${REF:-uniform}
REF_SPP=${REF_SPP:-4096}
REF_TIME=${REF_TIME:-300}
REF_PHOTONS=${REF_PHOTONS:-1000000}
RATIO_TO=${RATIO_TO:-uniform}
OUT=${OUT:-bench/results/fig5-$REF}
BIN="$BUILD/photonmarch"
make -s BUILD="$BUILD" "$BIN"
mkdir -p "$OUT"
{
  echo "bench_fig5: $(date -u '+%Y-%m-%d %H:%M UTC'), $(nproc) cores, load average $(cut -d' ' -f1-3 /proc/loadavg)"
  echo "commit $(git rev-parse --short HEAD 2>/dev/null || echo '?'), nice $(nice)"
  echo "RES=$RES BUDGET=$BUDGET RUNS=$RUNS THREADS=$THREADS METHODS=$METHODS"
  echo "REF=$REF REF_SPP=$REF_SPP REF_TIME=$REF_TIME REF_PHOTONS=$REF_PHOTONS"
} > "$OUT/machine.txt"
cat "$OUT/machine.txt" >&2

for scene in $SCENES; do
  file="scenes/$scene.json"
  dir="$OUT/$scene"
  mkdir -p "$dir"
  set_res=(--set "camera.resolution=[$RES]")
  ref_args=()
  if [ "$REF" = delta ]; then
    ref_args=(--ref-spp "$REF_SPP" --ref-time "$REF_TIME" --cache "$OUT/cache")
  else
    ref="$dir/ref-$REF.exr"
    if [ ! -f "$ref" ]; then
      echo "== $scene: reference by $REF, $REF_PHOTONS photons, $REF_SPP spp, at most $REF_TIME s" >&2
      "$BIN" render "$file" --method "$REF" "${set_res[@]}" --set "photons.count=$REF_PHOTONS" \
        --spp "$REF_SPP" --time "$REF_TIME" --seed 7777 --threads "$THREADS" --no-cache \
        -o "$ref" > "$dir/ref-$REF.log" 2>&1 || { cat "$dir/ref-$REF.log" >&2; exit 1; }
    fi
    ref_args=(--reference "$ref")
  fi
  echo "== $scene: compare $METHODS, $RUNS x $BUDGET s" >&2
  "$BIN" compare "$file" --methods "$METHODS" --equal time --budget "$BUDGET" --runs "$RUNS" \
    --threads "$THREADS" "${set_res[@]}" "${ref_args[@]}" -q -o "$dir/report" | tee "$dir/table.txt"
done
python3 "$(dirname "$0")/fig5_table.py" --ratio-to "$RATIO_TO" --machine "$OUT/machine.txt" --threads "$THREADS" \
  $(for s in $SCENES; do echo "$OUT/$s/report/metrics.json"; done) | tee "$OUT/fig5.md"
echo "results in $OUT/" >&2
