/* photons.c: photon tracing (THEORY.md §3; Jensen and Christensen 1998; seed 001 §2).
 *
 * Photons leave the lights (a light chosen per photon with probability proportional to its
 * power), fly with the free-path engine's delta tracking, and at every real collision store
 * (position, propagation direction, scattered power = incident power x albedo) before going on
 * with Russian roulette on the albedo. Optionally the path segments (the flights between
 * events, clipped to the media bounds) are stored too, for the track-length estimate.
 *
 * Positions: the map stores float offsets from its origin (photonmap.h), which this file sets
 * to the centre of the media bounds, so a scene far from the world origin keeps float precision
 * relative to its own size. Offsets are taken in double, then rounded once.
 *
 * Determinism: photon i draws from the PCG32 stream (i, seed); photons are traced in blocks
 * whose results are concatenated in block order, so the map is the same whatever the thread
 * count. Several ranks (rd_photon_opts.comm) trace contiguous ranges of the blocks and gather
 * them in block order (gather_blocks), so the map is the same whatever the rank count too. */
#include "scene/rd_geom.h"
#include "transport/rd_path.h"
#include "bake/rd_photons.h"
#include "core/rd_core.h"

#include <omp.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define BLOCK 4096 /* photons per work unit */

typedef struct {
    const double *origin; /* the map's origin: stored positions are relative to it */
    pm_photon *ph;
    size_t n_ph, cap_ph;
    pm_segment *seg;
    size_t n_seg, cap_seg;
    int split;            /* also keep the indirect photons (depth > 1) apart, in ind */
    pm_photon *ind;
    size_t n_ind, cap_ind;
    double emitted[3], absorbed[3], escaped[3], carried[3], absorbed_surf[3];
    double scattered[3], hidden[3], caustic[3]; /* rd_photon_stats.power_scattered, _hidden, _caustic */
    int oom;
} block_out;

/* Append a photon to the array *arr (n, cap), growing it; sets b->oom when it cannot. */
static void push_to(block_out *b, pm_photon **arr, size_t *n, size_t *cap, vec3 x, vec3 d, vec3 power)
{
    if (*n == *cap) {
        size_t c = *cap ? 2 * *cap : 1024;
        pm_photon *p = realloc(*arr, c * sizeof *p);
        if (!p) { b->oom = 1; return; }
        *arr = p;
        *cap = c;
    }
    pm_photon *p = &(*arr)[(*n)++];
    p->pos[0] = (float)(x.x - b->origin[0]);
    p->pos[1] = (float)(x.y - b->origin[1]);
    p->pos[2] = (float)(x.z - b->origin[2]);
    p->dir[0] = (float)d.x; p->dir[1] = (float)d.y; p->dir[2] = (float)d.z;
    p->power[0] = (float)power.x; p->power[1] = (float)power.y; p->power[2] = (float)power.z;
}

/* Store the part of the flight o + t d, t in [0, tmax], that lies inside the media bounds. */
static void push_segment(block_out *b, const rd_scene *s, ray3 r, double tmax, vec3 power)
{
    double t0, t1;
    if (!rd_box_intersect(s->bmin, s->bmax, r, 0.0, tmax, &t0, &t1)) return;
    if (b->n_seg == b->cap_seg) {
        size_t cap = b->cap_seg ? 2 * b->cap_seg : 1024;
        pm_segment *p = realloc(b->seg, cap * sizeof *p);
        if (!p) { b->oom = 1; return; }
        b->seg = p;
        b->cap_seg = cap;
    }
    pm_segment *g = &b->seg[b->n_seg++];
    vec3 o = ray_at(r, t0);
    g->org[0] = (float)(o.x - b->origin[0]);
    g->org[1] = (float)(o.y - b->origin[1]);
    g->org[2] = (float)(o.z - b->origin[2]);
    g->dir[0] = (float)r.d.x; g->dir[1] = (float)r.d.y; g->dir[2] = (float)r.d.z;
    g->length = (float)(t1 - t0);
    g->power[0] = (float)power.x; g->power[1] = (float)power.y; g->power[2] = (float)power.z;
}

static void acc(double a[3], vec3 v) { a[0] += v.x; a[1] += v.y; a[2] += v.z; }

/* ---- Photons aimed at the glass (photons.aim; Jensen's projection maps, simplified) ------- */

rd_emission_aim rd_emission_aim_of(const rd_scene *s)
{
    rd_emission_aim a = {0, {0, 0, 0}, 0.0, 0.0};
    if (!(s->photons.aim > 0.0)) return a;
    vec3 lo = v3(INFINITY, INFINITY, INFINITY), hi = v3(-INFINITY, -INFINITY, -INFINITY);
    for (int i = 0; i < s->n_shapes; i++) {
        if (s->shapes[i].material.kind != RD_MAT_DIELECTRIC) continue;
        lo = v3(fmin(lo.x, s->shapes[i].mesh.bmin.x), fmin(lo.y, s->shapes[i].mesh.bmin.y), fmin(lo.z, s->shapes[i].mesh.bmin.z));
        hi = v3(fmax(hi.x, s->shapes[i].mesh.bmax.x), fmax(hi.y, s->shapes[i].mesh.bmax.y), fmax(hi.z, s->shapes[i].mesh.bmax.z));
    }
    if (!(lo.x <= hi.x)) return a; /* no glass: nothing to aim at */
    /* The sphere around the box's centre through the farthest vertex (for a ball, the ball
     * itself: the box's own bounding sphere is sqrt(3) times too wide) */
    a.centre = v3_scale(v3_add(lo, hi), 0.5);
    double r2 = 0.0;
    for (int i = 0; i < s->n_shapes; i++) {
        const rd_mesh *m = &s->shapes[i].mesh;
        if (s->shapes[i].material.kind != RD_MAT_DIELECTRIC) continue;
        for (size_t v = 0; v < m->n_vertices; v++) {
            vec3 d = v3_sub(v3(m->positions[3 * v], m->positions[3 * v + 1], m->positions[3 * v + 2]), a.centre);
            r2 = fmax(r2, v3_dot(d, d));
        }
    }
    a.on = 1;
    a.radius = sqrt(r2) * (1.0 + 1e-6) + 1e-9;
    a.share = s->photons.aim;
    return a;
}

/* The cone of directions from p that meet the aim's sphere: axis w, cos of its half-angle, and
 * 1 - that cos (computed without cancellation). 0 when p is inside the sphere. */
typedef struct { vec3 w; double cos_max, one_minus; } aim_cone;
static int cone_from(const rd_emission_aim *aim, vec3 p, aim_cone *k)
{
    vec3 to = v3_sub(aim->centre, p);
    double d2 = v3_dot(to, to), s2 = aim->radius * aim->radius / d2;
    if (!(s2 < 1.0)) return 0;
    k->w = v3_scale(to, 1.0 / sqrt(d2));
    k->cos_max = sqrt(1.0 - s2);
    k->one_minus = s2 / (1.0 + k->cos_max);
    return 1;
}
/* Uniform in the cone's solid angle (pdf 1 / (2 pi (1 - cos_max))). */
static vec3 cone_sample(const aim_cone *k, double u1, double u2)
{
    double c = 1.0 - u1 * k->one_minus, sn = sqrt(fmax(0.0, 1.0 - c * c)), phi = 2.0 * M_PI * u2;
    vec3 a, b;
    v3_basis(k->w, &a, &b);
    return v3_norm(v3_add(v3_scale(k->w, c), v3_add(v3_scale(a, sn * cos(phi)), v3_scale(b, sn * sin(phi)))));
}
static double cone_pdf(const aim_cone *k, vec3 d)
{
    /* 1 - cos(d, w) = |d - w|^2 / 2 for unit vectors, without the cancellation of 1 - dot */
    vec3 e = v3_sub(d, k->w);
    return 0.5 * v3_dot(e, e) <= k->one_minus ? 1.0 / (2.0 * M_PI * k->one_minus) : 0.0;
}

/* Emission sampling (rd_photons.h documents each light's distribution). With an aim (a scene
 * with glass and photons.aim > 0), a share of each point, spot, sphere and directional light's
 * photons leaves toward the bounding sphere of the glass: a one-sample mixture of the light's
 * own distribution and a uniform one over the directions (the disc, for a directional light)
 * that meet the sphere, each photon's power its emitted radiance over the mixture's density
 * (Veach 1997 §9.2.2), so the map's expected power in any region is the same as without; what
 * changes is that light the glass concentrates (a volume caustic) is carried by many photons of
 * lower power instead of a few. */
int rd_light_sample_emission(const rd_scene *s, const rd_light *l, const rd_emission_aim *aim,
                             pcg32 *rng, ray3 *r, vec3 *power)
{
    double u1 = pcg32_uniform(rng), u2 = pcg32_uniform(rng);
    vec3 centre = v3_scale(v3_add(s->bmin, s->bmax), 0.5);
    double R = rd_scene_radius(s);
    const int aimed = aim && aim->on && aim->share > 0.0;
    aim_cone k;
    switch (l->kind) {
    case RD_LIGHT_POINT:
        r->o = l->pos;
        if (aimed && cone_from(aim, l->pos, &k)) {
            double a = aim->share;
            r->d = pcg32_uniform(rng) < a ? cone_sample(&k, u1, u2) : rd_sample_sphere(u1, u2);
            *power = v3_scale(l->value, 1.0 / ((1.0 - a) / (4.0 * M_PI) + a * cone_pdf(&k, r->d)));
            return 1;
        }
        r->d = rd_sample_sphere(u1, u2);
        *power = v3_scale(l->value, 4.0 * M_PI); /* I / pdf, pdf = 1/(4 pi) */
        return 1;
    case RD_LIGHT_SPOT: {
        /* Uniform in the cone's solid angle; weight by the smooth falloff. Aimed as below. */
        r->o = l->pos;
        double a = 0.0;
        if (aimed && cone_from(aim, l->pos, &k)) {
            /* only where the cones overlap, and the spot's is not inside the aim's (then every
             * photon of the spot already meets the sphere) */
            double between = acos(fmax(-1.0, fmin(1.0, v3_dot(k.w, l->dir))));
            double spot = acos(l->cos_outer), cone = acos(k.cos_max);
            if (between < spot + cone && between + spot > cone) a = aim->share;
        }
        if (a > 0.0 && pcg32_uniform(rng) < a) {
            r->d = cone_sample(&k, u1, u2);
        } else {
            double c = 1.0 - u1 * (1.0 - l->cos_outer);
            double sn = sqrt(fmax(0.0, 1.0 - c * c)), phi = 2.0 * M_PI * u2;
            vec3 a1, b1;
            v3_basis(l->dir, &a1, &b1);
            r->d = v3_norm(v3_add(v3_scale(l->dir, c), v3_add(v3_scale(a1, sn * cos(phi)), v3_scale(b1, sn * sin(phi)))));
            if (a == 0.0) {
                double falloff = rd_spot_falloff(l, c);
                *power = v3_scale(l->value, falloff * 2.0 * M_PI * (1.0 - l->cos_outer));
                return 1;
            }
        }
        double cs = v3_dot(r->d, l->dir);
        if (cs < l->cos_outer) return 0; /* outside the spot: no light */
        double pdf = (1.0 - a) / (2.0 * M_PI * (1.0 - l->cos_outer)) + a * cone_pdf(&k, r->d);
        *power = v3_scale(l->value, rd_spot_falloff(l, cs) / pdf);
        return 1;
    }
    case RD_LIGHT_DIRECTIONAL: {
        /* A disc across the beam (its own radius, or the scene's), upstream of the scene. */
        double rad = l->radius > 0 ? l->radius : R;
        vec3 c0 = l->radius > 0 ? l->beam_center : centre;
        /* move the disc centre to the plane through the scene centre, then 2R upstream */
        c0 = v3_madd(c0, l->dir, v3_dot(v3_sub(centre, c0), l->dir) - 2.0 * R);
        vec3 a1, b1;
        v3_basis(l->dir, &a1, &b1);
        /* Aimed: a disc of the aim's radius around the aim's centre, in the same plane, where
         * it overlaps the beam's. */
        vec3 ca = aimed ? v3_madd(aim->centre, l->dir, v3_dot(v3_sub(c0, aim->centre), l->dir)) : c0;
        double apart = v3_len(v3_sub(ca, c0));
        double a = aimed && apart < rad + aim->radius && apart + rad > aim->radius ? aim->share : 0.0;
        int pick_aim = a > 0.0 && pcg32_uniform(rng) < a;
        double disc = pick_aim ? aim->radius : rad;
        double rr = disc * sqrt(u1), phi = 2.0 * M_PI * u2;
        r->o = v3_add(pick_aim ? ca : c0, v3_add(v3_scale(a1, rr * cos(phi)), v3_scale(b1, rr * sin(phi))));
        r->d = l->dir;
        if (a == 0.0) {
            *power = v3_scale(l->value, M_PI * rad * rad); /* E times the disc area */
            return 1;
        }
        vec3 off = v3_sub(r->o, c0), offa = v3_sub(r->o, ca);
        if (v3_dot(off, off) > rad * rad) return 0; /* outside the beam's disc */
        double pdf = (1.0 - a) / (M_PI * rad * rad) +
                     (v3_dot(offa, offa) <= aim->radius * aim->radius ? a / (M_PI * aim->radius * aim->radius) : 0.0);
        *power = v3_scale(l->value, 1.0 / pdf);
        return 1;
    }
    case RD_LIGHT_SPHERE: {
        /* Uniform point on the sphere, cosine-weighted outward direction. */
        vec3 n = rd_sample_sphere(u1, u2);
        double v1 = pcg32_uniform(rng), v2 = pcg32_uniform(rng);
        r->o = v3_madd(l->pos, n, l->radius * (1.0 + 1e-9));
        /* aimed where some of the cone lies in front of this point's tangent plane */
        if (aimed && cone_from(aim, r->o, &k) && v3_dot(k.w, n) > -sqrt(fmax(0.0, 1.0 - k.cos_max * k.cos_max))) {
            double area = 4.0 * M_PI * l->radius * l->radius;
            /* Aimed: the cone from this point; the mixture's density is this point's. */
            double a = aim->share;
            if (pcg32_uniform(rng) < a) {
                r->d = cone_sample(&k, v1, v2);
            } else {
                double rr = sqrt(v1), phi = 2.0 * M_PI * v2;
                vec3 a1, b1;
                v3_basis(n, &a1, &b1);
                r->d = v3_norm(v3_add(v3_scale(n, sqrt(fmax(0.0, 1.0 - v1))), v3_add(v3_scale(a1, rr * cos(phi)), v3_scale(b1, rr * sin(phi)))));
            }
            double cs = v3_dot(r->d, n);
            if (!(cs > 0.0)) return 0; /* into the light itself: no light */
            double pdf = (1.0 - a) * cs / M_PI + a * cone_pdf(&k, r->d);
            *power = v3_scale(l->value, cs * area / pdf); /* L cos A / pdf */
            return 1;
        }
        double rr = sqrt(v1), phi = 2.0 * M_PI * v2;
        vec3 a1, b1;
        v3_basis(n, &a1, &b1);
        r->d = v3_norm(v3_add(v3_scale(n, sqrt(fmax(0.0, 1.0 - v1))), v3_add(v3_scale(a1, rr * cos(phi)), v3_scale(b1, rr * sin(phi)))));
        *power = v3_scale(l->value, M_PI * 4.0 * M_PI * l->radius * l->radius); /* L pi A */
        return 1;
    }
    case RD_LIGHT_ENVIRONMENT: {
        /* Uniform direction; a disc of radius R across it, 2R upstream of the scene centre. */
        vec3 d = rd_sample_sphere(u1, u2);
        double v1 = pcg32_uniform(rng), v2 = pcg32_uniform(rng);
        double rr = R * sqrt(v1), phi = 2.0 * M_PI * v2;
        vec3 a, b;
        v3_basis(d, &a, &b);
        r->o = v3_add(v3_madd(centre, d, -2.0 * R), v3_add(v3_scale(a, rr * cos(phi)), v3_scale(b, rr * sin(phi))));
        r->d = d;
        *power = v3_scale(l->value, 4.0 * M_PI * M_PI * R * R); /* L (pi R^2) (4 pi) */
        return 1;
    }
    }
    return 0;
}

/* Whether photon i's collision at `depth` is stored under thinning (rd_photon_opts.keep): a hash
 * of the seed, the photon and the depth against keep, so the photon's stream is untouched. */
static int kept(const rd_photon_opts *o, size_t i, int depth)
{
    /* (the tag keeps the hash apart from pcg32_seed's, rd_math.h, which mixes alike) */
    uint64_t h = rd_mix64(o->seed ^ 0x7468696e6e696e67ULL ^ rd_mix64((uint64_t)i * 0x9E3779B97F4A7C15ULL + (uint64_t)depth));
    return (double)(h >> 11) * 0x1.0p-53 < o->keep;
}

static void trace_block(const rd_scene *s, const rd_photon_opts *o, const double *cdf,
                        const rd_emission_aim *aim, size_t first, size_t count, block_out *b,
                        rd_track_counters *tc)
{
    const double inv_n = 1.0 / (double)o->count;
    const int thin = o->keep > 0.0 && o->keep < 1.0;
    for (size_t i = first; i < first + count; i++) {
        pcg32 rng = pcg32_seed(i, 0x70686f746f6eULL, o->seed);
        /* Choose a light with probability proportional to its power (binary search). */
        double u = pcg32_uniform(&rng);
        int lo = 0, hi = s->n_lights - 1;
        while (lo < hi) {
            int mid = (lo + hi) / 2;
            if (u < cdf[mid + 1]) hi = mid; else lo = mid + 1;
        }
        double p_light = cdf[lo + 1] - cdf[lo];
        ray3 r;
        vec3 beta;
        if (!rd_light_sample_emission(s, &s->lights[lo], aim, &rng, &r, &beta)) continue;
        beta = v3_scale(beta, inv_n / p_light); /* photon power: Phi_l / (N p_l) */
        acc(b->emitted, beta);
        /* rd_photon_stats.power_caustic: a photon whose first event (an interface is none) is a
         * specular surface is on an L S+ path, and so is every collision it makes later;
         * power_hidden: such a photon from a point, spot or directional light. */
        const int delta_light = rd_light_is_delta(&s->lights[lo]);
        int events = 0, caustic = 0;
        /* The region the photon starts in (rd_scene.h "Surfaces in the transport"). */
        int region = rd_scene_region_at(s, r.o), crossings = 0;
        rd_hit h, prev;
        const rd_hit *from = NULL;
        for (int depth = 1;; depth++) {
            /* Sphere lights are opaque to camera paths and shadow rays, so to photons too: a
             * photon that reaches one ends there (counted as escaped). A surface ends the
             * flight too. */
            int got = rd_scene_intersect(s, r, INFINITY, from, &h);
            double t_light = got ? h.t : INFINITY;
            rd_collision col = rd_sample_free_path(s, region, r, t_light, &rng, tc);
            /* With o->reachable, a hidden photon (caustic, from a delta light) stores nothing. */
            const int store = !o->count_only && !(o->reachable && caustic && delta_light);
            /* The first flight carries direct light: store it only with store_direct, as for
             * the photons, so k-NN and track-length bakes see the same light. */
            if (o->segments && store && (depth > 1 || o->store_direct))
                push_segment(b, s, r, col.hit ? col.t : t_light, beta);
            /* Weighted trackers (seed 002 Alg. 2-3) return a path weight for the flight; the
             * analog trackers return 1. (Segments keep the flowing power before it: the
             * track-length estimate assumes an analog tracker, the default.) */
            if (col.weight != 1.0) beta = v3_scale(beta, col.weight);
            if (!col.hit && got && h.shape >= 0) {
                /* At a surface, in IMPORTANCE mode (rd_geom.h): a refraction carries the
                 * power on unscaled, the Fresnel choice splitting it between the two
                 * branches, so the photon map holds the volume caustics. An interface only
                 * changes the region. Nothing is stored on surfaces. */
                const rd_material *mat = &s->shapes[h.shape].material;
                prev = h;
                from = &prev;
                if (mat->kind == RD_MAT_INTERFACE) {
                    if (++crossings > 4096) break;
                    region = prev.medium_to;
                    r = rd_hit_spawn(&prev, r.d);
                    depth--; /* not an event */
                    continue;
                }
                if (depth >= o->max_depth) { acc(b->carried, beta); break; }
                double ue = pcg32_uniform(&rng), u1 = pcg32_uniform(&rng), u2 = pcg32_uniform(&rng);
                rd_surface_sample ss;
                if (!rd_material_sample(mat, r.d, prev.ng, prev.ns, RD_TRANSPORT_IMPORTANCE, ue, u1, u2, &ss)) {
                    acc(b->absorbed_surf, beta); /* nothing leaves: the surface keeps it */
                    break;
                }
                if (events++ == 0 && ss.specular) caustic = 1;
                vec3 out = v3_mul(beta, ss.weight);
                acc(b->absorbed_surf, v3_sub(beta, out)); /* diffuse: (1 - albedo) x incident */
                /* Russian roulette on the weight (the albedo at a diffuse surface; 1 for glass) */
                double p = fmin(1.0, v3_maxc(ss.weight));
                if (p <= 0.0) break;
                if (p < 1.0) {
                    if (pcg32_uniform(&rng) >= p) break;
                    out = v3_scale(out, 1.0 / p);
                }
                beta = out;
                region = ss.crossed ? prev.medium_to : prev.medium_from;
                r = rd_hit_spawn(&prev, ss.d);
                continue;
            }
            if (!col.hit) { acc(b->escaped, beta); break; }
            from = NULL;
            const rd_medium *m = col.medium;
            vec3 x = ray_at(r, col.t);
            vec3 scattered = v3_mul(beta, m->albedo);
            events++;
            acc(b->scattered, scattered);
            if (caustic) acc(b->caustic, scattered);
            if (caustic && delta_light) acc(b->hidden, scattered);
            /* Store the scattered power; skip first collisions when NEE supplies direct light.
             * With thinning (o->keep), one choice for both maps, so the indirect map stays a
             * subset of the other. */
            if (store && (!thin || kept(o, i, depth))) {
                vec3 stored = thin ? v3_scale(scattered, 1.0 / o->keep) : scattered;
                if (depth > 1 || o->store_direct) push_to(b, &b->ph, &b->n_ph, &b->cap_ph, x, r.d, stored);
                if (depth > 1 && b->split) push_to(b, &b->ind, &b->n_ind, &b->cap_ind, x, r.d, stored);
            }
            acc(b->absorbed, v3_sub(beta, scattered)); /* expected absorption at this event */
            if (depth >= o->max_depth) { acc(b->carried, scattered); break; }
            /* Russian roulette on the albedo: survive with p = max channel, power x albedo / p. */
            double p = v3_maxc(m->albedo);
            if (p <= 0.0 || pcg32_uniform(&rng) >= p) break;
            beta = v3_scale(scattered, 1.0 / p);
            r.o = x;
            r.d = rd_hg_sample(m->g, r.d, pcg32_uniform(&rng), pcg32_uniform(&rng));
        }
        if (b->oom) return;
    }
}

/* The power sums a block keeps, in the order gather_blocks sends them. */
enum { BLOCK_SUMS = 24 };
static void block_sums_get(const block_out *b, double *v)
{
    const double *src[8] = {b->emitted, b->absorbed, b->escaped, b->carried, b->absorbed_surf, b->scattered, b->hidden, b->caustic};
    for (int k = 0; k < 8; k++) memcpy(v + 3 * k, src[k], 3 * sizeof(double));
}
static void block_sums_set(block_out *b, const double *v)
{
    double *dst[8] = {b->emitted, b->absorbed, b->escaped, b->carried, b->absorbed_surf, b->scattered, b->hidden, b->caustic};
    for (int k = 0; k < 8; k++) memcpy(dst[k], v + 3 * k, 3 * sizeof(double));
}

/* Copy the records of blocks [b0, b1) into one array (NULL when there are none), freeing each
 * block's own; *oom on failure. `which` 0: photons, 1: segments, 2: indirect photons. */
static void *concat_records(block_out *blocks, size_t b0, size_t b1, int which, size_t n, int *oom)
{
    size_t es = which == 1 ? sizeof(pm_segment) : sizeof(pm_photon);
    char *out = n ? malloc(n * es) : NULL;
    if (n && !out) *oom = 1;
    size_t at = 0;
    for (size_t bi = b0; bi < b1; bi++) {
        block_out *b = &blocks[bi];
        const void *src = which == 0 ? (const void *)b->ph : which == 1 ? (const void *)b->seg : (const void *)b->ind;
        size_t m = which == 0 ? b->n_ph : which == 1 ? b->n_seg : b->n_ind;
        if (out && m) memcpy(out + at * es, src, m * es);
        at += m;
        if (which == 0) free(b->ph), b->ph = NULL;
        else if (which == 1) free(b->seg), b->seg = NULL;
        else free(b->ind), b->ind = NULL;
    }
    return out;
}

/* Several ranks: this rank traced blocks [b0, b1) of nblocks. Gather every rank's photons,
 * segments and indirect photons, in block order, into blocks[0] (the other blocks then hold
 * none) and every block's power sums into blocks[bi], and sum the counters, so that the caller
 * adds to the map and sums the power exactly as one process would (power in block order: the
 * same additions in the same order, whatever the rank count). v (3 K + 2) and counts (K) are
 * the caller's scratch. Collective: a reduce of the counts, an agreement on the allocations,
 * four gathers. */
static rd_status gather_blocks(const rd_comm *c, block_out *blocks, size_t nblocks, size_t b0, size_t b1,
                               uint64_t *v, size_t *counts, uint64_t *coll, uint64_t *look, rd_photon_stats *ps,
                               char *err, size_t errlen)
{
    const int K = c->size, r = c->rank;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    memset(v, 0, (3 * (size_t)K + 2) * sizeof *v);
    for (size_t bi = b0; bi < b1; bi++) {
        v[3 * r] += blocks[bi].n_ph;
        v[3 * r + 1] += blocks[bi].n_seg;
        v[3 * r + 2] += blocks[bi].n_ind;
    }
    v[3 * K] = *coll, v[3 * K + 1] = *look;
    c->reduce(c->user, v, 3 * (size_t)K + 2, RD_COMM_UINT64, RD_COMM_SUM, -1);
    size_t tot[3] = {0, 0, 0};
    for (int k = 0; k < K; k++)
        for (int j = 0; j < 3; j++) tot[j] += v[3 * k + j];
    int oom = 0;
    void *mine[3] = {NULL, NULL, NULL}, *all[3] = {NULL, NULL, NULL};
    double *sums_mine = NULL, *sums_all = NULL;
    for (int j = 0; !oom && j < 3; j++) {
        mine[j] = concat_records(blocks, b0, b1, j, v[3 * r + j], &oom);
        size_t es = j == 1 ? sizeof(pm_segment) : sizeof(pm_photon);
        if (tot[j] && !(all[j] = malloc(tot[j] * es))) oom = 1;
    }
    if (!oom) {
        sums_mine = malloc((b1 - b0 + 1) * BLOCK_SUMS * sizeof *sums_mine);
        sums_all = malloc(nblocks * BLOCK_SUMS * sizeof *sums_all);
        oom = !sums_mine || !sums_all;
    }
    if (oom)
        snprintf(err, errlen, "photon tracing: out of memory gathering the ranks' photons (%zu photons, %zu "
                              "segments)", tot[0], tot[1]);
    rd_status st = rd_comm_agree(c, oom ? RD_ERR_NOMEM : RD_OK, "photon tracing: gathering the photons", err, errlen);
    if (st == RD_OK) {
        for (int j = 0; j < 3; j++) {
            for (int k = 0; k < K; k++) counts[k] = v[3 * k + j];
            c->allgatherv(c->user, mine[j], all[j], counts, j == 1 ? sizeof(pm_segment) : sizeof(pm_photon));
        }
        for (size_t bi = b0; bi < b1; bi++) block_sums_get(&blocks[bi], sums_mine + (bi - b0) * BLOCK_SUMS);
        for (int k = 0; k < K; k++) counts[k] = nblocks * (size_t)(k + 1) / K - nblocks * (size_t)k / K;
        c->allgatherv(c->user, sums_mine, sums_all, counts, BLOCK_SUMS * sizeof(double));
        for (size_t bi = 0; bi < nblocks; bi++) {
            block_sums_set(&blocks[bi], sums_all + bi * BLOCK_SUMS);
            blocks[bi].n_ph = blocks[bi].n_seg = blocks[bi].n_ind = 0;
        }
        blocks[0].ph = all[0], blocks[0].seg = all[1], blocks[0].ind = all[2];
        blocks[0].n_ph = tot[0], blocks[0].n_seg = tot[1], blocks[0].n_ind = tot[2];
        *coll = v[3 * K], *look = v[3 * K + 1];
        clock_gettime(CLOCK_MONOTONIC, &t1);
        ps->gather_seconds = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
        ps->gather_bytes = (tot[0] + tot[2]) * sizeof(pm_photon) + tot[1] * sizeof(pm_segment) +
                           nblocks * BLOCK_SUMS * sizeof(double);
    } else {
        for (int j = 0; j < 3; j++) free(all[j]);
    }
    for (int j = 0; j < 3; j++) free(mine[j]);
    free(sums_mine);
    free(sums_all);
    return st;
}

rd_status rd_trace_photons(const rd_scene *s, const rd_photon_opts *o, pm_map *map,
                           rd_photon_stats *st, char *err, size_t errlen)
{
    return rd_trace_photons_split(s, o, map, NULL, st, err, errlen);
}

rd_status rd_trace_photons_split(const rd_scene *s, const rd_photon_opts *o, pm_map *map,
                                 pm_map *indirect, rd_photon_stats *st, char *err, size_t errlen)
{
    memset(st, 0, sizeof *st);
    if (o->count == 0 || o->max_depth < 1) {
        snprintf(err, errlen, "photon tracing: count and max_depth must be >= 1");
        return RD_ERR_ARG;
    }
    /* Stored positions are offsets from the map's origin: the media centre for a new map (an
     * appended map keeps the origin it has). */
    char pmerr[256];
    if (pm_map_photon_count(map) == 0 && pm_map_segment_count(map) == 0) {
        vec3 c = v3_scale(v3_add(s->bmin, s->bmax), 0.5);
        double centre[3] = {c.x, c.y, c.z};
        if (pm_map_set_origin(map, centre, pmerr, sizeof pmerr) != PM_OK) {
            snprintf(err, errlen, "photon map: %s", pmerr);
            return RD_ERR_INTERNAL;
        }
    }
    double origin[3];
    pm_map_origin(map, origin);
    if (indirect) {
        /* The indirect map stores its positions from the same origin, so that its photons are
         * bit for bit those a trace of its own (store_direct 0) would store. */
        if (pm_map_photon_count(indirect) != 0 || pm_map_segment_count(indirect) != 0 ||
            pm_map_set_origin(indirect, origin, pmerr, sizeof pmerr) != PM_OK) {
            snprintf(err, errlen, "photon tracing: the indirect map must be new and empty");
            return RD_ERR_INTERNAL;
        }
    }
    /* Light selection CDF by power (luminance). */
    double *cdf = calloc((size_t)s->n_lights + 1, sizeof *cdf);
    if (!cdf) {
        snprintf(err, errlen, "photon tracing: out of memory for the light selection table "
                              "(%d lights)", s->n_lights);
        return rd_comm_agree(o->comm, RD_ERR_NOMEM, "photon tracing", err, errlen);
    }
    double R = rd_scene_radius(s);
    for (int i = 0; i < s->n_lights; i++) cdf[i + 1] = cdf[i] + rd_light_power(&s->lights[i], R);
    if (s->n_lights == 0 || !(cdf[s->n_lights] > 0)) {
        free(cdf);
        snprintf(err, errlen, "%s: lights: no light emits power; nothing to trace", s->path);
        return RD_ERR_SCENE;
    }
    for (int i = 1; i <= s->n_lights; i++) cdf[i] /= cdf[s->n_lights];

    size_t nblocks = o->count / BLOCK + (o->count % BLOCK != 0); /* no overflow at SIZE_MAX */
    /* Several ranks: this rank's contiguous range of blocks, and the gather's scratch. */
    const rd_comm *comm = o->comm && o->comm->size > 1 ? o->comm : NULL;
    size_t b0 = comm ? nblocks * (size_t)comm->rank / comm->size : 0;
    size_t b1 = comm ? nblocks * (size_t)(comm->rank + 1) / comm->size : nblocks;
    block_out *blocks = calloc(nblocks, sizeof *blocks);
    uint64_t *gv = comm ? calloc(3 * (size_t)comm->size + 2, sizeof *gv) : NULL;
    size_t *gcounts = comm ? calloc((size_t)comm->size, sizeof *gcounts) : NULL;
    if (!blocks || (comm && (!gv || !gcounts))) {
        free(cdf);
        free(blocks);
        free(gv);
        free(gcounts);
        snprintf(err, errlen, "photon tracing: out of memory for the %zu work blocks of %zu photons",
                 nblocks, o->count);
        return rd_comm_agree(comm, RD_ERR_NOMEM, "photon tracing", err, errlen);
    }
    for (size_t bi = 0; bi < nblocks; bi++) {
        blocks[bi].origin = origin;
        blocks[bi].split = indirect != NULL;
    }
    int nthreads = o->threads > 0 ? o->threads : omp_get_max_threads();
    const rd_emission_aim aim = rd_emission_aim_of(s);
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    uint64_t coll = 0, look = 0;
#pragma omp parallel for num_threads(nthreads) schedule(dynamic, 1) reduction(+ : coll, look)
    for (size_t bi = b0; bi < b1; bi++) {
        if (o->cancel && *o->cancel) continue; /* cancelled: skip the blocks not begun */
        size_t first = bi * BLOCK, cnt = first + BLOCK <= o->count ? BLOCK : o->count - first;
        rd_track_counters tc = {0};
        trace_block(s, o, cdf, &aim, first, cnt, &blocks[bi], &tc);
        coll += tc.collisions;
        look += tc.lookups;
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    st->seconds = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
    st->collisions = coll;
    st->lookups = look;
    st->emitted = o->count;

    rd_status status = RD_OK;
    if (o->cancel && *o->cancel) {
        snprintf(err, errlen, "%s: photon tracing interrupted", s->path);
        status = RD_ERR_CANCELLED; /* nothing is added to the maps; the blocks are freed below */
    }
    for (size_t bi = b0; status == RD_OK && bi < b1; bi++)
        if (blocks[bi].oom) {
            snprintf(err, errlen, "photon tracing: out of memory for the photons and segments of "
                                  "block %zu (%zu photons, %zu segments so far)", bi, blocks[bi].n_ph,
                     blocks[bi].n_seg);
            status = RD_ERR_NOMEM;
        }
    if (comm) { /* every rank's outcome, then every rank's records in block order */
        char what[1100];
        snprintf(what, sizeof what, "%s: photon tracing", s->path);
        status = rd_comm_agree(comm, status, what, err, errlen);
        if (status == RD_OK) status = gather_blocks(comm, blocks, nblocks, b0, b1, gv, gcounts, &coll, &look, st, err, errlen);
        st->collisions = coll;
        st->lookups = look;
        clock_gettime(CLOCK_MONOTONIC, &t1); /* the wait for the slowest rank and the gather too */
        st->seconds = (t1.tv_sec - t0.tv_sec) + 1e-9 * (t1.tv_nsec - t0.tv_nsec);
    }
    free(gv);
    free(gcounts);
    for (size_t bi = 0; bi < nblocks; bi++) {
        block_out *b = &blocks[bi];
        pm_status ps = PM_OK;
        if (status == RD_OK) ps = pm_map_add_photons(map, b->ph, b->n_ph, pmerr, sizeof pmerr);
        if (status == RD_OK && ps == PM_OK) ps = pm_map_add_segments(map, b->seg, b->n_seg, pmerr, sizeof pmerr);
        if (status == RD_OK && ps == PM_OK && indirect) ps = pm_map_add_photons(indirect, b->ind, b->n_ind, pmerr, sizeof pmerr);
        if (ps != PM_OK) {
            snprintf(err, errlen, "photon map: %s", pmerr);
            status = ps == PM_ERR_NOMEM ? RD_ERR_NOMEM : RD_ERR_INTERNAL;
        }
        for (int c = 0; c < 3; c++) {
            st->power_emitted[c] += b->emitted[c];
            st->power_absorbed[c] += b->absorbed[c];
            st->power_escaped[c] += b->escaped[c];
            st->power_carried[c] += b->carried[c];
            st->power_absorbed_surfaces[c] += b->absorbed_surf[c];
            st->power_scattered[c] += b->scattered[c];
            st->power_hidden[c] += b->hidden[c];
            st->power_caustic[c] += b->caustic[c];
        }
        st->stored += b->n_ph;
        st->segments += b->n_seg;
        free(b->ph);
        free(b->seg);
        free(b->ind);
    }
    free(blocks);
    free(cdf);
    return status;
}

double rd_phase_hg_cb(double cos_theta, void *user)
{
    return rd_hg_eval(*(const double *)user, cos_theta);
}

/* ---- Light that only L S+ paths carry ------------------------------------------------------ */

rd_status rd_hidden_light(const rd_scene *s, size_t count, int threads, double *share, double *caustic, char *err,
                          size_t errlen)
{
    *share = 0.0;
    if (caustic) *caustic = 0.0;
    int glass = 0;
    double power = 0.0, R = rd_scene_radius(s);
    for (int i = 0; i < s->n_shapes; i++) glass |= s->shapes[i].material.kind == RD_MAT_DIELECTRIC;
    /* the lights whose L S+ light is asked for: the delta lights, and with *caustic every light */
    for (int i = 0; i < s->n_lights; i++)
        if (caustic || rd_light_is_delta(&s->lights[i])) power += rd_light_power(&s->lights[i], R);
    /* no L S+ path into a medium (and no trace: one whose lights emit nothing would fail) */
    if (!glass || !(power > 0.0) || s->n_media == 0) return RD_OK;
    pm_map *map = pm_map_new();
    if (!map) {
        snprintf(err, errlen, "%s: out of memory for the photon map of the check for light by way of glass", s->path);
        return RD_ERR_NOMEM;
    }
    /* Its own seed (the check must not depend on the bake's photons.seed); nothing stored (the
     * power sums only), and at most 64 events a photon: the power a longer path carries is a
     * scene's last few per cent, counted as carried, and the check must stay short at load. */
    rd_photon_opts o = {.count = count, .store_direct = 1, .segments = 0, .count_only = 1,
                        .max_depth = s->photons.max_depth < 64 ? s->photons.max_depth : 64,
                        .seed = 0x68696464656eULL, .threads = threads};
    rd_photon_stats st;
    char msg[RD_ERRLEN];
    rd_status rs = rd_trace_photons(s, &o, map, &st, msg, sizeof msg);
    pm_map_free(map);
    if (rs) {
        snprintf(err, errlen, "%s: the check for light by way of glass: %s", s->path, msg);
        return rs;
    }
    double all = v3_lum(v3(st.power_scattered[0], st.power_scattered[1], st.power_scattered[2]));
    double hid = v3_lum(v3(st.power_hidden[0], st.power_hidden[1], st.power_hidden[2]));
    double cau = v3_lum(v3(st.power_caustic[0], st.power_caustic[1], st.power_caustic[2]));
    *share = all > 0.0 ? hid / all : 0.0;
    if (caustic) *caustic = all > 0.0 ? cau / all : 0.0;
    return RD_OK;
}
