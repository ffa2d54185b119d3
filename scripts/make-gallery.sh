#!/usr/bin/env bash
# Make the gallery (docs/gallery.md): every scene in scenes/ rendered by `delta` and by `guided`
# at equal time, each measured against a longer `delta` reference, by `photonmarch compare`
# (docs/compare.md). For each scene it runs
#
#   photonmarch compare scenes/NAME.json --methods delta,guided --equal time --budget B --runs 1
#       --ref-time R --ref-spp 1000000 --threads 2 --set camera.resolution=[W/2,H/2] -o out/gallery/NAME
#
# (W x H the scene's own resolution, halved so that the budget buys more samples per pixel),
# then copies the three pictures (delta, guided, reference; PNG) into docs/images/gallery/
# and writes the tables between the markers <!-- gallery:begin --> and <!-- gallery:end --> of
# docs/gallery.md (the text around them is kept).
#
# Usage: scripts/make-gallery.sh [options] [NAME...]     (default: every scene in scenes/)
#   --budget B     seconds per run, the guided bake included (default 40)
#   --ref-time R   seconds of the delta reference (default 150)
#   --bin PATH     the photonmarch binary (default build/photonmarch; built with make if stale)
#   --force        render again even when out/gallery/NAME holds this very comparison
#   --table-only   render nothing: rebuild the pictures and tables from out/gallery/
#
# A scene already compared with the same command (out/gallery/NAME/command.txt) is not rendered
# again; its reference is cached in out/.photonmarch-cache/ either way. Scenes in SKIP (below)
# are listed in the page with the command that would render them and the reason they are left
# out; a scene whose volume file is missing is left out with the script that makes it.
# Every command runs under `nice -n 19` (the machine is shared).
set -euo pipefail
cd "$(dirname "$0")/.."

B=40
R=150
BIN=build/photonmarch
FORCE=0
TABLE_ONLY=0
OUT=out/gallery
IMG=docs/images/gallery
PAGE=docs/gallery.md
MAX_KB=150
# Scenes left out of the default run, with the reason (shown in the page).
declare -A SKIP=(
    [dense-512]="its 0.57 GB grid (scripts/make-volumes.sh) is noise-block.json voxelised at 512^3, made for the free-path benchmark; noise-block.json, the same medium, is in the gallery. Loading it alone (\`photonmarch info scenes/dense-512.json\`) took 305 s of wall time on the gallery's machine, more than a whole scene's budget"
    [plume-1024]="its 0.22 GB sparse grid (scripts/make-volumes.sh) loads in 36 s here, but a comparison of it would have taken the gallery past its hour (the other scenes used it up)"
)

# Scenes that get a longer budget than B, with the reason (shown in the page). The budget must
# buy guided its bake and one full pass over the image (compare refuses less).
declare -A LONGER=(
    [clouds-low]="120:at 40 s guided could not finish one pass over the 128x96 image (its bake took 4.0 s; load average 11): compare refused the run"
    [hetero-forward]="150:at 40 s guided's bake alone took 64.7 s (142 s in a first attempt with another comparison running beside it; hetero-isotropic's, the same scene with g = 0, took 15.3 s): compare refused the run"
    [plume-env-dense]="120:at 40 s guided's bake alone took 36.6 s, leaving too little for one pass over the image: compare refused the run"
)

NAMES=()
while [ $# -gt 0 ]; do
    case $1 in
    --budget) B=$2; shift 2 ;;
    --ref-time) R=$2; shift 2 ;;
    --bin) BIN=$2; shift 2 ;;
    --force) FORCE=1; shift ;;
    --table-only) TABLE_ONLY=1; shift ;;
    -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d; s/^# \{0,1\}//'; exit 0 ;;
    -*) echo "make-gallery.sh: unknown option $1" >&2; exit 2 ;;
    *) NAMES+=("$1"); shift ;;
    esac
done
ALL=()
for f in scenes/*.json; do ALL+=("$(basename "$f" .json)"); done
[ ${#NAMES[@]} -eq 0 ] && NAMES=("${ALL[@]}")
command -v jq >/dev/null || { echo "make-gallery.sh: needs jq" >&2; exit 2; }

say() { echo "make-gallery: $*" >&2; }

build_if_stale() {
    if [ "$BIN" = build/photonmarch ] && ! make -q build/photonmarch 2>/dev/null; then
        say "building build/photonmarch (make -j2, niced)"
        nice -n 19 make -j2 build/photonmarch >&2
    fi
}

# The volume file a scene reads and that is missing, if any ("" when all are there).
missing_volume() {
    local scene=$1 f
    for f in $(jq -r '.. | objects | select(.type? == "vdb" or .type? == "raw") | .file' "$scene"); do
        [ -e "scenes/$f" ] || { echo "scenes/$f"; return; }
    done
}

# The budget of one scene: B, or its entry in LONGER.
budget_of() {
    local l=${LONGER[$1]:-}
    if [ -n "$l" ]; then echo "${l%%:*}"; else echo "$B"; fi
}

# The compare command for one scene, as one line (also what the page shows).
compare_cmd() {
    local name=$1 w h
    w=$(jq '.camera.resolution[0]' "scenes/$name.json")
    h=$(jq '.camera.resolution[1]' "scenes/$name.json")
    echo "$BIN compare scenes/$name.json --methods delta,guided --equal time --budget $(budget_of "$name")" \
         "--runs 1 --ref-time $R --ref-spp 1000000 --threads 2" \
         "--set camera.resolution=[$((w / 2)),$((h / 2))] -o $OUT/$name"
}

run_one() {
    local name=$1 cmd dir=$OUT/$1 t0 t1 rc
    cmd=$(compare_cmd "$name")
    if [ $FORCE = 0 ] && [ -f "$dir/metrics.json" ] && [ -f "$dir/command.txt" ] \
        && [ "$(cat "$dir/command.txt")" = "$cmd" ] \
        && [ "$(jq .cancelled "$dir/metrics.json")" = false ]; then
        say "$name: $dir already holds this comparison (--force to render it again)"
        return
    fi
    say "$name: $cmd"
    mkdir -p "$dir"
    t0=$(date +%s)
    rc=0
    # shellcheck disable=SC2086  # the command is one line of words without spaces inside
    nice -n 19 $cmd -q > "$dir/table.txt" 2> "$dir/stderr.txt" || rc=$?
    t1=$(date +%s)
    echo "$((t1 - t0)) $(cut -d' ' -f1-3 /proc/loadavg)" > "$dir/wall.txt"
    if [ $rc = 0 ]; then
        echo "$cmd" > "$dir/command.txt"
        say "$name: done in $((t1 - t0)) s; report $dir/index.html"
    else
        rm -f "$dir/command.txt"
        say "$name: compare failed (exit $rc): $(tail -1 "$dir/stderr.txt")"
    fi
}

# A PNG of compare's into docs/images/gallery/, checked against MAX_KB (at these sizes, at most
# 160x120 pixels, a PNG is under 60 KB: 3 bytes a pixel before compression).
copy_png() {
    local src=$1 dst=$2
    cp "$src" "$dst"
    [ $(($(stat -c %s "$dst") / 1024)) -lt $MAX_KB ] || say "warning: $dst is over $MAX_KB KB"
}

num() { printf '%.3g' "$(jq -r "$1" "$2")"; }
# samples per pixel: whole numbers from 100 on (1160, not 1.16e+03)
spp() { awk -v v="$(jq -r "$1" "$2")" 'BEGIN { printf (v >= 100 ? "%.0f" : "%.3g"), v }'; }

# One scene's section of the page.
section() {
    local name=$1 dir=$OUT/$1 m=$OUT/$1/metrics.json desc
    desc=$(jq -r '.description // ""' "scenes/$name.json")
    echo "### $name"
    echo
    echo "$desc"
    echo
    if [ ! -f "$m" ]; then
        echo "Not rendered: \`$(compare_cmd "$name")\` failed: $(tail -1 "$dir/stderr.txt" 2>/dev/null || echo 'not run')"
        echo
        return
    fi
    for who in delta guided reference; do
        copy_png "$dir/$who.png" "$IMG/$name-$who.png"
    done
    local w h
    w=$(jq .width "$m"); h=$(jq .height "$m")
    echo "| delta | guided | reference (delta, $(num .reference.seconds "$m") s, $(spp .reference.spp "$m") spp) |"
    echo "|---|---|---|"
    echo "| <img src=\"images/gallery/$name-delta.png\" width=\"$((w * 2))\" alt=\"$name: delta\"> |" \
         "<img src=\"images/gallery/$name-guided.png\" width=\"$((w * 2))\" alt=\"$name: guided\"> |" \
         "<img src=\"images/gallery/$name-reference.png\" width=\"$((w * 2))\" alt=\"$name: reference\"> |"
    echo
    echo "| method | time (s, bake included) | bake (s) | spp | RMSE | bias² | variance |"
    echo "|---|---|---|---|---|---|---|"
    for who in delta guided; do
        local q=".methods[] | select(.label == \"$who\")"
        echo "| $who | $(num "$q.seconds" "$m") | $(num "$q.bake_seconds" "$m") | $(spp "$q.spp" "$m")" \
             "| $(num "$q.rmse" "$m") | $(num "$q.bias2" "$m") | $(num "$q.variance" "$m") |"
    done
    echo
    [ -n "${LONGER[$name]:-}" ] && \
        echo "**Budget $(budget_of "$name") s, not $B s:** ${LONGER[$name]#*:}." && echo
    echo "${w}x$h pixels. Made by \`$(cat "$dir/command.txt")\` ($(cut -d' ' -f1 "$dir/wall.txt") s of wall time," \
         "load average $(cut -d' ' -f2-4 "$dir/wall.txt") at the end)."
    [ "$(jq .reference.too_noisy "$m")" = true ] && \
        echo "compare flags the reference as **too noisy to rank** the two methods on this scene (its variance is over a quarter of the smaller MSE)."
    echo
}

# The summary row of one scene: samples, RMSEs and their ratio, guided's bias share.
summary_row() {
    local name=$1 m=$OUT/$1/metrics.json label=$1
    [ -f "$m" ] || { echo "| [$name](#$name) | not rendered (below) | | | | | | |"; return; }
    [ -n "${LONGER[$name]:-}" ] && label="$name (B = $(budget_of "$name") s)"
    jq -r --arg lab "$label" --arg n "$name" '
        (.methods[] | select(.label == "delta")) as $d | (.methods[] | select(.label == "guided")) as $g
        | [$lab, $n, $d.spp, $g.spp, $g.bake_seconds, $d.rmse, $g.rmse, $g.bias2, $g.mse,
           (if .reference.too_noisy then "yes" else "no" end)] | @tsv' "$m" |
    awk -F'\t' '{
        r = $6 / $7
        printf "| [%s](#%s) | %.0f | %.3g (%.1f s) | %.3g | %.3g | %.2f (%s lower) | %.0f%% | %s |\n",
            $1, $2, $3, $4, $5, $6, $7, r, (r > 1 ? "guided" : "delta"), 100 * ($8 > 0 ? $8 : 0) / $9, $10 }'
}

write_page() {
    local tmp name
    tmp=$(mktemp)
    mkdir -p "$IMG"
    [ -f "$PAGE" ] || printf '# Gallery\n\n<!-- gallery:begin -->\n<!-- gallery:end -->\n' > "$PAGE"
    {
        sed -n '1,/^<!-- gallery:begin -->$/p' "$PAGE"
        echo
        echo "Budget B = $B s per run (the guided bake included), reference R = $R s of \`delta\`;"
        echo "machine: $(nproc) cores ($(lscpu | sed -n 's/^Model name: *//p' | head -1)), $(free -g | awk '/^Mem:/ {print $2}') GB;"
        echo "load average (1, 5, 15 min) when the renders began: $(cat "$OUT/load-start.txt" 2>/dev/null || echo unknown)."
        echo
        echo "| scene | delta spp | guided spp (its bake) | delta RMSE | guided RMSE | delta / guided RMSE | guided bias² / MSE | reference too noisy to rank |"
        echo "|---|---|---|---|---|---|---|---|"
        for name in "${ALL[@]}"; do
            [ -n "${SKIP[$name]:-}" ] && continue
            [ -n "$(missing_volume "scenes/$name.json")" ] && continue
            summary_row "$name"
        done
        echo
        for name in "${ALL[@]}"; do
            [ -n "${SKIP[$name]:-}" ] && continue
            [ -n "$(missing_volume "scenes/$name.json")" ] && continue
            section "$name"
        done
        echo "### Left out"
        echo
        for name in "${ALL[@]}"; do
            local miss
            miss=$(missing_volume "scenes/$name.json")
            if [ -n "${SKIP[$name]:-}" ]; then
                echo "- **$name**: ${SKIP[$name]}. To render it: \`scripts/make-volumes.sh build/photonmarch $name\`, then \`$(compare_cmd "$name")\`."
            elif [ -n "$miss" ]; then
                echo "- **$name**: $miss is missing (\`scripts/make-volumes.sh\` makes it). Then: \`$(compare_cmd "$name")\`."
            fi
        done
        echo
        sed -n '/^<!-- gallery:end -->$/,$p' "$PAGE"
    } > "$tmp"
    chmod 644 "$tmp"
    mv "$tmp" "$PAGE"
    say "wrote $PAGE and $IMG/ ($(du -sk "$IMG" | cut -f1) KB)"
}

if [ $TABLE_ONLY = 0 ]; then
    build_if_stale
    say "budget $B s per run, reference $R s; reports in $OUT/NAME/, pictures to $IMG/, page $PAGE"
    mkdir -p "$OUT"
    # the page's "when the renders began": recorded by a run over every scene
    [ ${#NAMES[@]} = ${#ALL[@]} ] && cut -d' ' -f1-3 /proc/loadavg > "$OUT/load-start.txt"
    say "load average at start: $(cut -d' ' -f1-3 /proc/loadavg)"
    for name in "${NAMES[@]}"; do
        if [ -n "${SKIP[$name]:-}" ]; then say "$name: left out (${SKIP[$name]%%:*})"; continue; fi
        miss=$(missing_volume "scenes/$name.json")
        if [ -n "$miss" ]; then say "$name: left out, $miss is missing (scripts/make-volumes.sh)"; continue; fi
        run_one "$name"
    done
fi
write_page
