#!/usr/bin/env python3
"""cost_fit.py: the fits of bench/bench_cost_fit.sh (the tile selection's cost weights,
renderer/integrators/select.c), over the runs file the script wrote: one JSON object a render
with the scene, the method (or variant), the render seconds t, the camera samples n and the
counts L (lookups), S (shadow rays), E (equiangular set-ups), Z (equiangular samples), M
(marcher segments), P (marched samples), F (flight segments), V (guided vertices), H (balls a
beam query crossed).

    bench/cost_fit.py all|beams|gu|eq|eqs|ms|rel|relp|relcheck RUNS_FILE

all    every weight, a least-squares fit of time per camera sample on every render;
beams  the weight of a ball, the others held at select.c's;
gu     guided-unbiased's flight segment and guided vertex, the others held;
eq     a flight's equiangular set-up, on the paired difference of delta with
       settings.equiangular "auto" and "false";
eqs    an equiangular sample's own work (beyond its lookups and shadow ray), on the paired
       difference of delta with settings.equiangular "true" and "false", the set-up held;
rel    the marcher's PDF segment and marched sample, in delta's lookups of the same scene
       (delta, guided, and guided with 16 samples on every ray);
relp   the same runs, the marched sample alone, the PDF segment held at select.c's;
relcheck  no fit: rel's runs on other scenes, model over measured with select.c's weights and
       with session 51's rel and relp fits;
ms     a marched sample's own work (beyond its lookups, shadow rays and equiangular set-ups),
       on the paired difference of guided with 16 and 2 samples on every ray, those and the
       PDF segments held.
Every fit minimises relative errors (each row divided by its measured time). Prints markdown
tables: the weights, then each render's measured and modelled time."""
import collections
import json
import statistics
import sys

# select.c's weights in lookups, and the lookup's time in microseconds (the "all" fit's)
LOOKUP, SHADOW, CELL, SAMPLE, EQ, BALL = 0.164, 1.96, 1.52, 2.18, 0.40, 0.60


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


def fit_paired(path, a_name, o_name, count, name, held_terms):
    """One weight on the paired difference of two variants, a_name and o_name: per scene
    (t_a - t_o) / samples - held = w x (count_a - count_o) / samples, the held part
    held_terms(ja, jo, n) in us per sample (the difference's lookups and shadow rays at
    select.c's weights, and what else the mode holds)."""
    runs = load(path, lambda j: (j['scene'], j['method']))
    rows, shown = [], []
    for s in sorted({k[0] for k in runs}):
        a, o = runs.get((s, a_name)), runs.get((s, o_name))
        if not a or not o or not (a[0][count] - o[0].get(count, 0)):
            continue  # e.g. no point or spot light: nothing set up or sampled
        ja, n, ta = per_sample(a)
        jo, _, to = per_sample(o)
        held = held_terms(ja, jo, n)
        x = (ja[count] - jo.get(count, 0)) / n
        rows.append(([x], to + held, ta))
        shown.append((s, ta, to, held, x))
    (w,) = fit_relative(rows)
    weights_table([name], [w])
    print('| scene | us per sample, %s | %s | held part of the difference | %ss | model / measured |'
          % (a_name, o_name, name))
    print('|---|---|---|---|---|---|')
    for s, ta, to, held, x in shown:
        print('| %s | %.3f | %.3f | %.3f | %.2f | %.3f |' % (s, ta, to, held, x, (to + held + w * x) / ta))


def held_difference(setups, cells=False):
    """held_terms for fit_paired: the difference's lookups and shadow rays (and its equiangular
    set-ups at EQ's weight when `setups`: all of variant a's for eqs, whose other variant sets
    none up; the difference for ms; and its PDF segments at CELL's when `cells`)."""
    def held(ja, jo, n):
        h = (ja['L'] - jo['L']) / n + SHADOW * (ja['S'] - jo['S']) / n
        if setups == 'all':
            h += EQ * ja['E'] / n
        elif setups == 'difference':
            h += EQ * (ja['E'] - jo['E']) / n
        if cells:
            h += CELL * (ja['M'] - jo['M']) / n
        return LOOKUP * h
    return held


def held_relative(j, n):
    """A render's counted cost a camera sample by select.c's weights, the marcher's two (PDF
    segment, marched sample) left out."""
    return (j['L'] + SHADOW * j['S'] + EQ * j['E'] + BALL * j['H']) / n + SAMPLE


def relative_rows(path):
    """Per scene with a delta render, k = delta's time a sample over its counted cost, and for
    each guided row (s, m, y, h, M, P, k): its time in those lookups y, its held cost h, its PDF
    segments M and marched samples P a camera sample."""
    runs = load(path, lambda j: (j['scene'], j['method']))
    for s in sorted({key[0] for key in runs}):
        if (s, 'delta') not in runs:
            continue
        jd, nd, td = per_sample(runs[(s, 'delta')])
        k = td / held_relative(jd, nd)
        for m in ('guided', 'guided-n16'):
            if (s, m) not in runs:
                continue
            j, n, t = per_sample(runs[(s, m)])
            yield s, m, t / k, held_relative(j, n), j['M'] / n, j['P'] / n, k


def fit_relative_to_delta(path, hold_segment=False):
    """The marcher's PDF segment and marched sample weights, in the lookups of delta on the same
    scene: per scene k = delta's time a sample over its counted cost (select.c's weights); each
    guided row's time over k is its cost in those lookups, fitted as the held counts plus
    w_M segments plus w_P samples (relative errors). hold_segment: w_M held at select.c's,
    w_P alone fitted (mode relp)."""
    shown = list(relative_rows(path))
    if hold_segment:
        rows = [([P], h + CELL * M, y) for _, _, y, h, M, P, _ in shown]
        a = [CELL] + fit_relative(rows)
    else:
        a = fit_relative([([M, P], h, y) for _, _, y, h, M, P, _ in shown])
    print('| weight | in delta\'s lookups of the same scene |')
    print('|---|---|')
    for nm, v in zip(['PDF segment', 'marched sample'], a):
        print('| %s | %.3f |' % (nm, v))
    print()
    print('| scene | method | delta\'s us a lookup | measured, in lookups | held | segments | samples | model / measured | with select.c\'s weights |')
    print('|---|---|---|---|---|---|---|---|---|')
    for s, m, y, h, M, P, k in shown:
        print('| %s | %s | %.4f | %.2f | %.2f | %.2f | %.2f | %.3f | %.3f |' % (
            s, m, k, y, h, M, P, (h + a[0] * M + a[1] * P) / y, (h + CELL * M) / y))


# Session 51's two fits on the calibration scenes (rel: segment and marched sample; relp: the
# marched sample alone, the segment held), for relcheck.
REL_FIT, RELP_FIT = (0.674, 1.656), (CELL, 0.223)


def check_relative_to_delta(path):
    """No fit: each scene's guided rows, model over measured (in delta's lookups of the scene, as
    rel measures them) with select.c's weights, with session 51's rel fit and with its relp fit;
    for scenes the fits did not see."""
    print('| scene | method | delta\'s us a lookup | select.c\'s | rel %.3f, %.3f | relp %.2f, %.3f |' % (REL_FIT + RELP_FIT))
    print('|---|---|---|---|---|---|')
    for s, m, y, h, M, P, k in relative_rows(path):
        print('| %s | %s | %.3f | %.2f | %.2f | %.2f |' % (
            s, m, k, (h + CELL * M) / y, (h + REL_FIT[0] * M + REL_FIT[1] * P) / y,
            (h + RELP_FIT[0] * M + RELP_FIT[1] * P) / y))


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
        fit_paired(path, 'delta-true', 'delta-off', 'Z', 'equiangular sample', held_difference('all'))
    elif mode == 'eq':
        fit_paired(path, 'delta-auto', 'delta-off', 'E', 'equiangular set-up', held_difference(None))
    elif mode == 'rel':
        fit_relative_to_delta(path)
    elif mode == 'relp':
        fit_relative_to_delta(path, hold_segment=True)
    elif mode == 'relcheck':
        check_relative_to_delta(path)
    elif mode == 'ms':
        fit_paired(path, 'guided-n16', 'guided-n2', 'P', 'marched sample', held_difference('difference', True))
    else:
        sys.exit('cost_fit.py: mode must be all, beams, gu, eq, eqs, ms, rel, relp or relcheck, not ' + mode)


if __name__ == '__main__':
    main()
