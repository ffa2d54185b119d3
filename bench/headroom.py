#!/usr/bin/env python3
"""headroom.py: the headroom of a five-estimator tile selection for `guided`, scored offline
(bench/bench_headroom.sh renders its inputs; docs/benchmarks.md "Session 56").

    headroom.py PREFIX REFERENCE.exr

PREFIX-E.exr (with -stderr.exr and .json) for E in delta, method, delta_equiangular,
guided_path, beams: long renders of each estimator alone, whose per-pixel variance a sample
(se^2 spp, mean over RGB) is the table V_E; PREFIX-tr-g.jsonl and PREFIX-tr-b.jsonl: the select
traces of default `guided` and of `guided` with nee+beams and "tiles", whose last lines give
each tile's counted cost a sample C_E (the beams' from the second, their "method").

For a choice of one estimator a tile, a render of T seconds draws N = T / (tau sum C) samples
a pixel (tau: delta's table's seconds over its counted cost), and its summed squared error is
sum V / N plus the beams' squared bias in their tiles: per pixel (mean_beams - reference)^2
less both variances of the means (summed per tile, floored at 0; from the beams' table, so a
bias smaller than at a 10-s render's few passes). Printed per T (10 and 60 s): the efficiency
over every tile on delta's path, and with the bias left out, of
  default4   the rule (rd_select_choose: least (sum V)(sum C)) over the four estimators of
             default `guided`, on the tables;
  gbmt       the rule over delta's two paths and the beams;
  five       the rule over all five;
  five+bias  five, then single moves that lower the error with the bias, until none does;
  (trace)    the choices the two traced renders ended with.
The tables' variances miss one thing the mixed render has: with "tiles" a pass serves
pass_spp x (all pixels) samples of the marched pixels, so those share a pass's photons
(docs/guided-marching.md "Mixed with `delta` per tile").
"""
import json
import sys

import numpy as np
import OpenImageIO as oiio

TILE = 8
NAMES = ["delta", "method", "delta_equiangular", "guided_path", "beams"]


def img(path):
    return oiio.ImageBuf(path).get_pixels(oiio.FLOAT)[:, :, :3].astype(np.float64)


def tiles_sum(a, ty, tx):
    out = np.zeros((ty, tx))
    for y in range(ty):
        for x in range(tx):
            out[y, x] = a[y * TILE:(y + 1) * TILE, x * TILE:(x + 1) * TILE].sum()
    return out.ravel()


def rule(V, C, allowed):
    """rd_select_choose on per-tile V and C (dicts of arrays) over the estimators `allowed`."""
    n = len(next(iter(V.values())))
    Vm = np.array([[V[a][k] for a in allowed] for k in range(n)])
    Cm = np.array([[C[a][k] for a in allowed] for k in range(n)])
    # (a cost the trace left null is inf: never chosen, even where V is 0 and V C would be nan)
    ch = np.argmin(np.where(np.isinf(Cm), np.inf, Vm * Cm), axis=1)
    for _ in range(32):
        lam = Vm[range(n), ch].sum() / Cm[range(n), ch].sum()
        new = np.argmin(Vm + lam * Cm, axis=1)
        if (new == ch).all():
            break
        ch = new
    Vs, Cs = Vm[range(n), ch].sum(), Cm[range(n), ch].sum()
    changed, rounds = Cs > 0, 0
    while changed and rounds < 32:  # (rd_select_choose's bound)
        changed, rounds = False, rounds + 1
        for k in range(n):
            for e in range(len(allowed)):
                o = ch[k]
                if e == o:
                    continue
                V2, C2 = Vs - Vm[k, o] + Vm[k, e], Cs - Cm[k, o] + Cm[k, e]
                if V2 * C2 < Vs * Cs * (1 - 1e-12):
                    ch[k], Vs, Cs, changed = e, V2, C2, True
    return [allowed[c] for c in ch]


def main():
    prefix, ref = sys.argv[1], sys.argv[2]
    V, M, SE, REP = {}, {}, {}, {}
    for nm in NAMES:
        SE[nm] = img(f"{prefix}-{nm}-stderr.exr")
        REP[nm] = json.load(open(f"{prefix}-{nm}.json"))
        V[nm] = (SE[nm] ** 2).mean(axis=2) * REP[nm]["spp"]
        M[nm] = img(f"{prefix}-{nm}.exr")
    h, w = V["delta"].shape
    ty, tx = (h + TILE - 1) // TILE, (w + TILE - 1) // TILE
    pix = tiles_sum(np.ones((h, w)), ty, tx)
    Vt = {nm: tiles_sum(V[nm], ty, tx) for nm in NAMES}
    g = [json.loads(line) for line in open(f"{prefix}-tr-g.jsonl")]
    b = [json.loads(line) for line in open(f"{prefix}-tr-b.jsonl")]
    C = {}
    for tr, beams in ((g, False), (b, True)):
        for e, nm in enumerate(tr[-1]["estimators"]):
            if beams and nm != "method":
                continue
            cost = [t["cost"][e] if t["cost"][e] is not None else np.inf for t in tr[-1]["tiles"]]
            C["beams" if beams else nm] = np.array(cost) * pix
    avail = [nm for nm in NAMES if nm in C]
    R, RSE = img(ref), img(ref[:-len(".exr")] + "-stderr.exr")
    B2 = np.maximum(tiles_sum(((M["beams"] - R) ** 2 - SE["beams"] ** 2 - RSE ** 2).mean(axis=2), ty, tx), 0.0)
    tau = REP["delta"]["render_seconds"] / (REP["delta"]["spp"] * C["delta"].sum())

    def error(ch, T, bias=True):
        Vs = sum(Vt[nm][k] for k, nm in enumerate(ch))
        Cs = sum(C[nm][k] for k, nm in enumerate(ch))
        return Vs * tau * Cs / T + (sum(B2[k] for k, nm in enumerate(ch) if nm == "beams") if bias else 0.0)

    def with_bias(start, T):
        ch, best, changed = list(start), error(start, T), True
        while changed:
            changed = False
            for k in range(len(ch)):
                for e in avail:
                    o = ch[k]
                    if e == o:
                        continue
                    ch[k] = e
                    f = error(ch, T)
                    if f < best * (1 - 1e-12):
                        best, changed = f, True
                    else:
                        ch[k] = o
        return ch

    def traced(tr, beams):
        est = tr[-1]["estimators"]
        return [("beams" if beams and est[t["choice"]] == "method" else est[t["choice"]]) for t in tr[-1]["tiles"]]

    sets = {"default4": rule(Vt, C, [a for a in avail if a != "beams"]),
            "gbmt": rule(Vt, C, [a for a in ("delta", "delta_equiangular", "beams") if a in avail]),
            "five": rule(Vt, C, avail),
            "default(trace)": traced(g, False), "gbmt(trace)": traced(b, True)}
    print(f"{prefix}: estimators {avail}; tau {tau * 1e6:.3f} us a counted lookup; the beams' bias^2 summed "
          f"{B2.sum():.3g} ({REP['beams']['spp']} spp in {REP['beams']['render_seconds']:.0f} s)")
    # The traced nee+beams render's tiles on the beams at every line: its squared error there
    # against what the tables predict at its spp (pass noise shared by a pixel's samples shows).
    Bimg, BSE = img(f"{prefix}-b.exr"), img(f"{prefix}-b-stderr.exr")
    spp_b = json.load(open(f"{prefix}-b.json"))["spp"]
    mi = b[0]["estimators"].index("method")
    act = own = pred = 0.0
    kept = [k for k in range(len(pix)) if all(ln["tiles"][k]["choice"] == mi and ln["tiles"][k]["trial"] == 0 for ln in b)]
    for k in kept:
        y, x = divmod(k, tx)
        sl = (slice(y * TILE, (y + 1) * TILE), slice(x * TILE, (x + 1) * TILE))
        act += ((Bimg[sl] - R[sl]) ** 2 - RSE[sl] ** 2).mean(axis=2).sum()
        own += (BSE[sl] ** 2).mean(axis=2).sum()
        pred += V["beams"][sl].sum() / spp_b + B2[k]
    if kept:
        print(f"  the traced nee+beams render's {len(kept)} tiles on the beams throughout ({spp_b} spp): squared error "
              f"{act:.4g}, its own variance {own:.4g}, the tables' prediction {pred:.4g} (x{act / pred:.2f})")
    alld = ["delta"] * len(pix)
    for T in (10.0, 60.0):
        base = error(alld, T)
        row = [f"{k} {base / error(ch, T):.2f} (variance alone {base / error(ch, T, False):.2f}, beams "
               f"{np.mean([c == 'beams' for c in ch]):.0%})" for k, ch in sets.items()]
        wb = with_bias(sets["five"], T)
        row.append(f"five+bias {base / error(wb, T):.2f} (beams {np.mean([c == 'beams' for c in wb]):.0%})")
        print(f"  {T:.0f} s, efficiency over every tile on delta's path: " + "; ".join(row))


if __name__ == "__main__":
    main()
