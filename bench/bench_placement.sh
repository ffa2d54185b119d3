#!/usr/bin/env bash
# bench_placement.sh: what the placement of the samples alone buys, ray by ray (issue 9; run by
# hand, docs/guided-marching.md). For a lattice of pixels of each scene, `photonmarch explain`
# lays the camera ray open (dense integrand, 4000 simulated draws of each placement) and gives
# the variance of each placement's estimate of the ray's integral. This script reports, over
# the rays that meet lit medium (I > 1% of the largest I), the per-sample variance ratio
#   (var_other x N_other) / (var_guided x N_guided)
# i.e. how many times more samples `other` needs for guided's noise on that ray: median,
# quartiles and the share of rays where guided wins. No render noise enters (no film jitter, no
# photon noise: one bake); what it leaves out is the cost of a sample and the noise that is not
# placement (anti-aliasing, next-event estimation, T along the ray), which bench_march.sh sees.
#
#   bench/bench_placement.sh [BUILD]   environment: SCENES ("default beam"), RES (160,120),
#                                      STEP (16: every 16th pixel each way), SET (extra --set,
#                                      space-separated KEY=VALUE), LABEL (results subfolder)
set -euo pipefail
. "$(dirname "$0")/machine.sh"
bench_machine_note
BUILD=${1:-build}
SCENES=${SCENES:-default beam}
RES=${RES:-160,120}
STEP=${STEP:-16}
SET=${SET:-}
LABEL=${LABEL:-default}
OUT=bench/results/placement/$LABEL
BIN="$BUILD/photonmarch"
make -s "$BIN"
mkdir -p "$OUT"
W=${RES%,*}; H=${RES#*,}
for scene in $SCENES; do
  d="$OUT/$scene"; mkdir -p "$d"
  extra=(--set "camera.resolution=[$RES]")
  for s in $SET; do extra+=(--set "$s"); done
  pixels=()
  for ((y = STEP / 2; y < H; y += STEP)); do
    for ((x = STEP / 2; x < W; x += STEP)); do pixels+=(--pixel "$x,$y"); done
  done
  "$BIN" explain "scenes/$scene.json" "${pixels[@]}" "${extra[@]}" -q -o "$d/px" >/dev/null
  python3 - "$d" "$scene" <<'PY'
import json, glob, sys, statistics as st
d, scene = sys.argv[1], sys.argv[2]
rows = []
for f in sorted(glob.glob(d + "/px-*.json")):
    j = json.load(open(f))
    if j.get("hits_media") and j["I"] > 0:
        rows.append(j)
if not rows:
    print(f"{scene}: no ray meets the media"); sys.exit(0)
Imax = max(r["I"] for r in rows)
lit = [r for r in rows if r["I"] > 0.01 * Imax]
def per_sample(r, k):
    p = r["placements"][k]; return p["variance"] * p["samples"]
print(f"### {scene} ({d}): {len(lit)} lit rays of {len(rows)} that meet the media")
print()
print("| other placement | median ratio | quartiles | guided better on |")
print("|---|---|---|---|")
for k in ("transmittance", "uniform"):
    q = sorted(per_sample(r, k) / per_sample(r, "guided") for r in lit if per_sample(r, "guided") > 0)
    n = len(q)
    quart = st.quantiles(q, n=4) if n >= 2 else [q[0]] * 3
    print(f"| {k} | {st.median(q):.2f} | {quart[0]:.2f} - {quart[2]:.2f} | {sum(v > 1 for v in q)}/{n} |")
gN = [r["placements"]["guided"]["samples"] for r in lit]
print()
print(f"guided samples per lit ray: median {st.median(gN):.0f}, range {min(gN)}-{max(gN)}")
PY
done
