/* tracking.c: free-path sampling and transmittance through the scene's media (THEORY.md §2;
 * seeds 000, 002, 003): the media the ray crosses, in order, each handed to the free-path
 * engine (freepath.c) with the tracker and estimator the scene settings choose. */
#include "rd_internal.h"

typedef struct { double t0, t1; const rd_medium *m; } interval;

/* The media the ray crosses within [tmin, tmax], sorted by entry distance. Media do not overlap
 * (the loader checks), so the intervals are disjoint. Returns their number. */
static int media_intervals(const rd_scene *s, ray3 r, double tmin, double tmax, interval *out)
{
    int n = 0;
    for (int i = 0; i < s->n_media; i++) {
        double t0, t1;
        const rd_medium *m = &s->media[i];
        if (m->sigma_maj <= 0.0) continue;
        if (!rd_box_intersect(m->bmin, m->bmax, r, tmin, tmax, &t0, &t1)) continue;
        int k = n++;
        while (k > 0 && out[k - 1].t0 > t0) { out[k] = out[k - 1]; k--; }
        out[k].t0 = t0;
        out[k].t1 = t1;
        out[k].m = m;
    }
    return n;
}

static rd_fp_params params_of(const rd_scene *s)
{
    rd_fp_params p;
    p.tracker = (rd_fp_kind)s->settings.tracker;
    p.transmittance = (rd_tr_kind)s->settings.transmittance;
    p.b = s->settings.track_b;
    p.m = s->settings.track_m;
    p.step = s->settings.track_step;
    return p;
}

rd_collision rd_sample_free_path(const rd_scene *s, ray3 r, double tmax, pcg32 *rng,
                                 rd_track_counters *c)
{
    interval iv[64];
    int n = media_intervals(s, r, 0.0, tmax, iv);
    rd_collision col = {0, tmax, NULL, 1.0};
    rd_fp_params p = params_of(s);
    for (int i = 0; i < n; i++) {
        /* One medium at a time, with the engine's tracker (freepath.c). */
        rd_fp_medium fm = rd_fp_view(iv[i].m);
        rd_fp_event ev = rd_fp_sample(&p, &fm, r, iv[i].t0, iv[i].t1, rng, c);
        col.weight *= ev.weight;
        if (ev.hit) {
            col.hit = 1;
            col.t = ev.t;
            col.medium = iv[i].m;
            return col;
        }
    }
    return col;
}

double rd_transmittance(const rd_scene *s, ray3 r, double t0, double t1, pcg32 *rng,
                        rd_track_counters *c)
{
    interval iv[64];
    if (!(t1 > t0)) return 1.0;
    int n = media_intervals(s, r, t0, t1, iv);
    double T = 1.0;
    rd_fp_params p = params_of(s);
    for (int i = 0; i < n && T != 0.0; i++) {
        rd_fp_medium fm = rd_fp_view(iv[i].m);
        T *= rd_fp_transmittance(&p, &fm, r, iv[i].t0, iv[i].t1, rng, c);
    }
    return T;
}
