/* tracking.c: free-path sampling and transmittance through the scene's media with each
 * medium's global majorant (THEORY.md §2; seeds 000, 002, 003). Majorant grids and the other
 * trackers of the free-path engine build on the same interval walk. */
#include "rd_internal.h"

typedef struct { double t0, t1; const rd_medium *m; } interval;

/* The media the ray crosses within [0, tmax], sorted by entry distance. Media do not overlap
 * (the loader checks), so the intervals are disjoint. Returns their number. */
static int media_intervals(const rd_scene *s, ray3 r, double tmax, interval *out)
{
    int n = 0;
    for (int i = 0; i < s->n_media; i++) {
        double t0, t1;
        const rd_medium *m = &s->media[i];
        if (m->sigma_maj <= 0.0) continue;
        if (!rd_box_intersect(m->bmin, m->bmax, r, 0.0, tmax, &t0, &t1)) continue;
        int k = n++;
        while (k > 0 && out[k - 1].t0 > t0) { out[k] = out[k - 1]; k--; }
        out[k].t0 = t0;
        out[k].t1 = t1;
        out[k].m = m;
    }
    return n;
}

rd_collision rd_delta_track(const rd_scene *s, ray3 r, double tmax, pcg32 *rng,
                            rd_track_counters *c)
{
    interval iv[64];
    int n = media_intervals(s, r, tmax, iv);
    rd_collision col = {0, tmax, NULL};
    for (int i = 0; i < n; i++) {
        const rd_medium *m = iv[i].m;
        double inv_maj = 1.0 / m->sigma_maj, t = iv[i].t0;
        for (;;) {
            /* Tentative collision: t += -ln(1-u) / sigma_maj (Woodcock tracking). */
            t -= log(1.0 - pcg32_uniform(rng)) * inv_maj;
            if (t >= iv[i].t1) break;
            c->collisions++;
            c->lookups++;
            double sigma_t = rd_medium_sigma_t(m, ray_at(r, t));
            /* Real collision with probability sigma_t / sigma_maj, else a null collision. */
            if (pcg32_uniform(rng) * m->sigma_maj < sigma_t) {
                col.hit = 1;
                col.t = t;
                col.medium = m;
                return col;
            }
        }
    }
    return col;
}

double rd_ratio_track(const rd_scene *s, ray3 r, double tmax, pcg32 *rng, rd_track_counters *c)
{
    interval iv[64];
    int n = media_intervals(s, r, tmax, iv);
    double T = 1.0;
    for (int i = 0; i < n && T > 0.0; i++) {
        const rd_medium *m = iv[i].m;
        double inv_maj = 1.0 / m->sigma_maj, t = iv[i].t0;
        for (;;) {
            t -= log(1.0 - pcg32_uniform(rng)) * inv_maj;
            if (t >= iv[i].t1) break;
            c->collisions++;
            c->lookups++;
            /* Ratio tracking: T *= 1 - sigma_t / sigma_maj at every tentative collision. */
            T *= 1.0 - rd_medium_sigma_t(m, ray_at(r, t)) * inv_maj;
            if (T <= 0.0) return 0.0;
        }
    }
    return T;
}
