#!/usr/bin/env python3
"""fig5_table.py: the markdown table of bench_fig5.sh from compare's metrics.json files
(schema photonmarch-compare/1, docs/compare.md). Per scene, per method: time per run (bake
charged), samples per pixel, RMSE, bias^2 and one run's variance, efficiency 1/(MSE x s), the
efficiency as a ratio to one method's (--ratio-to) in the same compare run, and the noise
homogeneity (90th / 50th percentile of the per-pixel relative error; 1 = even).

    bench/fig5_table.py [--ratio-to METHOD] [--machine FILE] [--threads N] METRICS.json...
"""
import argparse
import json
import sys


def fmt(x, spec):
    return "n/a" if x is None else format(x, spec)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ratio-to", default="uniform")
    ap.add_argument("--machine")
    ap.add_argument("--threads", type=float, default=0,
                    help="threads of the runs: adds core-microseconds per camera sample, (s - bake) x threads / samples")
    ap.add_argument("metrics", nargs="+")
    a = ap.parse_args()
    if a.machine:
        with open(a.machine) as f:
            for line in f:
                print("    " + line.rstrip())
        print()
    for path in a.metrics:
        try:
            with open(path) as f:
                m = json.load(f)
        except OSError as e:
            print(f"fig5_table: {path}: {e}", file=sys.stderr)
            return 1
        ref = dict(m["reference"])
        if ref["origin"] == "given":  # a render's own report beside the image (bench_fig5.sh)
            try:
                with open(ref["source"].rsplit(".", 1)[0] + ".json") as f:
                    r = json.load(f)
                ref["spp"], ref["seconds"] = r.get("spp"), r.get("seconds")
                ref["origin"] = f"given (rendered by {r.get('method')})"
            except (OSError, ValueError):
                pass
        print(f"### {m['scene']} ({m['width']}x{m['height']}, equal {m['equal']}, "
              f"budget {m['budget']}, {m['runs']} runs{', CANCELLED' if m.get('cancelled') else ''})")
        print()
        print(f"reference: {ref['origin']} {ref['source']}, spp {ref['spp']}, {fmt(ref['seconds'], '.0f')} s, "
              f"mean stderr^2 {fmt(ref['variance'], '.3g')}"
              f"{' (TOO NOISY TO RANK)' if ref.get('too_noisy') else ''}")
        print()
        base = next((x for x in m["methods"] if x["label"] == a.ratio_to), None)
        cost = " core-us/sample |" if a.threads > 0 else ""
        print(f"| method | s/run (bake) | spp | RMSE | bias^2 | variance | efficiency | vs {a.ratio_to} | homogeneity |{cost}")
        print("|---|---|---|---|---|---|---|---|---|" + ("---|" if cost else ""))
        for x in m["methods"]:
            ratio = (x["efficiency"] / base["efficiency"]) if base and base["efficiency"] else None
            print(f"| {x['label']} | {fmt(x['seconds'], '.1f')} ({fmt(x['bake_seconds'], '.1f')}) "
                  f"| {fmt(x['spp'], '.1f')} | {fmt(x['rmse'], '.4g')} | {fmt(x['bias2'], '.3g')} "
                  f"| {fmt(x['variance'], '.3g')} | {fmt(x['efficiency'], '.4g')} | {fmt(ratio, '.3g')} "
                  f"| {fmt(x['homogeneity'], '.2f')} |", end="")
            if a.threads > 0:
                n = (x["spp"] or 0) * m["width"] * m["height"]
                us = 1e6 * (x["seconds"] - (x["bake_seconds"] or 0)) * a.threads / n if n else None
                print(f" {fmt(us, '.3g')} |", end="")
            print()
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
