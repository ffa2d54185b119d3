#!/usr/bin/env bash
# Make the gallery (docs/gallery.md): every scene in scenes/ rendered by `delta`, `guided` and
# `guided-unbiased` at equal time (the guided bakes charged), each measured against a longer
# `delta` reference, by `photonmarch compare` (docs/compare.md). For each scene it runs
#
#   photonmarch compare scenes/NAME.json --methods delta,guided,guided-unbiased --equal time
#       --budget B --runs 1 --ref-time R --ref-spp 1000000 --threads 2
#       --set camera.resolution=[W/D,H/D] -o out/gallery/NAME
#
# (W x H the scene's own resolution, divided by D = 2, or 4 when W/2 is over 160, so that every
# picture is at most 160 pixels wide and the budget buys more samples per pixel),
# recording its wall time and the load average (/proc/loadavg) at its start and its end, then
# copies the four pictures (delta, guided, guided-unbiased, reference; PNG) into
# docs/images/gallery/ and writes, between the markers <!-- gallery:begin --> and
# <!-- gallery:end --> of docs/gallery.md (the text around them is kept), a summary table (one
# row per scene: guided's and guided-unbiased's efficiency relative to delta, the winner,
# guided's bias share, the load) and below it each scene's pictures and table.
#
# Usage: scripts/make-gallery.sh [options] [NAME...]     (default: every scene in scenes/)
#   --budget B     seconds per run, the guided bakes included (default 10)
#   --ref-time R   seconds of the reference (default 60; delta's, or a photon render where delta
#                  cannot render the light: docs/compare.md, "Light only photons find")
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

B=10
R=60
METHODS=delta,guided,guided-unbiased
BIN=build/photonmarch
FORCE=0
TABLE_ONLY=0
OUT=out/gallery
IMG=docs/images/gallery
PAGE=docs/gallery.md
MAX_KB=150
# Scenes left out of the default run, with the reason (shown in the page).
declare -A SKIP=(
    [dense-512]="its 0.57 GB grid (scripts/make-volumes.sh) is noise-block.json voxelised at 512^3, made for the free-path benchmark; noise-block.json, the same medium, is in the gallery. Loading it alone (\`photonmarch info scenes/dense-512.json\`) took 305 s of wall time when the gallery was first made (load average about 11), more than a whole scene's run; the grid was not made again for this gallery"
    [plume-1024]="its 0.22 GB sparse grid (scripts/make-volumes.sh) loaded in 36 s when the gallery was first made, and a comparison of it did not fit that gallery's hour; the grid was not made again for this gallery, so that figure was not measured again"
)

# Scenes that get a longer budget than B, with the reason (shown in the page). The budget must
# buy each guided method its bake and one full pass over the image (compare refuses less).
# Measured for this gallery with `photonmarch render SCENE --method M --spp 1 --no-cache
# --threads 2 --set camera.resolution=[W/2,H/2]` under nice 19 (load average 4-7): on every
# scene without glass but one, bake and pass took 0.1-5.8 s, so the budgets that clouds-low,
# hetero-forward and plume-env-dense had when bakes took tens of seconds under a load of 11
# are gone. noise-block and the three scenes with glass need more. (A first attempt at 10 s,
# starved by other work at normal priority, also had cloud, clouds-high and hard-dense-block
# refused; with the machine to itself hard-dense-block's bakes take under 1.2 s, so they keep B
# until a quiet run shows otherwise.)
declare -A LONGER=(
    [noise-block]="20:guided's bake and one pass took 22.6 s (14.9 s of bake) when measured, while a benchmark ran beside it at normal priority; its bake was 11.7 s in the first gallery: the procedural noise is evaluated at every photon step"
    [exp1-point]="40:guided's bake and one pass at 320x240 took 17 s, guided-unbiased's 25 s, mostly the preparation before the bake (9.8 s and 23.4 s), which does not shrink with the image"
    [glass-fog]="60:guided's bake and one pass at 320x240 took 43.5 s (30 s of preparation, 13.4 s of bake); guided-unbiased's 3.0 s"
    [exp2-directional]="120:at 320x240 one pass of guided did not finish within 60 s after its 7.4-s bake, and guided-unbiased's bake alone took 45.6 s: the dense medium inside the glass knot (the budget is a guess for 160x120, a quarter of those pixels)"
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
IFS=, read -r -a WHO <<< "$METHODS"

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
    local name=$1 w h d=2
    w=$(jq '.camera.resolution[0]' "scenes/$name.json")
    h=$(jq '.camera.resolution[1]' "scenes/$name.json")
    while [ $((w / d)) -gt 160 ]; do d=$((d * 2)); done
    echo "$BIN compare scenes/$name.json --methods $METHODS --equal time --budget $(budget_of "$name")" \
         "--runs 1 --ref-time $R --ref-spp 1000000 --threads 2" \
         "--set camera.resolution=[$((w / d)),$((h / d))] -o $OUT/$name"
}

run_one() {
    local name=$1 cmd dir=$OUT/$1 t0 t1 l0 rc
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
    l0=$(cut -d' ' -f1-3 /proc/loadavg)
    rc=0
    # shellcheck disable=SC2086  # the command is one line of words without spaces inside
    nice -n 19 $cmd -q > "$dir/table.txt" 2> "$dir/stderr.txt" || rc=$?
    t1=$(date +%s)
    # wall seconds, then the load average (1, 5, 15 min) at the start and at the end
    echo "$((t1 - t0)) $l0 $(cut -d' ' -f1-3 /proc/loadavg)" > "$dir/wall.txt"
    if [ $rc = 0 ]; then
        echo "$cmd" > "$dir/command.txt"
        say "$name: done in $((t1 - t0)) s; report $dir/index.html"
    else
        rm -f "$dir/command.txt"
        say "$name: compare failed (exit $rc): $(tail -1 "$dir/stderr.txt")"
    fi
}

# A PNG of compare's into docs/images/gallery/, checked against MAX_KB (at these sizes, at most
# 160x128 pixels, a PNG is under 60 KB: 3 bytes a pixel before compression).
copy_png() {
    local src=$1 dst=$2
    cp "$src" "$dst"
    [ $(($(stat -c %s "$dst") / 1024)) -lt $MAX_KB ] || say "warning: $dst is over $MAX_KB KB"
}

num() { printf '%.3g' "$(jq -r "$1" "$2")"; }
# A method's time per sample (its bake left out) and variance per sample over delta's
# (compare's seconds_per_sample and variance_per_sample; docs/compare.md "Per sample").
per_sample() {
    local r
    r=$(jq -r --arg who "$1" '
        (.methods[] | select(.label == "delta")) as $b | (.methods[] | select(.label == $who)) as $x
        | if ($x.seconds_per_sample | type) == "number" and ($b.seconds_per_sample | type) == "number"
             and $b.seconds_per_sample > 0 and $b.variance_per_sample > 0
          then "\($x.seconds_per_sample / $b.seconds_per_sample) \($x.variance_per_sample / $b.variance_per_sample)"
          else "-" end' "$2")
    if [ -z "$r" ] || [ "$r" = - ]; then echo "–"; else awk -v t="${r% *}" -v v="${r#* }" 'BEGIN { printf "%.3gx, %.3gx", t, v }'; fi
}
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
    if [ ! -f "$m" ] || [ ! -f "$dir/command.txt" ]; then
        # note.txt: why a scene was left out, written by whoever stopped its run
        if [ -f "$dir/note.txt" ]; then
            echo "Not rendered: \`$(compare_cmd "$name")\`: $(cat "$dir/note.txt")"
        elif [ -s "$dir/stderr.txt" ]; then
            echo "Not rendered: \`$(compare_cmd "$name")\` failed: $(tail -1 "$dir/stderr.txt")"
        else
            echo "Not rendered: \`$(compare_cmd "$name")\` was not run."
        fi
        echo
        return
    fi
    local who w h dw
    for who in "${WHO[@]}" reference; do
        copy_png "$dir/$who.png" "$IMG/$name-$who.png"
    done
    w=$(jq .width "$m"); h=$(jq .height "$m")
    dw=$((w * 2))
    echo "| delta | guided | guided-unbiased | reference ($(jq -r '.reference.method // "delta"' "$m"), $(num .reference.seconds "$m") s, $(spp .reference.spp "$m") spp) |"
    echo "|---|---|---|---|"
    echo "|$(for who in "${WHO[@]}" reference; do
        printf ' <img src="images/gallery/%s-%s.png" width="%d" alt="%s: %s"> |' "$name" "$who" "$dw" "$name" "$who"
    done)"
    echo
    echo "| method | time (s, bake included) | bake (s) | spp | RMSE | bias² | variance | efficiency / delta's | bias share | per sample: time, variance / delta's |"
    echo "|---|---|---|---|---|---|---|---|---|---|"
    for who in "${WHO[@]}"; do
        local q=".methods[] | select(.label == \"$who\")"
        echo "| $who | $(num "$q.seconds" "$m") | $(num "$q.bake_seconds" "$m") | $(spp "$q.spp" "$m")" \
             "| $(num "$q.rmse" "$m") | $(num "$q.bias2" "$m") | $(num "$q.variance" "$m")" \
             "| $(jq -r "($q.efficiency_vs_baseline) // \"–\" | if type == \"number\" then (. * 100 | round / 100 | tostring) + \"x\" else . end" "$m")" \
             "| $(jq -r "($q.bias_share) // \"–\" | if type == \"number\" then (. * 100 | round | tostring) + \"%\" else . end" "$m")" \
             "| $(per_sample "$who" "$m") |"
    done
    echo
    echo "compare's verdict: $(jq -r '.summary.verdict // "none"' "$m")."
    echo
    [ -n "${LONGER[$name]:-}" ] && \
        echo "**Budget $(budget_of "$name") s, not $B s:** ${LONGER[$name]#*:}." && echo
    echo "${w}x$h pixels. Made by \`$(cat "$dir/command.txt")\` ($(cut -d' ' -f1 "$dir/wall.txt") s of wall time;" \
         "load average (1, 5, 15 min) $(cut -d' ' -f2-4 "$dir/wall.txt") at the start, $(cut -d' ' -f5-7 "$dir/wall.txt") at the end)."
    [ "$(jq .reference.too_noisy "$m")" = true ] && \
        echo "compare flags the reference as **too noisy to rank** the methods on this scene (its variance is $(jq -r '.reference.variance_share * 100 | round' "$m")% of the smallest MSE, over the limit of $(jq -r '.reference.variance_limit * 100 | round' "$m")%)."
    echo
}

# The summary row of one scene: guided's and guided-unbiased's efficiency over delta's (compare's
# efficiency_vs_baseline), the winner (compare's; none when the reference is too noisy to rank,
# then the highest efficiency is named), guided's bias share, the 1-min load average at the
# start and the end of the scene's run.
summary_row() {
    local name=$1 m=$OUT/$1/metrics.json label=$1 load
    if [ ! -f "$m" ] || [ ! -f "$OUT/$1/command.txt" ]; then echo "| [$name](#$name) | not rendered (below) | | | | |"; return; fi
    [ -n "${LONGER[$name]:-}" ] && label="$name (B = $(budget_of "$name") s)"
    load=$(awk '{ printf "%s → %s", $2, $5 }' "$OUT/$name/wall.txt")
    jq -r --arg lab "$label" --arg n "$name" --arg load "$load" '
        def m($l): .methods[] | select(.label == $l);
        def x: if type == "number" then (. * 100 | round / 100 | tostring) + "x" else "–" end;
        def pc: if type == "number" then (. * 100 | round | tostring) + "%" else "–" end;
        ([.methods[] | select(.efficiency != null)] | max_by(.efficiency) | .label) as $best
        | "| [\($lab)](#\($n)) | \(m("guided").efficiency_vs_baseline | x) | \(m("guided-unbiased").efficiency_vs_baseline | x)"
          + " | \(if .summary.winner then .summary.winner
                  elif .reference.too_noisy then "none: reference too noisy (highest: \($best))"
                  else "none (highest: \($best))" end)"
          + " | \(m("guided").bias_share | pc) | \($load) |"' "$m"
}

write_page() {
    local tmp name
    tmp=$(mktemp)
    mkdir -p "$IMG"
    [ -f "$PAGE" ] || printf '# Gallery\n\n<!-- gallery:begin -->\n<!-- gallery:end -->\n' > "$PAGE"
    {
        sed -n '1,/^<!-- gallery:begin -->$/p' "$PAGE"
        echo
        echo "Budget B = $B s of wall time per run (the guided bakes included) unless a scene says otherwise," \
             "one run per method (\`--runs 1\`), reference R = $R s of \`delta\`;" \
             "each scene at half its own resolution (a quarter for the 640x480 ones), as each section says;"
        echo "machine: $(nproc) cores ($(lscpu | sed -n 's/^Model name: *//p' | head -1)), $(free -g | awk '/^Mem:/ {print $2}') GB;"
        echo "load average (1, 5, 15 min) when the renders began: $(cat "$OUT/load-start.txt" 2>/dev/null || echo unknown)."
        echo
        echo "| scene | guided: efficiency / delta's | guided-unbiased: efficiency / delta's | winner | guided: bias share of its error | load (1 min) at start → end |"
        echo "|---|---|---|---|---|---|"
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
