#!/usr/bin/env python3
"""cost_fit.py: the fits of bench/bench_cost_fit.sh (the tile selection's cost weights,
renderer/integrators/select.c), over the runs file the script wrote: one JSON object a render
with the scene, the method (or variant), the render seconds t, the camera samples n and the
counts L (lookups), S (shadow rays), E (equiangular set-ups), Z (equiangular samples), M
(marcher segments), F (flight segments), V (guided vertices), H (balls a beam query crossed).

    bench/cost_fit.py all|beams|gu|eq|eqs RUNS_FILE

all    every weight, a least-squares fit of time per camera sample on every render;
beams  the weight of a ball, the others held at select.c's;
gu     guided-unbiased's flight segment and guided vertex, the others held;
eq     a flight's equiangular set-up, on the paired difference of delta with
       settings.equiangular "auto" and "false";
eqs    an equiangular sample's own work (beyond its lookups and shadow ray), on the paired
       difference of delta with settings.equiangular "true" and "false", the set-up held.
Every fit minimises relative errors (each row divided by its measured time). Prints markdown
tables: the weights, then each render's measured and modelled time."""
import collections
import json
import statistics
import sys

# select.c's weights in lookups, and the lookup's time in microseconds (the "all" fit's)
LOOKUP, SHADOW, CELL, SAMPLE, EQ = 0.164, 1.96, 1.52, 2.18, 0.40


def load(path, key):
    """The runs grouped by key(run): {key: [run, ...]}, in file order within a group."""
    runs = collections.defaultdict(list)
    for line in open(path):
        j = json.loads(line)
        runs[key(j)].append(j)
    return runs


def per_sample(js):
    """A group's first run (the counts are the same every round: the same seed), its camera
    samples, and the median time per camera sample in microseconds."""
    j = js[0]
    return j, j['n'], statistics.median(x['t'] for x in js) / j['n'] * 1e6


def solve(A, b):
    """Gaussian elimination with partial pivoting: the x with A x = b (A square, copied)."""
    p = len(b)
    A = [row[:] for row in A]
    b = b[:]
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
    return [b[i] / A[i][i] for i in range(p)]


def fit_relative(rows):
    """rows: (x, y, t) with x the unknowns' coefficients, y the known part of the time and t the
    measured time; the a minimising sum ((y + a . x) / t - 1)^2."""
    p = len(rows[0][0])
    A = [[0.0] * p for _ in range(p)]
    b = [0.0] * p
    for x, y, t in rows:
        xs = [v / t for v in x]
        r = 1.0 - y / t
        for i in range(p):
            b[i] += xs[i] * r
            for k in range(p):
                A[i][k] += xs[i] * xs[k]
    return solve(A, b)


def weights_table(names, a):
    print('| weight | us | in lookups |')
    print('|---|---|---|')
    for nm, v in zip(names, a):
        print('| %s | %.5f | %.3f |' % (nm, v, v / LOOKUP))
    print()


def fit_all(path):
    runs = load(path, lambda j: (j['scene'], j['method']))
    names = ['lookup', 'shadow ray', 'marcher segment', 'flight segment', 'guided vertex', 'camera sample']
    rows, keys = [], []
    for k, js in sorted(runs.items()):
        j, n, t = per_sample(js)
        rows.append(([j['L'] / n, j['S'] / n, j['M'] / n, j['F'] / n, j['V'] / n, 1.0], 0.0, t))
        keys.append(k)
    a = fit_relative(rows)
    print('| weight | us | in lookups |')
    print('|---|---|---|')
    for nm, v in zip(names, a):
        print('| %s | %.4f | %.3f |' % (nm, v, v / a[0]))
    print()
    # What the selection compares within a tile is a method's cost over delta's.
    model = {k: sum(ai * xi for ai, xi in zip(a, x)) for (x, _, _), k in zip(rows, keys)}
    meas = {k: t for (_, _, t), k in zip(rows, keys)}
    print('| scene | method | us per sample | model | model / measured | over delta: measured | model |')
    print('|---|---|---|---|---|---|---|')
    for (s, m) in keys:
        d = (s, 'delta')
        over = '| %.2f | %.2f' % (meas[(s, m)] / meas[d], model[(s, m)] / model[d]) if m != 'delta' and d in meas else '| | '
        print('| %s | %s | %.3f | %.3f | %.3f %s |' % (s, m, meas[(s, m)], model[(s, m)], model[(s, m)] / meas[(s, m)], over))


def fit_held(path, names, unknowns, held_terms, cols):
    """The weights of `unknowns` (count keys), the rest held: held_terms(j, n) is the held part
    in us per sample. cols: the per-sample counts printed for each scene."""
    rows, shown = [], []
    for s, js in sorted(load(path, lambda j: j['scene']).items()):
        j, n, t = per_sample(js)
        held = held_terms(j, n)
        rows.append(([j[u] / n for u in unknowns], held, t))
        shown.append((s, t, held, [j[c] / n for c in cols]))
    a = fit_relative(rows)
    weights_table(names, a)
    print('| scene | us per sample | held part | %s | model | model / measured |' % ' | '.join(cols))
    print('|---|---|---|%s---|---|' % ('---|' * len(cols)))
    for (x, held, t), (s, _, _, c) in zip(rows, shown):
        m = held + sum(ai * xi for ai, xi in zip(a, x))
        print('| %s | %.3f | %.3f | %s | %.3f | %.3f |' % (s, t, held, ' | '.join('%.2f' % v for v in c), m, m / t))


def fit_paired(path, variant, count, name, held_setups):
    """One weight on the paired difference of delta with settings.equiangular `variant` and
    "false": per scene (t_variant - t_off) / samples - held = a x count, the held part the
    difference's lookups and shadow rays at select.c's weights (and the set-ups at EQ's when
    `held_setups`)."""
    runs = load(path, lambda j: (j['scene'], j['method']))
    rows, shown = [], []
    for s in sorted({k[0] for k in runs}):
        a, o = runs.get((s, 'delta-' + variant)), runs.get((s, 'delta-off'))
        if not a or not o or not a[0][count]:
            continue  # no point or spot light: nothing set up or sampled
        ja, n, ta = per_sample(a)
        jo, _, to = per_sample(o)
        held = LOOKUP * ((ja['L'] - jo['L']) / n + SHADOW * (ja['S'] - jo['S']) / n +
                         (EQ * ja['E'] / n if held_setups else 0.0))
        rows.append(([ja[count] / n], to + held, ta))
        shown.append((s, ta, to, held, ja[count] / n))
    (w,) = fit_relative(rows)
    weights_table([name], [w])
    print('| scene | us per sample, %s | off | held part of the difference | %ss | model / measured |'
          % (variant, name))
    print('|---|---|---|---|---|---|')
    for s, ta, to, held, x in shown:
        print('| %s | %.3f | %.3f | %.3f | %.2f | %.3f |' % (s, ta, to, held, x, (to + held + w * x) / ta))


def main():
    mode, path = sys.argv[1], sys.argv[2]
    if mode == 'all':
        fit_all(path)
    elif mode == 'beams':
        # (With a weight per query too, the two are nearly collinear, a query being about one a
        # camera sample, and the first fit gave the query a negative weight: -0.31 us, the ball
        # 0.099 us.)
        fit_held(path, ['ball crossed'], ['H'],
                 lambda j, n: LOOKUP * (j['L'] / n + SHADOW * j['S'] / n + CELL * j['M'] / n + SAMPLE), ['Q', 'H'])
    elif mode == 'gu':
        fit_held(path, ['flight segment', 'guided vertex'], ['F', 'V'],
                 lambda j, n: LOOKUP * (j['L'] / n + SHADOW * j['S'] / n + EQ * j['E'] / n + SAMPLE), ['F', 'V'])
    elif mode == 'eqs':
        fit_paired(path, 'true', 'Z', 'equiangular sample', True)
    elif mode == 'eq':
        fit_paired(path, 'auto', 'E', 'equiangular set-up', False)
    else:
        sys.exit('cost_fit.py: mode must be all, beams, gu, eq or eqs, not ' + mode)


if __name__ == '__main__':
    main()
