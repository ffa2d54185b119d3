#!/usr/bin/env python3
"""suites_table.py: the summary of bench/bench_suites.sh from compare's metrics.json files
(schema photonmarch-compare/1, docs/compare.md): scene x method tables of

  - efficiency relative to delta: 1/((MSE - ref_var) x seconds) over delta's in the same
    compare run. ref_var is the reference's own variance (mean stderr^2), which adds to every
    measured MSE; removed here as compare removes it from bias^2. seconds include the bake.
  - bias share: bias^2 / (MSE - ref_var), the part of a method's error that more time at the
    same settings does not remove (compare's bias^2 already has the reference's variance and
    the runs' variance / K taken out; it can come out slightly negative when there is none).

  - per sample: each method's time per sample (seconds_per_sample, the bake left out) and
    variance per sample (variance_per_sample, variance x spp) over delta's, so that a reader
    sees whether an efficiency ratio comes from cost or from variance. For an unbiased method
    the efficiency ratio is about ((T - bake) / T) / (time ratio x variance ratio).
    (metrics.json files from before these fields existed give n/a.)

then the per-scene details. A scene whose reference compare calls too noisy to rank is
marked *; an MSE not above ref_var is "<ref" (the reference's noise hides the method's error).

    bench/suites_table.py [--machine FILE] [--hard "SCENES"] [--easy "SCENES"] [--base delta] METRICS.json...
"""
import argparse
import json
import math
import os
import sys


def fmt(x, spec):
    return "n/a" if x is None or (isinstance(x, float) and math.isnan(x)) else format(x, spec)


def corrected(x, ref_var):
    """MSE with the reference's variance removed, or None when not above it."""
    mse = x.get("mse")
    if mse is None:
        return None
    c = mse - (ref_var or 0.0)
    return c if c > 0 else None


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--machine")
    ap.add_argument("--hard", default="")
    ap.add_argument("--easy", default="")
    ap.add_argument("--base", default="delta")
    ap.add_argument("metrics", nargs="+")
    a = ap.parse_args()
    hard, easy = a.hard.split(), a.easy.split()
    if a.machine:
        with open(a.machine) as f:
            for line in f:
                print("    " + line.rstrip())
        print()

    scenes = []  # (suite, name, metrics)
    for path in a.metrics:
        try:
            with open(path) as f:
                m = json.load(f)
        except (OSError, ValueError) as e:
            print(f"suites_table: {path}: {e}", file=sys.stderr)
            return 1
        name = os.path.splitext(os.path.basename(m["scene"]))[0]
        suite = "hard" if name in hard else "easy" if name in easy else "-"
        scenes.append((suite, name, m))

    methods = []
    for _, _, m in scenes:
        for x in m["methods"]:
            if x["label"] not in methods:
                methods.append(x["label"])

    def rows(value):
        """One row per scene, value(x, base, ref_var) per method; a geometric-mean row per suite."""
        per_suite = {}
        out = []
        for suite, name, m in scenes:
            ref = m["reference"]
            rv = ref.get("variance")
            base = next((x for x in m["methods"] if x["label"] == a.base), None)
            cells = []
            for meth in methods:
                x = next((y for y in m["methods"] if y["label"] == meth), None)
                v = value(x, base, rv) if x else None
                cells.append(v)
                if isinstance(v, float) and v > 0:
                    per_suite.setdefault((suite, meth), []).append(v)
            flag = "*" if ref.get("too_noisy") else ""
            cancelled = " (cancelled)" if m.get("cancelled") else ""
            out.append((suite, name + flag + cancelled, cells))
        return out, per_suite

    def eff_ratio(x, base, rv):
        cx, cb = corrected(x, rv), corrected(base, rv) if base else None
        if cx is None or cb is None or not x.get("seconds") or not base.get("seconds"):
            return None
        return (cb * base["seconds"]) / (cx * x["seconds"])

    def bias_share(x, base, rv):
        c = corrected(x, rv)
        if c is None or x.get("bias2") is None:
            return None
        return x["bias2"] / c

    header = "| suite | scene | " + " | ".join(methods) + " |"
    rule = "|---|---|" + "---|" * len(methods)

    print(f"## Efficiency relative to {a.base}: 1/((MSE - ref_var) x s), over {a.base}'s in the same compare run")
    print()
    print(header)
    print(rule)
    out, per_suite = rows(eff_ratio)
    for suite, name, cells in out:
        print(f"| {suite} | {name} | " + " | ".join(fmt(v, ".3g") for v in cells) + " |")
    for suite in ("hard", "easy"):
        if any(s == suite for s, _, _ in scenes):
            gm = []
            for meth in methods:
                v = per_suite.get((suite, meth), [])
                n = sum(1 for s, _, _ in scenes if s == suite)
                gm.append(math.exp(sum(map(math.log, v)) / len(v)) if v and len(v) == n else None)
            print(f"| {suite} | geometric mean | " + " | ".join(fmt(v, ".3g") for v in gm) + " |")
    print()
    print("## Bias share: bias^2 / (MSE - ref_var)")
    print()
    print(header)
    print(rule)
    out, _ = rows(bias_share)
    for suite, name, cells in out:
        print(f"| {suite} | {name} | " + " | ".join(fmt(v, ".2f") for v in cells) + " |")
    print()
    print(f"## Per sample: time and variance over {a.base}'s (time per sample excludes the bake)")
    print()
    print(header)
    print(rule)

    def per_sample(x, base, rv):
        keys = ("seconds_per_sample", "variance_per_sample")
        if base is None or any(not isinstance(x.get(k), (int, float)) or not isinstance(base.get(k), (int, float))
                               or not base.get(k) > 0 for k in keys):
            return None
        return tuple(x[k] / base[k] for k in keys)

    out, _ = rows(per_sample)
    for suite, name, cells in out:
        print(f"| {suite} | {name} | "
              + " | ".join("n/a" if v is None else f"{v[0]:.3g}x time, {v[1]:.3g}x var" for v in cells) + " |")
    print()
    print("n/a: not measurable (the method's MSE is not above the reference's variance, the method is missing, or its metrics.json predates the per-sample fields).")
    if any(m["reference"].get("too_noisy") for _, _, m in scenes):
        print("*: compare calls the reference too noisy to rank the methods (its variance > 1/10 of the best MSE, docs/compare.md).")
    print()
    print("## Per scene")
    for suite, name, m in scenes:
        ref = m["reference"]
        rv = ref.get("variance")
        print()
        print(f"### {name} ({suite}; {m['width']}x{m['height']}, equal {m['equal']}, budget {m['budget']}, "
              f"{m['runs']} runs{', CANCELLED' if m.get('cancelled') else ''})")
        print()
        print(f"reference: {ref['origin']}, spp {fmt(ref.get('spp'), '.0f')}, {fmt(ref.get('seconds'), '.0f')} s, "
              f"ref_var {fmt(rv, '.3g')}{' (TOO NOISY TO RANK)' if ref.get('too_noisy') else ''}")
        print()
        print("| method | s/run (bake) | spp | MSE | MSE - ref_var | bias^2 | variance | efficiency (compare) | "
              f"efficiency (ref_var removed) | vs {a.base} | bias share |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        base = next((x for x in m["methods"] if x["label"] == a.base), None)
        for x in m["methods"]:
            c = corrected(x, rv)
            eff = 1.0 / (c * x["seconds"]) if c and x.get("seconds") else None
            print(f"| {x['label']} | {fmt(x.get('seconds'), '.1f')} ({fmt(x.get('bake_seconds'), '.1f')}) "
                  f"| {fmt(x.get('spp'), '.1f')} | {fmt(x.get('mse'), '.3g')} | {fmt(c, '.3g') if c else '<ref'} "
                  f"| {fmt(x.get('bias2'), '.3g')} | {fmt(x.get('variance'), '.3g')} | {fmt(x.get('efficiency'), '.4g')} "
                  f"| {fmt(eff, '.4g')} | {fmt(eff_ratio(x, base, rv) if base else None, '.3g')} "
                  f"| {fmt(bias_share(x, base, rv), '.2f')} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
