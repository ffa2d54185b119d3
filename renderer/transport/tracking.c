/* tracking.c: free-path sampling and transmittance through the scene's media (THEORY.md §2;
 * seeds 000, 002, 003): the media the ray crosses, in order, each handed to the free-path
 * engine (freepath.c) with the tracker and estimator the scene settings choose. */
#include "scene/rd_geom.h"
#include "transport/rd_transport.h"

#include <string.h>

typedef rd_interval interval;

#define MAX_IV RD_MAX_INTERVALS

static void insert_sorted(interval *out, int *n, double t0, double t1, const rd_medium *m)
{
    int k = (*n)++;
    while (k > 0 && out[k - 1].t0 > t0) { out[k] = out[k - 1]; k--; }
    out[k].t0 = t0;
    out[k].t1 = t1;
    out[k].m = m;
}

/* A bound region: its one medium, clipped to the medium's bounds. The open region: the box
 * media (they do not overlap: the loader checks), and the scene-wide medium in the gaps between
 * them, within its bounds. */
int rd_media_intervals(const rd_scene *s, int region, ray3 r, double tmin, double tmax,
                       rd_interval *out)
{
    int n = 0;
    double t0, t1;
    if (region != s->fill_medium) {
        if (region < 0 || region >= s->n_media) return 0;
        const rd_medium *m = &s->media[region];
        if (m->sigma_maj > 0.0 && rd_box_intersect(m->bmin, m->bmax, r, tmin, tmax, &t0, &t1))
            insert_sorted(out, &n, t0, t1, m);
        return n;
    }
    for (int i = 0; i < s->n_media && n < 64; i++) {
        const rd_medium *m = &s->media[i];
        if (m->sigma_maj <= 0.0 || m->bound) continue;
        if (!rd_box_intersect(m->bmin, m->bmax, r, tmin, tmax, &t0, &t1)) continue;
        insert_sorted(out, &n, t0, t1, m);
    }
    const rd_medium *f = s->fill_medium >= 0 ? &s->media[s->fill_medium] : NULL;
    if (!f || !(f->sigma_maj > 0.0) || !rd_box_intersect(f->bmin, f->bmax, r, tmin, tmax, &t0, &t1))
        return n;
    /* The scene-wide medium over [t0, t1] minus the box intervals. */
    int nb = n;
    double a = t0;
    for (int k = 0; k <= nb; k++) {
        double b = k < nb ? fmin(out[k].t0, t1) : t1;
        if (b > a) out[n++] = (interval){a, b, f};
        if (k < nb) a = fmax(a, out[k].t1);
    }
    /* re-sort the appended gaps into place (insertion sort: few elements) */
    for (int i = 1; i < n; i++) {
        interval v = out[i];
        int k = i;
        while (k > 0 && out[k - 1].t0 > v.t0) { out[k] = out[k - 1]; k--; }
        out[k] = v;
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

rd_collision rd_sample_free_path(const rd_scene *s, int region, ray3 r, double tmax, pcg32 *rng,
                                 rd_track_counters *c)
{
    interval iv[MAX_IV];
    int n = rd_media_intervals(s, region, r, 0.0, tmax, iv);
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

double rd_transmittance(const rd_scene *s, int region, ray3 r, double t0, double t1, pcg32 *rng,
                        rd_track_counters *c)
{
    interval iv[MAX_IV];
    if (!(t1 > t0)) return 1.0;
    int n = rd_media_intervals(s, region, r, t0, t1, iv);
    double T = 1.0;
    rd_fp_params p = params_of(s);
    for (int i = 0; i < n && T != 0.0; i++) {
        rd_fp_medium fm = rd_fp_view(iv[i].m);
        T *= rd_fp_transmittance(&p, &fm, r, iv[i].t0, iv[i].t1, rng, c);
    }
    return T;
}

double rd_shadow_transmittance(const rd_scene *s, int region, ray3 r, double dist, int light,
                               const rd_hit *from, pcg32 *rng, rd_track_counters *c)
{
    double T = 1.0, t0 = 0.0;
    rd_hit h, prev;
    /* Each leg runs from the current origin to the next surface; an interface hands the ray
     * to the medium on its other side (rd_geom.h: medium_to) and the estimate goes on. */
    for (int legs = 0; legs < 256 && T != 0.0; legs++) {
        double left = dist - t0;
        if (!rd_scene_intersect(s, r, left, from, &h)) return T * rd_transmittance(s, region, r, 0.0, left, rng, c);
        if (h.light >= 0) /* the light itself ends the ray; another one shadows it */
            return h.light == light ? T * rd_transmittance(s, region, r, 0.0, h.t, rng, c) : 0.0;
        if (s->shapes[h.shape].material.kind != RD_MAT_INTERFACE) return 0.0;
        T *= rd_transmittance(s, region, r, 0.0, h.t, rng, c);
        region = h.medium_to;
        t0 += h.t;
        prev = h;
        from = &prev;
        r = rd_hit_spawn(&prev, r.d);
    }
    return T;
}
