#!/usr/bin/env bash
# same-images.sh: does a change leave every image as it was? Renders every scene in scenes/ by
# every method with a fixed seed and spp, small, and prints one line per render: the SHA-256 of
# the EXR (its pixels and header, less the capDate attribute that OpenImageIO stamps with the
# wall clock), of the standard-error EXR and of the PNG. Run it with the binary before and after
# a change and diff the two lists: any line that differs is an image that changed.
#
#   scripts/same-images.sh BIN OUTDIR > after.txt
#   diff before.txt after.txt && echo "images unchanged"
#
# Every bake is made afresh (--no-cache), so a photon map or guide that changed shows too.
# Scenes whose volume file is absent (the large grids of scripts/make-volumes.sh) are listed as
# "skipped: no FILE" rather than failing. Environment: SPP (default 4), RES (default 24,18),
# PHOTONS (default 20000, photons.count for the methods that bake), THREADS (default 2; the
# image does not depend on it, docs/render-core.md).
set -uo pipefail
BIN=${1:?usage: same-images.sh BIN OUTDIR}
OUT=${2:?usage: same-images.sh BIN OUTDIR}
SPP=${SPP:-4}
RES=${RES:-24,18}
PHOTONS=${PHOTONS:-20000}
THREADS=${THREADS:-2}
# BIN and OUT as given from the caller's folder, before the script moves to the project root.
case $BIN in /*) ;; */*) BIN="$PWD/$BIN" ;; esac
case $OUT in /*) ;; *) OUT="$PWD/$OUT" ;; esac
cd "$(dirname "$0")/.."
mkdir -p "$OUT"

# The EXR's hash without the wall-clock date (a fixed-length "YYYY:MM:DD HH:MM:SS" value).
exr_hash() {
    perl -0777 -pe 's/(capDate\x00string\x00.{4})\d{4}:\d\d:\d\d \d\d:\d\d:\d\d/${1}DATE/s' "$1" \
        | sha256sum | cut -c1-16
}

methods=$("$BIN" render --help | awk '/^methods:/ {on=1; next} on && NF {print $1}')
for scene in scenes/*.json; do
    name=$(basename "$scene" .json)
    missing=""
    for f in $(grep -o '"file" *: *"[^"]*"' "$scene" | sed 's/.*"\([^"]*\)"$/\1/'); do
        [ -e "scenes/$f" ] || [ -e "$f" ] || missing="$f"
    done
    for m in $methods; do
        if [ -n "$missing" ]; then echo "$name $m skipped: no $missing"; continue; fi
        o="$OUT/$name-$m.exr"
        if ! "$BIN" render "$scene" --method "$m" --spp "$SPP" --seed 11 --threads "$THREADS" \
                --no-cache -q --set "camera.resolution=[$RES]" --set "photons.count=$PHOTONS" \
                -o "$o" 2> "$OUT/$name-$m.err"; then
            echo "$name $m failed: $(head -c 200 "$OUT/$name-$m.err")"
            continue
        fi
        echo "$name $m $(exr_hash "$o") $(exr_hash "${o%.exr}-stderr.exr") $(sha256sum < "${o%.exr}.png" | cut -c1-16)"
    done
done
