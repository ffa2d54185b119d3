#!/usr/bin/env bash
# bench_speed.sh: what a change that should leave every image as it was does to the time per
# camera sample (run by hand; docs/benchmarks.md). Two builds, A (before) and B (after), render
# each scene with each method at a fixed sample count on one thread, interleaved A, B, A, B, ...
# ROUNDS times, with a fresh bake each time (--no-cache). It prints, per scene and method, the
# median render seconds of each build with their min-max, B's median over A's, the same for the
# bake, and whether B's image equals A's to the bit (scripts/same-images.sh's hash: the EXR less
# its capDate stamp). Where the images are equal, the variance per sample is equal too, so B's
# efficiency over A's is exactly A's time per sample over B's.
#
#   bench/bench_speed.sh BIN_A BIN_B
#       environment: SCENES (the benchmark's eight), METHODS ("delta guided guided-unbiased"),
#                    SPP (32), RES ([160,120]), ROUNDS (3), OUT (bench/results/speed)
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/machine.sh
bench_machine_note
A=${1:?usage: bench/bench_speed.sh BIN_A BIN_B}
B=${2:?usage: bench/bench_speed.sh BIN_A BIN_B}
SCENES=${SCENES:-$BENCH_EIGHT}
METHODS=${METHODS:-delta guided guided-unbiased}
SPP=${SPP:-32}
RES=${RES:-[160,120]}
ROUNDS=${ROUNDS:-3}
OUT=${OUT:-bench/results/speed}
mkdir -p "$OUT"
log=$OUT/runs.txt
: > "$log"

exr_hash() { # the EXR less its wall-clock date, as scripts/same-images.sh hashes it
  perl -0777 -pe 's/(capDate\x00string\x00.{4})\d{4}:\d\d:\d\d \d\d:\d\d:\d\d/${1}DATE/s' "$1" \
    | sha256sum | cut -c1-16
}

for r in $(seq "$ROUNDS"); do
  for name in $SCENES; do
    for m in $METHODS; do
      for tag in A B; do
        bin=$A; [ $tag = B ] && bin=$B
        o=$OUT/$name-$m-$tag.exr
        "$bin" render "scenes/$name.json" --method "$m" --spp "$SPP" --threads 1 --no-cache \
          --set camera.resolution="$RES" -o "$o" > /dev/null 2>&1
        echo "$name $m $tag $(jq -r '"\(.render_seconds) \(.bake_seconds)"' "${o%.exr}.json") $(exr_hash "$o")" >> "$log"
      done
    done
  done
done

python3 - "$log" <<'EOF'
import collections, statistics, sys
runs = collections.defaultdict(list)
hashes = collections.defaultdict(set)
for line in open(sys.argv[1]):
    name, m, tag, t, bake, h = line.split()
    runs[(name, m, tag)].append((float(t), float(bake)))
    hashes[(name, m, tag)].add(h)
def fmt(v):
    return '%.3f (%.3f-%.3f)' % (statistics.median(v), min(v), max(v))
print('| scene | method | A render s | B render s | B / A | bake B / A | same image |')
print('|---|---|---|---|---|---|---|')
for (name, m, tag) in sorted(k for k in runs if k[2] == 'A'):
    a, b = runs[(name, m, 'A')], runs[(name, m, 'B')]
    ta, tb = [x[0] for x in a], [x[0] for x in b]
    ba, bb = [x[1] for x in a], [x[1] for x in b]
    same = hashes[(name, m, 'A')] == hashes[(name, m, 'B')] and len(hashes[(name, m, 'A')]) == 1
    bake = '%.2f' % (statistics.median(bb) / statistics.median(ba)) if statistics.median(ba) > 1e-3 else '-'
    print('| %s | %s | %s | %s | %.2f | %s | %s |' % (name, m, fmt(ta), fmt(tb),
          statistics.median(tb) / statistics.median(ta), bake, 'yes' if same else 'NO'))
EOF
