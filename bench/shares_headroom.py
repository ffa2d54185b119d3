#!/usr/bin/env python3
"""shares_headroom.py: what per-tile shares of the samples (settings.adaptive) could buy, scored
offline from renders of single estimators (docs/guided-marching.md "Samples where they pay").

    shares_headroom.py DIR [E1 E2 ...]

DIR/E.exr, DIR/E-stderr.exr and DIR/E.json for each estimator E (default: deq beams), each a
render of that estimator alone over the whole image at equal settings, e.g.

    photonmarch render S.json --method delta --set settings.equiangular=true -o DIR/deq.exr ...
    photonmarch render S.json --method guided --set settings.select=off --set march.ls=nee+beams \\
        --set photons.progressive=true -o DIR/beams.exr ...

Per 8x8 tile k and estimator e: V_ke, the variance a sample (the stderr squared times the
samples a pixel, mean over RGB and the tile's pixels), and C_e, the render's seconds a sample a
pixel (one figure an estimator). With every pixel drawing alike the error at equal time goes as
(sum_k V_k)(sum_k C_k); with shares n_k ~ sqrt(V_k / C_k) as (sum_k sqrt(V_k C_k))^2. Printed,
over the first estimator at every pixel alike: each estimator alone, uniform and with shares,
and the better of them in each tile with shares. Bounds: each tile's variance taken as known,
no bias counted (the beams' kernel bias is not in the stderr).
"""
import json
import sys

import numpy as np
import OpenImageIO as oiio

TILE = 8


def img(path):
    return oiio.ImageBuf(path).get_pixels(oiio.FLOAT)[:, :, :3].astype(np.float64)


def main(argv):
    if len(argv) < 2:
        print(__doc__)
        return 1
    d, names = argv[1], argv[2:] or ["deq", "beams"]
    V, C = {}, {}
    for e in names:
        js = json.load(open(f"{d}/{e}.json"))
        spp = js["spp_mean"]
        v = (img(f"{d}/{e}-stderr.exr") ** 2).mean(axis=2) * spp
        h, w = v.shape
        V[e] = v[: h - h % TILE, : w - w % TILE].reshape(h // TILE, TILE, w // TILE, TILE).mean(axis=(1, 3))
        C[e] = js["seconds"] / spp
    base = names[0]
    uniform = lambda e: V[e].sum() * C[e] * V[e].size  # noqa: E731
    shares = lambda e: np.sqrt(V[e] * C[e]).sum() ** 2  # noqa: E731
    best = np.minimum.reduce([V[e] * C[e] for e in names])
    print(f"time x error over {base} at every pixel alike (higher is better):")
    for e in names:
        print(f"  {e:8s} alike {uniform(base) / uniform(e):.3f}   with shares {uniform(base) / shares(e):.3f}")
    both = np.sqrt(best).sum() ** 2
    print(f"  the better in each tile, with shares {uniform(base) / both:.3f} ({shares(base) / both:.3f} over {base} with shares)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
