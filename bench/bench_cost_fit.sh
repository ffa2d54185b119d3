#!/usr/bin/env bash
# bench_cost_fit.sh: the tile selection's cost weights (renderer/integrators/select.c, the head),
# fitted again on this build (run by hand after a change to what a sample costs;
# docs/guided-marching.md "Where marching pays", docs/benchmarks.md).
#
# The selection counts a camera sample's cost as work, in units of one density lookup:
#     C = lookups + w_S shadow rays + w_M marcher PDF segments + w_F flight segments
#         + w_V guided vertices + w_0,
# so that the same seed gives the same choices on any machine. The weights come from a
# least-squares fit of time per camera sample on the calibration scenes, which are not in the
# benchmark's tables: each scene rendered by delta, guided and guided-unbiased with select off
# (every sample of the method), one thread, ROUNDS interleaved rounds, the median time. Each
# render gives one equation,
#     t / samples = a_L lookups + a_S shadow rays + a_M marcher segments + a_F flight segments
#                   + a_V guided vertices + a_0         (all per camera sample, a in us),
# fitted for relative error (each row divided by its t). The weights are the a over a_L.
# It prints the fit, the weights, and each render's measured and modelled time.
#
# FIT=beams fits the weight of march.ls nee+beams' balls instead, the others held at
# select.c's: guided with nee+beams (one fixed photon map, select off) on the same scenes,
#     t / samples - (held terms) = a_H balls crossed    (per camera sample),
# the held terms in us by select.c's weights times the lookup's 0.164 us.
# FIT=gu fits guided-unbiased's two weights (flight segment, guided vertex) the same way, the
# lookup, shadow ray, equiangular set-up and camera sample held: guided-unbiased alone, select off,
#     t / samples - (held terms) = a_F flight segments + a_V guided vertices.
# FIT=eq fits the weight of a flight's equiangular set-up (the choice of lights of "auto",
# rd_track_counters.eq_flights): delta with settings.equiangular "auto" and "false" on the same
# scenes, paired (the scenes with no point or spot light set nothing up and drop out),
#     (t_auto - t_off) / samples - (held terms of the difference) = a_E set-ups.
#
#   bench/bench_cost_fit.sh [BIN]
#       environment: SCENES (the six below), SPP (16), RES ([160,120]), ROUNDS (3),
#                    FIT (all, beams, gu or eq), OUT (bench/results/cost_fit, cost_fit_beams,
#                    cost_fit_gu, cost_fit_eq)
set -euo pipefail
cd "$(dirname "$0")/.."
. bench/machine.sh
bench_machine_note
BIN=${1:-build/photonmarch}
# glass-fog (session 21): its spot lights the fog by way of glass, so the marchers' march.ls
# defaults to nee+beams with progressive passes there (docs/scene-format.md) and `compare`
# renders a photon reference unless one is given; to measure nee+paths there as before, name
# it in the variant (march.ls=nee+paths) or leave glass-fog out of SCENES.
SCENES=${SCENES:-cloud smoke-vdb glass-fog sphere-in-fog hetero-forward noise-block}
SPP=${SPP:-16}
RES=${RES:-[160,120]}
ROUNDS=${ROUNDS:-3}
FIT=${FIT:-all}
case $FIT in
  beams) OUT=${OUT:-bench/results/cost_fit_beams} ;;
  gu) OUT=${OUT:-bench/results/cost_fit_gu} ;;
  eq) OUT=${OUT:-bench/results/cost_fit_eq} ;;
  *) OUT=${OUT:-bench/results/cost_fit} ;;
esac
mkdir -p "$OUT"
log=$OUT/runs.txt
: > "$log"
if [ "$FIT" = beams ]; then
  methods=guided
  extra=(--set march.ls='"nee+beams"' --set photons.progressive=false)
elif [ "$FIT" = gu ]; then
  methods=guided-unbiased
  extra=()
elif [ "$FIT" = eq ]; then
  methods="delta-auto delta-off"
  extra=()
else
  methods="delta guided guided-unbiased"
  extra=()
fi
for r in $(seq "$ROUNDS"); do
  for name in $SCENES; do
    for m in $methods; do
      o=$OUT/$name-$m.exr
      # FIT=eq's two variants are delta with settings.equiangular auto and off
      meth=$m variant=()
      case $m in
        delta-auto) meth=delta variant=(--set settings.equiangular='"auto"') ;;
        delta-off) meth=delta variant=(--set settings.equiangular=false) ;;
      esac
      "$BIN" render "scenes/$name.json" --method "$meth" --spp "$SPP" --threads 1 \
        --set settings.select='"off"' --set camera.resolution="$RES" "${extra[@]}" "${variant[@]}" -o "$o" > /dev/null 2>&1
      jq -c --arg s "$name" --arg m "$m" '{scene: $s, method: $m, t: .render_seconds, n: .paths,
          L: .density_lookups, S: .shadow_rays, E: (.equiangular_flights // 0),
          M: ((.march.rays // 0) * (.march.pdf_segments_per_ray // 0)),
          F: ((.guided_paths.flight_segments_per_path // 0) * .paths),
          V: ((.guided_paths.guide_vertices_per_path // 0) * .paths),
          Q: (.march.beam_queries // 0),
          H: ((.march.beam_queries // 0) * (.march.balls_per_query // 0))}' "${o%.exr}.json" >> "$log"
    done
  done
done

if [ "$FIT" = beams ]; then
python3 - "$log" <<'EOF'
import json, statistics, sys, collections
# select.c's held weights, in lookups, and the lookup's time (us)
LOOKUP, SHADOW, CELL, SAMPLE = 0.164, 1.96, 1.52, 2.18
runs = collections.defaultdict(list)
for line in open(sys.argv[1]):
    j = json.loads(line)
    runs[j['scene']].append(j)
rows = []
for s, js in sorted(runs.items()):
    j = js[0]
    n = j['n']
    t = statistics.median(x['t'] for x in js) / n * 1e6
    held = LOOKUP * (j['L'] / n + SHADOW * j['S'] / n + CELL * j['M'] / n + SAMPLE)
    rows.append((s, t, held, j['Q'] / n, j['H'] / n))
# One unknown, relative error: minimise sum ((held + aH h) / t - 1)^2. (With a weight per
# query too, the two are nearly collinear, a query being about one a camera sample, and the
# first fit gave the query a negative weight: -0.31 us, the ball 0.099 us.)
num = den = 0.0
for s, t, held, q, h in rows:
    x, y = h / t, 1.0 - held / t
    num += x * y
    den += x * x
aH = num / den
print('| weight | us | in lookups |')
print('|---|---|---|')
print('| ball crossed | %.5f | %.4f |' % (aH, aH / LOOKUP))
print()
print('| scene | us per sample | held part | queries | balls | model | model / measured |')
print('|---|---|---|---|---|---|---|')
for s, t, held, q, h in rows:
    m = held + aH * h
    print('| %s | %.3f | %.3f | %.3f | %.1f | %.3f | %.3f |' % (s, t, held, q, h, m, m / t))
EOF
exit 0
fi

if [ "$FIT" = eq ]; then
python3 - "$log" <<'EOF'
import json, statistics, sys, collections
# select.c's held weights, in lookups, and the lookup's time (us)
LOOKUP, SHADOW = 0.164, 1.96
runs = collections.defaultdict(list)
for line in open(sys.argv[1]):
    j = json.loads(line)
    runs[(j['scene'], j['method'])].append(j)
rows = []
for s in sorted({k[0] for k in runs}):
    a, o = runs.get((s, 'delta-auto')), runs.get((s, 'delta-off'))
    if not a or not o or not a[0]['E']:
        continue
    n = a[0]['n']
    ta = statistics.median(x['t'] for x in a) / n * 1e6
    to = statistics.median(x['t'] for x in o) / n * 1e6
    held = LOOKUP * ((a[0]['L'] - o[0]['L']) / n + SHADOW * (a[0]['S'] - o[0]['S']) / n)
    rows.append((s, ta, to, held, a[0]['E'] / n))
# One unknown on the paired difference, relative to the auto render's time:
# minimise sum ((to + held + aE e) / ta - 1)^2.
num = den = 0.0
for s, ta, to, held, e in rows:
    x, y = e / ta, 1.0 - (to + held) / ta
    num += x * y
    den += x * x
aE = num / den
print('| weight | us | in lookups |')
print('|---|---|---|')
print('| equiangular flight set-up | %.5f | %.3f |' % (aE, aE / LOOKUP))
print()
print('| scene | us per sample, auto | off | held part of the difference | set-ups | model / measured |')
print('|---|---|---|---|---|---|')
for s, ta, to, held, e in rows:
    print('| %s | %.3f | %.3f | %.3f | %.2f | %.3f |' % (s, ta, to, held, e, (to + held + aE * e) / ta))
EOF
exit 0
fi

if [ "$FIT" = gu ]; then
python3 - "$log" <<'EOF'
import json, statistics, sys, collections
# select.c's held weights, in lookups, and the lookup's time (us)
LOOKUP, SHADOW, SAMPLE, EQ = 0.164, 1.96, 2.18, 0.59
rows = []
runs = collections.defaultdict(list)
for line in open(sys.argv[1]):
    j = json.loads(line)
    runs[j['scene']].append(j)
for s, js in sorted(runs.items()):
    j = js[0]
    n = j['n']
    t = statistics.median(x['t'] for x in js) / n * 1e6
    held = LOOKUP * (j['L'] / n + SHADOW * j['S'] / n + EQ * j['E'] / n + SAMPLE)
    rows.append((s, t, held, j['F'] / n, j['V'] / n))
# Two unknowns, relative error: minimise sum ((held + aF f + aV v) / t - 1)^2.
Sff = Sfv = Svv = Sfy = Svy = 0.0
for s, t, held, f, v in rows:
    xf, xv, y = f / t, v / t, 1.0 - held / t
    Sff += xf * xf; Sfv += xf * xv; Svv += xv * xv; Sfy += xf * y; Svy += xv * y
det = Sff * Svv - Sfv * Sfv
aF = (Sfy * Svv - Svy * Sfv) / det
aV = (Svy * Sff - Sfy * Sfv) / det
print('| weight | us | in lookups |')
print('|---|---|---|')
print('| flight segment | %.5f | %.3f |' % (aF, aF / LOOKUP))
print('| guided vertex | %.5f | %.3f |' % (aV, aV / LOOKUP))
print()
print('| scene | us per sample | held part | segments | vertices | model | model / measured |')
print('|---|---|---|---|---|---|---|')
for s, t, held, f, v in rows:
    m = held + aF * f + aV * v
    print('| %s | %.3f | %.3f | %.2f | %.2f | %.3f | %.3f |' % (s, t, held, f, v, m, m / t))
EOF
exit 0
fi

python3 - "$log" <<'EOF'
import json, statistics, sys, collections
runs = collections.defaultdict(list)
for line in open(sys.argv[1]):
    j = json.loads(line)
    runs[(j['scene'], j['method'])].append(j)
names = ['lookup', 'shadow ray', 'marcher segment', 'flight segment', 'guided vertex', 'camera sample']
rows, keys = [], []
for k, js in sorted(runs.items()):
    j = js[0]  # the counts are the same every round (same seed); the time is the median
    n = j['n']
    t = statistics.median(x['t'] for x in js) / n * 1e6  # us per camera sample
    x = [j['L'] / n, j['S'] / n, j['M'] / n, j['F'] / n, j['V'] / n, 1.0]
    rows.append((x, t))
    keys.append(k)
# Least squares for relative error: rows scaled by 1/t; normal equations, Gaussian elimination.
p = len(names)
A = [[0.0] * p for _ in range(p)]
b = [0.0] * p
for x, t in rows:
    xs = [v / t for v in x]
    for i in range(p):
        b[i] += xs[i]  # (t / t) = 1
        for k in range(p):
            A[i][k] += xs[i] * xs[k]
for c in range(p):
    piv = max(range(c, p), key=lambda r: abs(A[r][c]))
    A[c], A[piv] = A[piv], A[c]
    b[c], b[piv] = b[piv], b[c]
    for r in range(p):
        if r != c and A[c][c] != 0.0:
            f = A[r][c] / A[c][c]
            for k in range(c, p):
                A[r][k] -= f * A[c][k]
            b[r] -= f * b[c]
a = [b[i] / A[i][i] for i in range(p)]
print('| weight | us | in lookups |')
print('|---|---|---|')
for nm, v in zip(names, a):
    print('| %s | %.4f | %.3f |' % (nm, v, v / a[0]))
print()
# What the selection compares within a tile is a method's cost over delta's: measured and modelled.
model = {k: sum(ai * xi for ai, xi in zip(a, x)) for (x, t), k in zip(rows, keys)}
meas = {k: t for (x, t), k in zip(rows, keys)}
print('| scene | method | us per sample | model | model / measured | over delta: measured | model |')
print('|---|---|---|---|---|---|---|')
for (s, m) in keys:
    d = (s, 'delta')
    over = '| %.2f | %.2f' % (meas[(s, m)] / meas[d], model[(s, m)] / model[d]) if m != 'delta' and d in meas else '| | '
    print('| %s | %s | %.3f | %.3f | %.3f %s |' % (s, m, meas[(s, m)], model[(s, m)], model[(s, m)] / meas[(s, m)], over))
EOF
