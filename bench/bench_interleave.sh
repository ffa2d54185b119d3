#!/usr/bin/env bash
# bench_interleave.sh: two settings of one method at equal spp, their efficiency per sample
# (run by hand; docs/benchmarks.md "Session 22" quotes its figures). This machine's single-run
# times wander by 10-30%, so A and B are rendered alternately ROUNDS times and only the rounds'
# time ratios B/A are used (their median, min and max); the variance per sample comes from the
# render report and is the same every round (fixed seed). Efficiency B/A = (variance A /
# variance B) / median time ratio: the render alone, the bake not in it.
#
#   bench/bench_interleave.sh SCENE 'KEY=VALUE ... (A)' 'KEY=VALUE ... (B)' [BIN]
#       environment: METHOD (guided), SPP (8), ROUNDS (5), SEED (3), RES (160,120),
#                    THREADS (1), SELECT (off: the method alone; "" keeps the scene's)
#   e.g. bench/bench_interleave.sh hard-narrow-spot march.equiangular=false march.equiangular=auto
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/machine.sh
bench_machine_note
SCENE=${1:?usage: bench/bench_interleave.sh SCENE 'SETS A' 'SETS B' [BIN]}
A=${2?usage: bench/bench_interleave.sh SCENE 'SETS A' 'SETS B' [BIN]}
B=${3?usage: bench/bench_interleave.sh SCENE 'SETS A' 'SETS B' [BIN]}
BIN=${4:-build/photonmarch}
METHOD=${METHOD:-guided}
SPP=${SPP:-8}
ROUNDS=${ROUNDS:-5}
SEED=${SEED:-3}
RES=${RES:-160,120}
THREADS=${THREADS:-1}
SELECT=${SELECT-off}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# run SETS: one render; prints its render seconds and variance per sample
run() {
  local args=(--set "camera.resolution=[$RES]")
  [ -n "$SELECT" ] && args+=(--set "settings.select=$SELECT")
  for kv in $1; do args+=(--set "$kv"); done
  "$BIN" render "scenes/$SCENE.json" --method "$METHOD" --spp "$SPP" --threads "$THREADS" \
    --seed "$SEED" "${args[@]}" -o "$tmp/r.exr" > /dev/null 2> "$tmp/err" || {
    cat "$tmp/err" >&2
    exit 1
  }
  jq -r '"\(.render_seconds) \(.variance_per_sample)"' "$tmp/r.json"
}

ta=() tb=()
for _ in $(seq "$ROUNDS"); do
  read -r t1 va < <(run "$A")
  read -r t2 vb < <(run "$B")
  ta+=("$t1") tb+=("$t2")
done
python3 - "$SCENE" "$va" "$vb" "${ta[*]}" "${tb[*]}" <<'PY'
import statistics, sys
scene, va, vb = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
ta = [float(x) for x in sys.argv[4].split()]
tb = [float(x) for x in sys.argv[5].split()]
r = [b / a for a, b in zip(ta, tb)]  # each round's B over its own A
m = statistics.median(r)
print(f"{scene}: time A {statistics.median(ta):.3f} s, B {statistics.median(tb):.3f} s; "
      f"B/A: time {m:.3f} ({min(r):.3f}-{max(r):.3f}), variance per sample {vb / va:.3f}, "
      f"efficiency {(va / vb) / m:.3f}")
PY
