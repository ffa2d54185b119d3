#!/usr/bin/env bash
# bench_ranks.sh: render throughput on MPI ranks against threads (issue 23; docs/cluster.md).
# One scene rendered to a fixed sample count three ways, REPS times each, interleaved so that a
# drift in the machine's load falls on all three alike: one process with one thread (1x1), two
# ranks with one thread each under mpirun (2x1), one process with two threads (1x2). Prints the
# render's own seconds (its report's "seconds": passes, film gather included; mpirun's start-up
# not) and the wall time of the whole command, each run and the medians, and checks that the
# ranks' image equals one process's byte for byte (the EXR headers differ in their date).
#   SCENE (scenes/default.json) METHOD (delta) SPP (96) RES (160,120) REPS (3) BIN (build/photonmarch)
set -euo pipefail
cd "$(dirname "$0")/.."
source bench/machine.sh
SCENE=${SCENE:-scenes/default.json} METHOD=${METHOD:-delta} SPP=${SPP:-96} RES=${RES:-160,120}
REPS=${REPS:-3} BIN=${BIN:-build/photonmarch}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
MPIRUN=(mpirun -n 2 --oversubscribe --bind-to none --mca btl_vader_single_copy_mechanism none)
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
bench_machine_note
echo "bench_ranks: $SCENE, $METHOD, $SPP spp, $RES, $REPS reps, commit $(git rev-parse --short HEAD 2>/dev/null || echo ?)"
declare -A render wall
for rep in $(seq "$REPS"); do
  for cfg in 1x1 2x1 1x2; do
    case $cfg in
      1x1) cmd=("$BIN") th=1 ;;
      2x1) cmd=("${MPIRUN[@]}" "$BIN") th=1 ;;
      1x2) cmd=("$BIN") th=2 ;;
    esac
    s=$(date +%s.%N)
    "${cmd[@]}" render "$SCENE" --method "$METHOD" --spp "$SPP" --threads "$th" --seed 1 \
      --set "camera.resolution=[$RES]" -q -o "$out/$cfg.exr"
    e=$(date +%s.%N)
    r=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['seconds'])" "$out/$cfg.json")
    w=$(python3 -c "import sys; print(float(sys.argv[2]) - float(sys.argv[1]))" "$s" "$e")
    render[$cfg]+="$r " wall[$cfg]+="$w "
    printf '%s %s render %.3f s wall %.3f s\n' "$rep" "$cfg" "$r" "$w"
  done
done
python3 - "$out/1x1.exr" "$out/2x1.exr" <<'PY'
import re, sys
# The files as bytes with the header's capture date (capDate, "YYYY:MM:DD hh:mm:ss") blanked:
# every other byte, the pixels' included, must agree.
a, b = (re.sub(rb"\d{4}:\d\d:\d\d \d\d:\d\d:\d\d", b"#" * 19, open(p, "rb").read(), count=1) for p in sys.argv[1:3])
print("bench_ranks: 2x1 image", "equals" if a == b else "DIFFERS FROM", "1x1's byte for byte (the capture date aside)")
PY
median() { tr ' ' '\n' <<<"$1" | grep . | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
spread() { tr ' ' '\n' <<<"$1" | grep . | sort -g | awk 'NR==1{lo=$1} {hi=$1} END {printf "%.3f-%.3f", lo, hi}'; }
r11=$(median "${render[1x1]}") r21=$(median "${render[2x1]}") r12=$(median "${render[1x2]}")
w11=$(median "${wall[1x1]}") w21=$(median "${wall[2x1]}") w12=$(median "${wall[1x2]}")
printf 'median render s: 1x1 %.3f (%s), 2x1 %.3f (%s), 1x2 %.3f (%s)\n' "$r11" "$(spread "${render[1x1]}")" \
  "$r21" "$(spread "${render[2x1]}")" "$r12" "$(spread "${render[1x2]}")"
printf 'median wall s:   1x1 %.3f, 2x1 %.3f, 1x2 %.3f\n' "$w11" "$w21" "$w12"
python3 -c "import sys; a,b,c,d,e,f=map(float,sys.argv[1:]); print('throughput, render: 2x1 / 1x1 = %.2fx, 2x1 / 1x2 = %.2fx; wall: %.2fx, %.2fx' % (a/b, c/b, d/e, f/e))" \
  "$r11" "$r21" "$r12" "$w11" "$w21" "$w12"
