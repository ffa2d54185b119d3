#!/usr/bin/env bash
# Make the pictures of docs/how-it-works.md from the real code and data, for scenes/default.json:
#   docs/images/how/photons.png      the stored photons (tools/pm-inspect photons), top and front
#   docs/images/how/guide-slice.png  the SH guide grid on the plane z = 0 (pm-inspect slice):
#                                    its DC term and its value toward the camera
#   docs/images/how/pdf-bright.png,  photonmarch explain's own plots of two camera rays: the
#   docs/images/how/pdf-dim.png      placements' PDFs against the ideal f/I, and their samples
#   docs/images/how/samples.png      where those samples fall in the scene, over the guide
# It runs `photonmarch explain` once (two pixels, one bake: the photon map and guide that
# `render --method guided` would use, cached in out/how/.photonmarch-cache/), dumps the bake
# with build/tools/pm-inspect, and draws with gnuplot. Work files go to out/how/.
# Usage: scripts/make-how-it-works.sh [--force]   (--force: run explain again)
# Every command runs under `nice -n 19` (the machine is shared).
set -euo pipefail
cd "$(dirname "$0")/.."

SCENE=scenes/default.json
BRIGHT=215,105  # a ray through the blue spot's lobe, where the guide concentrates its samples
DIM=110,100     # a ray through the faint warm lobe, where it does not help
EYE=0,0.4,4.6   # the scene's camera position (camera.position)
SLICE_Y=0.18    # the height of the bright ray in the middle of the smoke (0.4 - 0.047 t, t ~ 4.6)
OUT=out/how
IMG=docs/images/how
BIN=build/photonmarch
TOOL=build/tools/pm-inspect
MAX_KB=200
FORCE=0
[ "${1:-}" = --force ] && FORCE=1

say() { echo "make-how-it-works: $*" >&2; }
for t in gnuplot jq; do command -v $t >/dev/null || { say "needs $t"; exit 2; }; done
mkdir -p "$OUT" "$IMG"

for target in $BIN $TOOL; do
    if ! make -q "$target" 2>/dev/null; then
        say "building $target (make -j2, niced)"
        nice -n 19 make -j2 "$target" >&2
    fi
done

bx=${BRIGHT%,*}; by=${BRIGHT#*,}; dx=${DIM%,*}; dy=${DIM#*,}
EXPLAIN_CMD="$BIN explain $SCENE --pixel $BRIGHT --pixel $DIM --threads 2 -o $OUT/explain"
if [ $FORCE = 1 ] || [ ! -f "$OUT/explain-$bx-$by.json" ] || [ ! -f "$OUT/explain-$dx-$dy.json" ]; then
    say "$EXPLAIN_CMD"
    # shellcheck disable=SC2086  # one line of words without spaces inside
    nice -n 19 $EXPLAIN_CMD -q >&2
else
    say "$OUT/explain-$bx-$by.* and -$dx-$dy.* are there (--force to run explain again)"
fi
# The bake explain used: the newest cache entry (the photon map, not the indirect one).
# shellcheck disable=SC2012  # the cache names are hex digits
GUIDE=$(ls -t "$OUT"/.photonmarch-cache/*.guide | head -1)
PMAP=${GUIDE%.guide}.pmap
say "bake: $PMAP, $GUIDE"

# (a) photons: every 10th, as CSV (x,y,z,dx,dy,dz,r,g,b)
say "$TOOL photons $PMAP --every 10 > $OUT/photons.csv"
nice -n 19 $TOOL photons "$PMAP" --every 10 > "$OUT/photons.csv"
NPH=$($TOOL info "$PMAP" | sed -n 's/^photons //p')
# (b) guide slices on z = 0 (through both spots' aim points), 280 x 200 pixels
say "$TOOL slice $GUIDE --axis z --at 0 --res 280,200 --dc | --eye $EYE > $OUT/slice-*.csv"
nice -n 19 $TOOL slice "$GUIDE" --axis z --at 0 --res 280,200 --dc > "$OUT/slice-dc.csv"
nice -n 19 $TOOL slice "$GUIDE" --axis z --at 0 --res 280,200 --eye $EYE > "$OUT/slice-eye.csv"
# A check of what the DC term means: summed over every cell (one raster pixel per cell, one
# slice per cell layer) times the cell volume it should give about the stored photon power
# (mean over R, G, B), up to the k-NN estimate's blur at the edges of the lit region.
read -r nx ny nz < <($TOOL info "$GUIDE" | sed -n 's/^res //p')
read -r lx ly lz < <($TOOL info "$GUIDE" | sed -n 's/^lo //p')
read -r hx hy hz < <($TOOL info "$GUIDE" | sed -n 's/^hi //p')
dc_sum=$(for k in $(seq 0 $((nz - 1))); do
    z=$(awk -v k="$k" -v lo="$lz" -v hi="$hz" -v n="$nz" 'BEGIN { print lo + (k + 0.5) * (hi - lo) / n }')
    $TOOL slice "$GUIDE" --axis z --at "$z" --res "$nx,$ny" --dc
done | awk -F, 'NF == 3 && $1 + 0 == $1 { s += $3 } END { printf "%.6g", s }')
awk -v s="$dc_sum" -v v="$(awk -v a="$lx" -v b="$hx" -v c="$ly" -v d="$hy" -v e="$lz" -v f="$hz" \
        -v nx="$nx" -v ny="$ny" -v nz="$nz" 'BEGIN { print (b-a)*(d-c)*(f-e)/(nx*ny*nz) }')" \
    -v p="$($TOOL photons "$PMAP" | awk -F, 'NR > 2 { s += ($7 + $8 + $9) / 3 } END { printf "%.6g", s }')" \
    'BEGIN { printf "make-how-it-works: check: DC term x cell volume over the grid %.4g W; the power of the stored photons %.4g W\n", s * v, p }' >&2
# (d) the top view at the bright ray's height, toward the camera
say "$TOOL slice $GUIDE --axis y --at $SLICE_Y --res 280,200 --eye $EYE > $OUT/slice-top.csv"
nice -n 19 $TOOL slice "$GUIDE" --axis y --at $SLICE_Y --res 280,200 --eye $EYE > "$OUT/slice-top.csv"
# the samples of the bright ray as world points: x = o + t d, one file per placement
J=$OUT/explain-$bx-$by.json
for p in guided transmittance uniform; do
    jq -r --arg p "$p" '.origin as $o | .direction as $d | .placements[$p].positions[]
        | [$o[0] + . * $d[0], $o[2] + . * $d[2], .] | @csv' "$J" > "$OUT/samples-$p.csv"
done
read -r t0 t1 < <(jq -r '"\(.t0) \(.t1)"' "$J")
read -r ox oz ddx ddz < <(jq -r '"\(.origin[0]) \(.origin[2]) \(.direction[0]) \(.direction[2])"' "$J")

say "drawing $IMG/photons.png, guide-slice.png, samples.png (gnuplot)"
nice -n 19 gnuplot <<GP
set datafile separator ','
set terminal png size 1000,440 font ',10' noenhanced
set output '$IMG/photons.png'
set multiplot layout 1,2 title 'scenes/default.json: stored photons (every 10th of $NPH), colour = their RGB power, normalised'
set size ratio -1
set key off
# colour: the photon's RGB power divided by its largest channel, on a black background
# (gnuplot's libgd png terminal: a 256-colour palette keeps the scatter under MAX_KB; pngcairo's
# antialiased true colour made it 260 KB)
rgb(r,g,b) = (int(255*r/mx(r,g,b)) << 16) + (int(255*g/mx(r,g,b)) << 8) + int(255*b/mx(r,g,b))
mx(r,g,b) = (r > g ? (r > b ? r : b) : (g > b ? g : b))
set title 'top view (x, z); camera at z = 4.6, looking along -z'
set xlabel 'x [m]'; set ylabel 'z [m]'
set xrange [-1.5:1.5]; set yrange [1.1:-1.1]
set object 1 rect from -1.4,-1 to 1.4,1 fs empty border rgb '#888888'
set object 2 rect from graph 0,0 to graph 1,1 behind fc rgb '#000000' fs solid
plot '$OUT/photons.csv' using 1:3:(rgb(\$7,\$8,\$9)) skip 2 with points pt 7 ps 0.12 lc rgb variable
set title 'front view (x, y), as the camera sees it'
set xlabel 'x [m]'; set ylabel 'y [m]'
set yrange [-1.1:1.1]
plot '$OUT/photons.csv' using 1:2:(rgb(\$7,\$8,\$9)) skip 2 with points pt 7 ps 0.12 lc rgb variable
unset multiplot

set terminal pngcairo size 1000,400 font ',10' noenhanced
set output '$IMG/guide-slice.png'
set multiplot layout 1,2 title 'the SH guide grid of scenes/default.json on the plane z = 0 (22x16x16 cells, 8 bands)'
unset object 1
unset object 2
set size ratio -1
set palette defined (0 '#000004', 1 '#3b0f70', 2 '#8c2981', 3 '#de4968', 4 '#fe9f6d', 5 '#fcfdbf')
set xrange [-1.4:1.4]; set yrange [-1:1]
set xlabel 'x [m]'; set ylabel 'y [m]'
set title 'DC term: sqrt(4 pi) c_00 = sigma_s x fluence [W/m^3]'
plot '$OUT/slice-dc.csv' using 1:2:3 skip 2 with image
set title 'guide value toward the camera: max(0, sum c_lm Y_lm(w)) [W/m^3/sr]'
plot '$OUT/slice-eye.csv' using 1:2:3 skip 2 with image
unset multiplot

set terminal pngcairo size 760,560 font ',10' noenhanced
set output '$IMG/samples.png'
set title "the samples of pixel ($BRIGHT) from above (plane y = $SLICE_Y), over the guide value toward the camera;\nplacements drawn 0.06 m apart beside the ray (true positions on the ray: x = o + t d)"
set size ratio -1
set xrange [-1.4:1.4]; set yrange [1:-1]
set xlabel 'x [m]'; set ylabel 'z [m]'
set key outside bottom center horizontal
set cblabel 'W/m^3/sr'
plot '$OUT/slice-top.csv' using 1:2:3 skip 2 with image notitle, \
     '+' using ($ox + $ddx*($t0 + (\$0/99.0)*($t1-$t0))):($oz + $ddz*($t0 + (\$0/99.0)*($t1-$t0))) \
         every ::0::99 with lines lc rgb '#aaaaaa' dt 2 lw 1.5 title 'camera ray', \
     '$OUT/samples-guided.csv' using (\$1-0.06):2 with points pt 2 ps 0.8 lc rgb '#ff4040' title 'guided', \
     '$OUT/samples-transmittance.csv' using 1:2 with points pt 6 ps 1 lc rgb '#40a0ff' title 'transmittance', \
     '$OUT/samples-uniform.csv' using (\$1+0.06):2 with points pt 4 ps 1 lc rgb '#40e040' title 'uniform'
GP

for p in $BRIGHT:bright $DIM:dim; do
    px=${p%:*}; name=${p#*:}
    cp "$OUT/explain-${px%,*}-${px#*,}.png" "$IMG/pdf-$name.png"
done
for f in "$IMG"/*.png; do
    kb=$(( $(stat -c %s "$f") / 1024 ))
    [ $kb -le $MAX_KB ] || say "warning: $f is $kb KB, over $MAX_KB KB"
    say "wrote $f ($kb KB)"
done
