/* march_share.c: the kernel ball's share of photons near a box medium's faces
 * (rd_march_support_share, rd_march.h), by which the marchers' photon estimates divide: the
 * point gather (march.c) and the beam estimate (march_beams.c). A leaf of both. */
#include "integrators/rd_march.h"

#include <float.h>
#include <math.h>

/* The share of a kernel ball's volume that holds photons, weighted by their density: a ball of
 * radius r about x inside a box medium whose faces open onto empty space or onto another medium.
 * The photons are stored at collisions, so their density is sigma_t(y) phi(y), and the
 * sample-point estimate at x averages it over the ball. Where the ball reaches past a face, that
 * part holds the density of what lies beyond, sigma_o phi (none in empty space), and with the
 * fluence phi continuous across the face the estimate reads its value at x times
 *     m = share inside + (sigma_o / sigma_t(x)) share beyond,
 * an O(r) bias (low in a box in empty space or in a thinner medium, high beside a denser one)
 * where the interior's is O(r^2); the photon estimates divide by m. Per axis, the share of the
 * unit ball's volume whose coordinate lies in [-a, b] is G(b) - G(-a),
 * G(s) = 1/2 + 3 s / 4 - s^3 / 4 (the coordinate's marginal density is 3 (1 - s^2) / 4), and the
 * parts below and above the faces G(-a) and 1 - G(b); the three axes' factors are multiplied,
 * which is exact wherever the ball is cut on one axis only (and, by symmetry, wherever x lies
 * on every face that cuts it: on a face alone, an edge or a corner); cut on two or three axes
 * it reads the share inside high, by up to 1.4% near an edge and 4.4% near a corner (at 0.4 r
 * from each face; by numerical integration, tests/test_beams.c). Only
 * constant-density box media (their photons fill the box to its faces; sigma_o is read just
 * past the face, at the foot of the perpendicular from x); a medium bound by surfaces, or whose
 * density falls off by itself, gets 1. */
static double ball_cdf(double s)
{
    s = fmax(-1.0, fmin(1.0, s));
    return 0.5 + 0.75 * s - 0.25 * s * s * s;
}

double rd_march_support_share(const rd_scene *s, int region, const rd_medium *m, vec3 x, double r)
{
    if (m->kind != RD_DENSITY_CONSTANT || m->bound || !(r > 0.0)) return 1.0;
    double sig = rd_medium_sigma_t(m, x);
    if (!(sig > 0.0)) return 1.0;
    const double xs[3] = {x.x, x.y, x.z};
    const double lo[3] = {m->bmin.x, m->bmin.y, m->bmin.z}, hi[3] = {m->bmax.x, m->bmax.y, m->bmax.z};
    double share = 1.0;
    for (int a = 0; a < 3; a++) {
        double dl = (xs[a] - lo[a]) / r, dh = (hi[a] - xs[a]) / r;
        if (dl >= 1.0 && dh >= 1.0) continue;
        double below = ball_cdf(-dl), above = 1.0 - ball_cdf(dh), f = 1.0 - below - above;
        /* The density past each face the ball reaches, relative to x's (0: empty space). */
        for (int side = 0; side < 2; side++) {
            if ((side ? dh : dl) >= 1.0) continue;
            /* (past the face by more than its coordinate's rounding, however far from the origin) */
            double face = side ? hi[a] : lo[a], past = fmax(1e-6 * r, 16.0 * DBL_EPSILON * fabs(face));
            double p[3] = {xs[0], xs[1], xs[2]};
            p[a] = side ? face + past : face - past;
            vec3 q = v3(p[0], p[1], p[2]);
            const rd_medium *o = rd_scene_medium_at(s, region, q);
            double w = o && o != m ? rd_medium_sigma_t(o, q) / sig : 0.0;
            f += w * (side ? above : below);
        }
        share *= f;
    }
    return share;
}
