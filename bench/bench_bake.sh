#!/usr/bin/env bash
# bench_bake.sh: issue 21 item 1's figure, "1e6 photons traced and indexed", measured as a user
# runs it: `photonmarch bake SCENE --stats` (trace the photon map, build its FLANN kd-tree, bake
# the SH guide, write the files), for one or more builds of photonmarch, interleaved (run k of
# every binary before run k+1 of any), so load from other users of the machine falls on all of
# them alike. Per binary it prints every run and then the median and min-max of:
#   trace      tracing seconds (bake --stats "tracing")
#   index      FLANN kd-tree build seconds ("index")
#   trace+idx  their sum: the issue's "traced and indexed"
#   guide      SH guide bake seconds ("guide")
#   wall       the whole command (scene load with its majorant build, files written)
#   cpu        user + system seconds of the whole command (steadier than wall on a loaded
#              machine; on an idle one wall is about cpu / threads)
# and, with two or more binaries, how much faster each one is than the first: the median over
# the runs of the ratio run k of the first / run k of this one (the two ran back to back, so
# under about the same load), for trace+idx, wall and cpu, with trace+idx's ratio of every run.
#
#   bench/bench_bake.sh BIN [BIN2 ...]    environment: RUNS (3), PHOTONS (1000000),
#                                         THREADS (2), SCENE (scenes/default.json),
#                                         OUT (a temporary folder, removed after)
set -euo pipefail
. "$(dirname "$0")/machine.sh"
bench_machine_note
[ $# -ge 1 ] || { echo "usage: bench/bench_bake.sh BIN [BIN2 ...]" >&2; exit 2; }
RUNS=${RUNS:-3}
PHOTONS=${PHOTONS:-1000000}
THREADS=${THREADS:-2}
SCENE=${SCENE:-scenes/default.json}
OUT=${OUT:-}
tmp=""
if [ -z "$OUT" ]; then tmp=$(mktemp -d); OUT=$tmp; fi
trap '[ -n "$tmp" ] && rm -rf "$tmp"' EXIT
mkdir -p "$OUT"
echo "scene $SCENE, photons.count=$PHOTONS, --threads $THREADS, $RUNS runs per binary, interleaved;" \
     "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"

# One run: prints "trace index guide wall cpu".
one_run() {
    local bin=$1 log=$2
    local TIMEFORMAT='%R %U %S' t
    t=$( { time "$bin" bake "$SCENE" --stats --threads "$THREADS" --set "photons.count=$PHOTONS" \
              -o "$OUT/bake" > "$log" 2>&1; } 2>&1 ) || { echo "bench_bake: $bin failed: $(head -c 300 "$log")" >&2; exit 1; }
    awk -v t="$t" '
        /^tracing / { tr = $2 }
        /^index /   { for (i = 1; i <= NF; i++) if ($i == "in") ix = $(i + 1) }
        /^guide / && /baked in/ { for (i = 1; i <= NF; i++) if ($i == "in") gd = $(i + 1) }
        END { split(t, w, " "); printf "%s %s %s %s %.3f\n", tr, ix, (gd == "" ? 0 : gd), w[1], w[2] + w[3] }' "$log"
}

declare -A rows
for r in $(seq 1 "$RUNS"); do
    for b in "$@"; do
        line=$(one_run "$b" "$OUT/log")
        rows[$b]+="$line"$'\n'
        echo "run $r  $b: trace $(cut -d' ' -f1 <<< "$line") s, index $(cut -d' ' -f2 <<< "$line") s," \
             "guide $(cut -d' ' -f3 <<< "$line") s, wall $(cut -d' ' -f4 <<< "$line") s, cpu $(cut -d' ' -f5 <<< "$line") s"
    done
done
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
echo
echo "| binary | trace s | index s | trace+idx s | guide s | wall s | cpu s |"
echo "|---|---|---|---|---|---|---|"
first=$1
for b in "$@"; do
    printf '%s' "${rows[$b]}" | awk -v name="$b" '
        function med(a, n,   i, j, t) { for (i = 2; i <= n; i++) { t = a[i]; for (j = i - 1; j >= 1 && a[j] > t; j--) a[j + 1] = a[j]; a[j + 1] = t }
                                          return n % 2 ? a[(n + 1) / 2] : (a[n / 2] + a[n / 2 + 1]) / 2 }
        function cell(a, n,   lo, hi, i) { lo = hi = a[1]; for (i = 2; i <= n; i++) { if (a[i] < lo) lo = a[i]; if (a[i] > hi) hi = a[i] }
                                           return sprintf("%.2f (%.2f-%.2f)", med(a, n), lo, hi) }
        NF == 5 { n++; tr[n] = $1; ix[n] = $2; ti[n] = $1 + $2; gd[n] = $3; wl[n] = $4; cp[n] = $5 }
        END { printf "| %s | %s | %s | %s | %s | %s | %s |\n", name, cell(tr, n), cell(ix, n), cell(ti, n), cell(gd, n), cell(wl, n), cell(cp, n) }'
done
if [ $# -ge 2 ]; then
    echo
    for b in "${@:2}"; do
        paste -d' ' <(printf '%s' "${rows[$first]}") <(printf '%s' "${rows[$b]}") | awk -v a="$first" -v b="$b" '
            function med(x, n,   i, j, t) { for (i = 2; i <= n; i++) { t = x[i]; for (j = i - 1; j >= 1 && x[j] > t; j--) x[j + 1] = x[j]; x[j + 1] = t }
                                              return n % 2 ? x[(n + 1) / 2] : (x[n / 2] + x[n / 2 + 1]) / 2 }
            NF == 10 { n++; rt[n] = ($1 + $2) / ($6 + $7); rw[n] = $4 / $9; rc[n] = $5 / $10
                       per = per sprintf("%s%.2f", n > 1 ? ", " : "", rt[n]) }
            END { printf "%s against %s: trace+idx %.2fx faster (median of the per-run ratios: %s), wall %.2fx, cpu %.2fx\n",
                         b, a, med(rt, n), per, med(rw, n), med(rc, n) }'
    done
fi
