/* beam_connect.c: the path loops' beam connections (settings.beam_connect; docs/free-path.md
 * "Beam connections"). A directional beam (a directional light with a radius) lights only a thin
 * cylinder, so the light it scatters twice or more reaches a path only when one of the path's
 * collisions lands inside the cylinder and its next-event estimate finds the light. Where the
 * medium scatters forward (beam.json: g = 0.85) that is rare and bright: the light the beam
 * scatters forward along itself reaches a vertex x near the beam only from upstream points y on
 * the axis, and a phase-sampled flight from x finds them only when it happens to head up the
 * beam (docs/benchmarks.md, "Session 30": the tail of `true` on beam.json).
 *
 * The strategy. At every scattering vertex x of a path (after `delta`'s throughput roulette, or
 * after guided-unbiased's vertex policy has decided the vertex's roulette and splitting: one
 * connection for all its copies; transport/path.c), a point y inside the cylinder is drawn and
 * connected to x:
 *     C_B = w_B f_p(d . w) T(x, y) sigma_s(y) L_nee(y, w) / (|y - x|^2 p_B(y)),  w = (y - x)/|y - x|,
 * with f_p the phase function at x (d the way the path arrived), T(x, y) a transmittance
 * estimate, L_nee(y, w) next-event estimation at y toward the beam for a path arriving along w
 * (the phase at y, the irradiance, the transmittance to the light: rd_nee_light), and p_B the
 * density of y per unit volume. This is the second way to build the vertex y that the path
 * builds by phase sampling w and delta tracking to a collision at y, then next-event estimation
 * at y; the two are combined by the balance heuristic (Veach 1997 §9.2) in the volume measure
 * at y:
 *     p_A(y) = p_dir(w) sigma~ exp(-sigma~ |y - x|) / |y - x|^2,   w_B = p_B / (p_A + p_B),
 * and the collision's next-event estimate toward the beam takes w_A = 1 - w_B. sigma~ is the
 * global majorant of the beam's medium (the one its axis crosses longest): p_A stands in for
 * delta tracking's collision density, exact in a homogeneous medium, and the weights need only
 * be the same function of (x, y) on both sides to sum to one (as the equiangular strategy's
 * stand-in: equiangular.c).
 *
 * Surfaces and media. The path builds y from x only by a straight flight in x's region: a
 * surface on the way ends the flight, and the collision after it is not weighted (path.c clears
 * `prev_scatter`). So the connection is blocked by any surface or sphere light between x and y,
 * and y's medium (sigma_s, albedo, phase) is the one x's region holds at y, which may be
 * another box medium than x's.
 *
 * p_B. The axis is a(s) = c + s D (D the light's direction), s in [s0, s1] within the media's
 * bounds.
 * Seen from x, at axial coordinate s_x and distance h from the axis (at least the radius R:
 * the density stays bounded where x lies inside the beam), a point a(s) lies at the angle
 * theta = atan((s - s_x) / h), and ds = (h^2 + (s - s_x)^2) / h dtheta: the 1 / |y - x|^2 of
 * C_B is uniform in theta (Kulla & Fajardo's equiangular sampling). What is not is the phase at
 * y: light travelling along D scatters toward x at the cosine D . (x - y)/|x - y| = -sin theta
 * (for y on the axis), and a forward-scattering medium sends almost all of it to points
 * downstream. So theta is drawn from an even mixture of the uniform density on [theta0, theta1]
 * and the density proportional to HG(g, -sin theta) there, the latter from a table of
 * RD_BC_BINS bins over [-pi/2, pi/2] (piecewise constant: its density is exact, what matters for
 * the estimate's weight), and y = a(s) plus a uniform point of the disc of radius R across the
 * axis:
 *     p_B(y) = p_theta(theta) h / (h^2 + (s - s_x)^2) / (pi R^2)
 * (the disc is across D, so (s, disc) is a volume-preserving parametrisation).
 *
 * Roulette. Most connections carry little: the phase at x or y far from its peak, or y far
 * away. Before the two transmittances (the connection's cost) the estimate without them,
 *     P = w_B f_p p_y sigma_s(y) / (|y - x|^2 p_B)   (times the irradiance; T <= 1),
 * decides: the connection goes on with probability q = min(1, P / RD_BC_ROULETTE), weighted
 * 1 / q (unbiased: the weights w_A, w_B do not change). */
#include "scene/rd_geom.h"
#include "transport/rd_transport.h"

#include <math.h>

/* The roulette's threshold on P (above): chosen of 0.03, 0.1 and 0.3 on the calibration scenes
 * beam-vdb and smoke-vdb, within the rounds' spread of each other (docs/free-path.md, "Beam
 * connections"). */
#define RD_BC_ROULETTE 0.1
/* The share of the phase-shaped part of the angle's mixture (above): an even split (first
 * tried on beam.json, a benchmark scene: docs/benchmarks.md "Session 31"). A screen of 0.1, 0.25,
 * 0.5 and 0.75 on the calibration scenes beam-vdb and smoke-vdb (its beam narrowed) found no
 * share clear of the seeds' spread (docs/benchmarks.md "Session 32"), so it stays. */
#define RD_BC_PHASE_SHARE 0.5

int rd_beam_connect_setup(rd_scene *s)
{
    rd_beam_connect *bc = &s->beam_connect;
    bc->light = -1;
    for (int i = 0; i < s->n_lights; i++) {
        const rd_light *l = &s->lights[i];
        if (l->kind != RD_LIGHT_DIRECTIONAL || !(l->radius > 0.0)) continue;
        /* the axis from where it enters the first medium's bounds to where it leaves the
         * last's; the medium it crosses longest gives the table its g, one that fills its
         * bounds before one held inside a shape (whose bounds are the shape's box) */
        ray3 axis = {l->beam_center, l->dir};
        double s0 = INFINITY, s1 = -INFINITY, longest = 0.0, volume = 0.0;
        int best = -1, best_held = 1;
        for (int k = 0; k < s->n_media; k++) {
            const rd_medium *m = &s->media[k];
            double a, b;
            if (!(m->sigma_maj > 0.0)) continue; /* a clear medium: nothing to scatter */
            if (!rd_box_intersect(m->bmin, m->bmax, axis, -1e30, 1e30, &a, &b) || !(b > a)) continue;
            s0 = fmin(s0, a), s1 = fmax(s1, b);
            vec3 e = v3_sub(m->bmax, m->bmin);
            volume += e.x * e.y * e.z;
            int held = m->bound && k != s->fill_medium; /* inside a shape */
            if (best < 0 || held < best_held || (held == best_held && b - a > longest))
                best = k, best_held = held, longest = b - a;
        }
        if (best < 0) continue;
        const rd_medium *m = &s->media[best];
        bc->light = i;
        bc->s0 = s0, bc->s1 = s1;
        bc->medium = best;
        bc->share = M_PI * l->radius * l->radius * (s1 - s0) / volume;
        bc->breadth = bc->share * (1.0 - fabs(m->g)) * (1.0 - fabs(m->g)); /* load.c */
        bc->sigma_bar = m->sigma_maj;
        double acc = 0.0;
        bc->cdf[0] = 0.0;
        for (int k = 0; k < RD_BC_BINS; k++) {
            double th = -0.5 * M_PI + M_PI * (k + 0.5) / RD_BC_BINS;
            acc += rd_hg_eval(m->g, -sin(th));
            bc->cdf[k + 1] = acc;
        }
        return 1;
    }
    return 0;
}

/* The table's CDF at theta (linear within a bin), and its density per unit theta. */
static double table_cdf(const rd_beam_connect *bc, double th)
{
    double u = (th + 0.5 * M_PI) / M_PI * RD_BC_BINS;
    if (!(u > 0.0)) return 0.0;
    if (u >= RD_BC_BINS) return bc->cdf[RD_BC_BINS];
    int k = (int)u;
    return bc->cdf[k] + (u - k) * (bc->cdf[k + 1] - bc->cdf[k]);
}
static double table_density(const rd_beam_connect *bc, double th)
{
    int k = (int)((th + 0.5 * M_PI) / M_PI * RD_BC_BINS);
    k = k < 0 ? 0 : k >= RD_BC_BINS ? RD_BC_BINS - 1 : k;
    return (bc->cdf[k + 1] - bc->cdf[k]) * RD_BC_BINS / M_PI;
}
/* theta with table_cdf(theta) = c, c in [0, cdf[RD_BC_BINS]]. */
static double table_invert(const rd_beam_connect *bc, double c)
{
    int lo = 0, hi = RD_BC_BINS;
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (bc->cdf[mid] <= c) lo = mid;
        else hi = mid;
    }
    double w = bc->cdf[lo + 1] - bc->cdf[lo];
    double f = w > 0.0 ? (c - bc->cdf[lo]) / w : 0.5;
    return -0.5 * M_PI + M_PI * (lo + f) / RD_BC_BINS;
}

/* x's axial coordinate *sx, distance from the axis (at least R), and the angles of the axis'
 * ends; 0 when the span is empty. */
static int seen_from(const rd_scene *s, vec3 x, double *sx, double *h, double *th0, double *th1)
{
    const rd_beam_connect *bc = &s->beam_connect;
    const rd_light *l = &s->lights[bc->light];
    vec3 q = v3_sub(x, l->beam_center);
    *sx = v3_dot(q, l->dir);
    vec3 perp = v3_madd(q, l->dir, -*sx);
    *h = fmax(sqrt(v3_dot(perp, perp)), l->radius);
    *th0 = atan((bc->s0 - *sx) / *h);
    *th1 = atan((bc->s1 - *sx) / *h);
    return *th1 > *th0;
}

double rd_beam_connect_pdf(const rd_scene *s, vec3 x, vec3 y)
{
    const rd_beam_connect *bc = &s->beam_connect;
    if (bc->light < 0) return 0.0;
    const rd_light *l = &s->lights[bc->light];
    vec3 q = v3_sub(y, l->beam_center);
    double sy = v3_dot(q, l->dir);
    vec3 perp = v3_madd(q, l->dir, -sy);
    if (v3_dot(perp, perp) > l->radius * l->radius || sy < bc->s0 || sy > bc->s1) return 0.0;
    double sx, h, th0, th1;
    if (!seen_from(s, x, &sx, &h, &th0, &th1)) return 0.0;
    double th = atan((sy - sx) / h);
    /* the sampler draws uniformly in theta alone where the table has no mass over the span */
    double Z = table_cdf(bc, th1) - table_cdf(bc, th0), p;
    if (Z > 0.0) p = (1.0 - RD_BC_PHASE_SHARE) / (th1 - th0) + RD_BC_PHASE_SHARE * table_density(bc, th) / Z;
    else p = 1.0 / (th1 - th0);
    return p * h / (h * h + (sy - sx) * (sy - sx)) / (M_PI * l->radius * l->radius);
}

int rd_beam_connect_sample(const rd_scene *s, vec3 x, double u_mix, double u_th, double u1, double u2,
                           vec3 *y, double *pdf)
{
    const rd_beam_connect *bc = &s->beam_connect;
    double sx, h, th0, th1;
    *pdf = 0.0;
    if (bc->light < 0 || !seen_from(s, x, &sx, &h, &th0, &th1)) return 0;
    double C0 = table_cdf(bc, th0), C1 = table_cdf(bc, th1), th;
    if (u_mix < RD_BC_PHASE_SHARE && C1 > C0) th = table_invert(bc, C0 + u_th * (C1 - C0));
    else th = th0 + u_th * (th1 - th0);
    th = fmin(fmax(th, th0), th1);
    const rd_light *l = &s->lights[bc->light];
    vec3 e1, e2;
    v3_basis(l->dir, &e1, &e2);
    double rho = l->radius * sqrt(u1), phi = 2.0 * M_PI * u2;
    vec3 a = v3_madd(l->beam_center, l->dir, sx + h * tan(th));
    *y = v3_add(a, v3_add(v3_scale(e1, rho * cos(phi)), v3_scale(e2, rho * sin(phi))));
    *pdf = rd_beam_connect_pdf(s, x, *y);
    return *pdf > 0.0;
}

double rd_beam_connect_path_pdf(const rd_scene *s, double dir_pdf, double dist)
{
    double sb = s->beam_connect.sigma_bar;
    return dir_pdf * sb * exp(-sb * dist) / (dist * dist);
}

vec3 rd_beam_connect_estimate(const rd_scene *s, int region, vec3 x, vec3 d, const rd_medium *m,
                              const rd_dir_mix *mx, pcg32 *rng, rd_track_counters *c)
{
    vec3 zero = v3(0, 0, 0);
    const rd_beam_connect *bc = &s->beam_connect;
    double u_mix = pcg32_uniform(rng), u_th = pcg32_uniform(rng), u1 = pcg32_uniform(rng),
           u2 = pcg32_uniform(rng), u_rr = pcg32_uniform(rng);
    vec3 y;
    double pb;
    if (!rd_beam_connect_sample(s, x, u_mix, u_th, u1, u2, &y, &pb)) return zero;
    vec3 dv = v3_sub(y, x);
    double dist = sqrt(v3_dot(dv, dv));
    if (!(dist > 0.0)) return zero;
    vec3 w = v3_scale(dv, 1.0 / dist);
    double fx = rd_hg_eval(m->g, v3_dot(d, w));
    /* y's medium: the path reaches y from x only by a straight flight in x's region (a surface
     * on the way ends the flight, and the collision after it takes no weight w_A), so y is
     * taken in that region, and a surface between the two blocks the connection (below) */
    const rd_medium *my = rd_scene_medium_at(s, region, y);
    if (!my) return zero;
    double sig = rd_medium_sigma_t(my, y);
    c->lookups++;
    if (!(sig > 0.0) || !(fx > 0.0)) return zero;
    /* the path's direction density at x: the phase function's, or guided-unbiased's mixture */
    double pdir = mx && mx->a > 0.0 ? rd_dir_mix_pdf(mx, m->g, d, w) : fx;
    double pa = rd_beam_connect_path_pdf(s, pdir, dist), wb = 1.0 / (1.0 + pa / pb); /* pb > 0 */
    /* the light's direction is -D: the phase at y between D and -w (nee.c's convention) */
    double py = rd_hg_eval(my->g, -v3_dot(w, s->lights[bc->light].dir));
    double albedo = (my->albedo.x + my->albedo.y + my->albedo.z) / 3.0;
    double P = wb * fx * py * sig * albedo / (dist * dist * pb);
    double q = fmin(1.0, P / RD_BC_ROULETTE);
    if (!(u_rr < q)) return zero;
    ray3 cr = {x, w};
    /* a surface or a sphere light between x and y ends the path's flight there: the path
     * cannot build this y by a flight from x (nee.c stops a shadow ray at a sphere light too) */
    int blocked = s->geom ? rd_geom_occluded(s->geom, cr, 0.0, dist, NULL) : rd_scene_hit_light(s, cr, dist, -1, NULL) >= 0;
    if (blocked) return zero;
    c->shadow_rays++;
    double T = rd_transmittance(s, region, cr, 0.0, dist, rng, c);
    if (!(T != 0.0)) return zero;
    vec3 Ly = rd_nee_light(s, region, y, w, my->g, bc->light, rng, c);
    return v3_scale(v3_mul(my->albedo, Ly), wb * fx * T * sig / (dist * dist * pb * q));
}
