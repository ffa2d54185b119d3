#!/usr/bin/env bash
# bench_headroom.sh: how much a tile selection with the beams as a fifth estimator could gain
# over `guided`'s default selection, scored offline (docs/benchmarks.md "Session 56").
#
#   bench/bench_headroom.sh SCENE REFERENCE.exr [OUT_DIR] [SECONDS]
#
# Renders, at 160x120 on two threads, each estimator alone for SECONDS (default 40) as the
# selection renders it (bench_select_score's tables: delta's path, the nee+paths marcher,
# delta's path with the equiangular strategy on every flight, guided-unbiased's paths, and the
# nee+beams marcher with progressive passes), and two traced 64-spp renders (default `guided`;
# `guided` with nee+beams and "tiles") for the tiles' counted costs; then bench/headroom.py
# scores choices against the tables (REFERENCE: a long `delta` render at 160x120 with its
# -stderr.exr, for the beams' squared bias). Needs Debian's python3 (PYTHON to override) with OpenImageIO and numpy
# (Debian: python3-openimageio, python3-numpy). Not a timed test: it prints ratios.
set -euo pipefail
scene=${1:?usage: bench/bench_headroom.sh SCENE REFERENCE.exr [OUT_DIR] [SECONDS]}
ref=${2:?usage: bench/bench_headroom.sh SCENE REFERENCE.exr [OUT_DIR] [SECONDS]}
here=$(cd "$(dirname "$0")/.." && pwd)
out=${3:-$here/bench/results/headroom}
sec=${4:-40}
bin=$here/build/photonmarch
name=$(basename "$scene" .json)
mkdir -p "$out"
R=(--set 'camera.resolution=[160,120]' --threads 2 -q --no-cache)
run() { local tag=$1; shift; "$bin" render "$scene" "$@" "${R[@]}" -o "$out/$name-$tag.exr"; }
run delta --method delta --set settings.probes=1 --time "$sec" --seed 71
run method --method guided --set 'settings.select="off"' --time "$sec" --seed 72
run delta_equiangular --method delta --set settings.equiangular=true --set settings.probes=1 --time "$sec" --seed 73
run guided_path --method guided-unbiased --set 'settings.select="off"' --set guide.equiangular=false --time "$sec" --seed 74
run beams --method guided --set march.ls=nee+beams --set photons.progressive=true --set 'settings.select="off"' \
    --time "$sec" --seed 75
# (the traces without shares: headroom.py reads every index from a line's from_sample to the
# next's as drawn by every pixel, which settings.adaptive's shares, `guided`'s default since
# session 70, do not)
run g --method guided --set settings.adaptive=false --spp 64 --seed 76 --select-trace "$out/$name-tr-g.jsonl"
run b --method guided --set march.ls=nee+beams --set photons.progressive=true --set 'settings.select="tiles"' \
    --set settings.adaptive=false --spp 64 --seed 77 --select-trace "$out/$name-tr-b.jsonl"
"${PYTHON:-/usr/bin/python3}" "$here/bench/headroom.py" "$out/$name" "$ref"
