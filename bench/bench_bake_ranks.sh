#!/usr/bin/env bash
# bench_bake_ranks.sh: the bake on MPI ranks against one process (issue 23; docs/cluster.md,
# docs/benchmarks.md "Ranks"). One scene baked with PHOTONS photons two ways, REPS times each,
# interleaved: one process with one thread (1x1) and two ranks with one thread each under mpirun
# (2x1). From `bake --stats`: the tracing's seconds (on ranks: the rank's own range, the wait for
# the slower rank and the gather), the gather's seconds and the bytes each rank received (the
# "gather" line), the kd-tree's and the guide's seconds (every rank does them whole), and the
# command's wall time. Checks that the ranks' .pmap equals one process's byte for byte.
#   SCENE (scenes/default.json) PHOTONS (1000000) REPS (3) BIN (build/photonmarch)
set -euo pipefail
cd "$(dirname "$0")/.."
source bench/machine.sh
SCENE=${SCENE:-scenes/default.json} PHOTONS=${PHOTONS:-1000000} REPS=${REPS:-3} BIN=${BIN:-build/photonmarch}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
MPIRUN=(mpirun -n 2 --oversubscribe --bind-to none --mca btl_vader_single_copy_mechanism none)
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
bench_machine_note
echo "bench_bake_ranks: $SCENE, $PHOTONS photons, $REPS reps, commit $(git rev-parse --short HEAD 2>/dev/null || echo ?)"
for rep in $(seq "$REPS"); do
  for cfg in 1x1 2x1; do
    case $cfg in
      1x1) cmd=("$BIN") ;;
      2x1) cmd=("${MPIRUN[@]}" "$BIN") ;;
    esac
    s=$(date +%s.%N)
    "${cmd[@]}" bake "$SCENE" --photons "$PHOTONS" --seed 1 --threads 1 --stats -q -o "$out/$cfg" >"$out/$cfg.txt"
    e=$(date +%s.%N)
    python3 - "$rep" "$cfg" "$s" "$e" "$out/$cfg.txt" <<'PY'
import re, sys
rep, cfg, s, e, path = sys.argv[1:]
t = open(path).read()
num = lambda pat: (re.search(pat, t) or [None, "nan"])[1]
trace, index, guide = num(r"tracing\s+([\d.]+) s"), num(r"kd-tree built in ([\d.]+) s"), num(r"baked in ([\d.]+) s")
gs, gmib, gbpp = num(r"([\d.]+) s to gather"), num(r"([\d.]+) MiB received"), num(r"\(([\d.]+) bytes per photon emitted")
stored = num(r"stored (\d+)")
print(f"{rep} {cfg} trace {trace} s gather {gs} s {gmib} MiB ({gbpp} B/photon emitted) index {index} s "
      f"guide {guide} s wall {float(e) - float(s):.3f} s stored {stored}")
PY
  done
done
cmp -s "$out/1x1.pmap" "$out/2x1.pmap" && echo "bench_bake_ranks: 2x1 .pmap equals 1x1's byte for byte" \
  || echo "bench_bake_ranks: 2x1 .pmap DIFFERS FROM 1x1's"
