#!/usr/bin/env bash
# make demo: render the default scene with the unbiased reference, bake its photon map and
# guide grid, compare guided with delta at equal time, then say where everything is.
set -euo pipefail
BIN=${1:-build/photonmarch}
SCENE=scenes/default.json
mkdir -p out
echo "photonmarch demo: rendering $SCENE with the unbiased reference (delta tracking)..." >&2
start=$(date +%s)
"$BIN" render "$SCENE" -o out/default.exr -q
"$BIN" bake "$SCENE" -o out/default -q
# At 160x120: one guided pass (a sample per pixel) over the full 320x240 image took about 25 s
# on a busy 2-core machine, and its ~5 s bake is charged to each run; at a quarter of the
# pixels a 30 s budget gives it a few passes.
echo "photonmarch demo: comparing guided and delta at equal time (160x120, 2 runs of 30 s each," >&2
echo "  against a 1024-spp delta reference, rendered once and cached in out/.photonmarch-cache/)..." >&2
"$BIN" compare "$SCENE" --methods guided,delta --budget 30 --runs 2 --ref-spp 1024 \
    --set 'camera.resolution=[160,120]' -o out/compare
end=$(date +%s)
cat <<MSG
done in $((end - start)) s
image   out/default.exr (linear, float)  and  out/default.png (sRGB preview)
noise   out/default-stderr.exr (per-pixel standard error of the image)
report  out/default.json (method, samples, time, collisions and lookups per path, noise)
photons out/default.pmap, picture of where the light went: out/default-photons.png
guide   out/default.guide, a slice of it: out/default-slice-z.png
compare out/compare/index.html (open it in a browser: guided vs delta, error maps, metrics, plot)
MSG
