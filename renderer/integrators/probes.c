/* probes.c: more camera chains for the light a camera sample sees at the end of its camera
 * chain (march.probes for the marchers, settings.probes for `delta`, guide.probes for
 * `guided-unbiased` and its delta tiles; docs/guided-marching.md "Probes",
 * docs/guided-unbiased.md "Probes").
 *
 * A camera sample of a marcher (march.c, rd_march_radiance), of `delta` (transport/path.c,
 * rd_delta_radiance_split) or of `guided-unbiased` (rd_path_radiance_split) is the sum of two
 * parts:
 *
 *   L = I + E,   I = everything the camera chain's media and surfaces scatter toward the
 *                    camera: the marched in-scattering, or delta's paths from its collisions,
 *                    and what a diffuse surface the chain ends on gives;
 *                E = beta T L_e, the light the chain sees at its end (a sphere light, the
 *                    environment, the background) through the media and the chain's glass
 *                    (a marcher: T by settings.transmittance's estimator; delta: its
 *                    flight's pass or stop).
 *
 * I costs many lookups (a marcher's samples, a path's collisions); E costs one chain of rays and
 * the transmittance along them. Where E is noisy (a small light seen through a glass ball: whether
 * the jittered chain hits it) and I is not, E takes most of the pixel's variance while each
 * sample pays for an I. So a sample may add M - 1 probes: more camera chains through the
 * pixel, each with a jitter of its own, that estimate E alone (the transmittance only, no
 * marching), and takes
 *
 *   L = I_0 + (E_0 + E_1 + ... + E_{M-1}) / M,
 *
 * unbiased for every M >= 1 chosen before the sample (each E_j has the mean of E_0).
 *
 * How many. Every pixel takes the same samples, so the image's efficiency is 1 / (V C_img), V and
 * C_img the sums over the pixels of a sample's variance and cost. Where pixel p takes M_p chains,
 * its variance V_p(M_p) and cost C_p(M_p) follow its model (model_of below: the variances of I,
 * of its own E_0 and of a probe's E, the covariance of I and E_0, which one chain's jitter sets
 * both of, as across a smoke's edge, and the costs), and d(V C_img) = 0 gives each pixel's
 *
 *   M_p = the M minimising V_p(M) + lambda C_p(M),   lambda = V / C_img
 *
 * (for a marcher, whose own chain and probes are alike, V_0 = V_p = V_E, this is about
 * M_p = sqrt((V_E + 2 C) / (lambda c_p)); M_p = 1 where the probes would undo a covariance that
 * cancels noise). "auto" chooses at the epochs, samples 4, 16, 64, ... of every pixel (the
 * selection's): each pixel's model from its own image samples so far (not the selection's
 * pilot), lambda from the whole image (V and C_img are those its M_p would make, so lambda is a
 * fixed point found from M_p = 1), and each pixel's M_p, which its samples take until the next
 * epoch (rd_probes_epoch; chosen once there, not at every sample, because a `delta` sample is
 * cheap). M_p is kept in [1, RD_PROBES_MAX]; a pixel's first samples take one probe each (what
 * its model needs), and none more until the first epoch at which it has a model (a guided
 * method's tile that moves to the method between epochs: until the next). The costs are the
 * selection's counted costs (select.c), so the choice, and the image, are the same for a seed on
 * any machine, thread count and number of ranks. A fixed integer M probes every sample alike.
 *
 * Where a pixel has seen no light (session 58). The model knows E only from the pixel's own
 * chains, and a light that covers a small part of the pixel can be missed by all of them: then
 * v0 = vp = 0, the search takes M = 1, and the pixel never learns otherwise. Where samples are
 * costly the chains are few: on hard-lens-caustic `guided` with march.beams gives the beams'
 * tiles about 30 samples a pixel in 10 s, and the small light's image through the glass ball
 * (a reference of 10.3 and 9.4 in two pixels, E non-zero on a few chains in a hundred) came
 * out 0.15 and 0.21, 97% of the image's squared error (docs/guided-marching.md "Where a pixel has seen no
 * light"). So where a pixel's model has no variance of E (its chains have seen no light, or the
 * same light every time), it takes at least the M the search
 * finds for the variance a light it has not seen may still hide: a light as bright as the
 * scene's brightest, b (a sphere light's radiance, or the background with the environment
 * lights), on which a chain ends with probability p = 1 / (chains + 2), the posterior mean
 * under a uniform prior after all of the pixel's chains missed it, so p (1 - p) b^2; but never
 * more than the probes that cost an eighth of its sample, 1 + floor(c / (8 cp)) chains. The
 * eighth bounds the loss where no light can be seen at 1/9 of the time, and a cheap sample
 * (delta's, about one chain) takes none; a dim background (b small against the image's lambda)
 * asks for none; the want falls as the chains that missed grow. */
#include "integrators/rd_probes.h"
#include "integrators/rd_select.h"
#include "scene/rd_camera.h"
#include "scene/rd_geom.h"
#include "transport/rd_path.h"
#include "transport/rd_transport.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>

/* Under "auto", a pixel's first PROBE_FIRST_SAMPLES samples take M = PROBE_FIRST (one probe
 * each): what its model needs to know of E and of a probe's cost, once per pixel */
#define PROBE_FIRST_SAMPLES 2
#define PROBE_FIRST 2

/* One pixel's statistics for "auto" (floats: they choose M, they do not enter the image). */
struct rd_probe_px {
    float n;              /* the pixel's samples so far */
    float i1, i2;         /* sum and sum of squares of I (the mean of its channels) */
    float e1, e2, ie;     /* sum and sum of squares of the samples' own E_0, and sum of I E_0 */
    float np, p1, p2;     /* probes taken, and the sum and sum of squares of their E */
    float cost, cost_p;   /* the samples' counted cost (probes left out), and the probes' */
    int M;                /* the chains its samples take until the next epoch (0: none chosen) */
};

/* The epochs: samples 4, 16, 64, ... of every pixel (select.c's). */
#define PROBE_EPOCH_FIRST 4
#define PROBE_EPOCH_GROWTH 4

/* Surface crossings of one probe chain that are not events (index-matched interfaces), as in
 * the marcher's own chain. */
#define PROBE_MAX_CROSSINGS 4096

vec3 rd_probes_chain(const rd_scene *s, ray3 r, pcg32 *rng, rd_track_counters *c)
{
    if (!s->geom) {
        double t_light, t0, t1;
        int hit_light = rd_scene_hit_light(s, r, INFINITY, -1, &t_light);
        vec3 Lb = rd_scene_behind(s, hit_light);
        if (!(v3_maxc(Lb) > 0.0)) return v3(0, 0, 0);
        double T = s->n_media > 0 && rd_box_intersect(s->bmin, s->bmax, r, 0.0, t_light, &t0, &t1) && t1 > t0
                       ? rd_transmittance(s, s->fill_medium, r, t0, t1, rng, c)
                       : 1.0;
        return v3_scale(Lb, T);
    }
    /* The marcher's specular chain (march.c), with each segment's transmittance in place of its
     * marching; a chain that reaches a diffuse surface sees no light at its end (what that
     * surface gives is I's). */
    int region = rd_scene_camera_region(s, r), crossings = 0, depth = 0;
    double eta_scale = 1.0;
    vec3 beta = v3(1, 1, 1);
    rd_hit h, prev;
    const rd_hit *from = NULL;
    for (;;) {
        int got = rd_scene_intersect(s, r, INFINITY, from, &h);
        int bright = !got || h.light >= 0 ? v3_maxc(rd_scene_behind(s, got ? h.light : -1)) > 0.0 : 0;
        if ((!got || h.light >= 0) && !bright) return v3(0, 0, 0);
        double t0, t1, t_end = got ? h.t : INFINITY;
        if (s->n_media > 0 && rd_box_intersect(s->bmin, s->bmax, r, 0.0, t_end, &t0, &t1) && t1 > t0)
            beta = v3_scale(beta, rd_transmittance(s, region, r, t0, t1, rng, c));
        if (!got || h.light >= 0) return v3_mul(beta, rd_scene_behind(s, got ? h.light : -1));
        if (beta.x == 0.0 && beta.y == 0.0 && beta.z == 0.0) return v3(0, 0, 0); /* (as the chain's T == 0) */
        prev = h;
        from = &prev;
        const rd_material *mat = &s->shapes[h.shape].material;
        if (mat->kind == RD_MAT_INTERFACE) {
            if (++crossings > PROBE_MAX_CROSSINGS) return v3(0, 0, 0);
            region = prev.medium_to;
            r = rd_hit_spawn(&prev, r.d);
            continue;
        }
        if (++depth > s->settings.max_depth || mat->kind == RD_MAT_DIFFUSE) return v3(0, 0, 0);
        rd_surface_step st = {.r = r, .beta = beta, .region = region, .camera_chain = 1, .eta_scale = eta_scale};
        if (!rd_surface_event(s, &prev, depth, &st, rng, c) || !st.camera_chain) return v3(0, 0, 0);
        r = st.r, beta = st.beta, region = st.region, eta_scale = st.eta_scale;
    }
}

/* The brightest light a chain can end on, as the mean of its channels: a sphere light, or what
 * lies behind everything (the background and the environment lights, rd_scene_behind). 0
 * exactly where no chain can end on light (radiances are >= 0: the loader's bounds). */
static double brightest(const rd_scene *s)
{
    vec3 b = rd_scene_behind(s, -1);
    double m = (b.x + b.y + b.z) / 3.0;
    for (int i = 0; i < s->n_lights; i++) {
        vec3 v = s->lights[i].value;
        if (s->lights[i].kind == RD_LIGHT_SPHERE) m = fmax(m, (v.x + v.y + v.z) / 3.0);
    }
    return m;
}

rd_status rd_probes_init(rd_probes *p, const rd_scene *s, int setting, double cell_cost, char *err, size_t errlen)
{
    p->M = setting;
    p->px = NULL;
    p->cell_cost = cell_cost;
    p->bright = brightest(s);
    if (!(p->bright > 0.0)) {
        p->M = 1; /* E is 0 on every chain: nothing to probe */
        return RD_OK;
    }
    if (p->M != 0) return RD_OK;
    size_t n = (size_t)s->camera.width * (size_t)s->camera.height;
    p->px = calloc(n, sizeof *p->px);
    if (!p->px) {
        snprintf(err, errlen, "out of memory for the probes' statistics (%zu pixels)", n);
        return RD_ERR_NOMEM;
    }
    return RD_OK;
}

void rd_probes_free(rd_probes *p)
{
    free(p->px);
    p->px = NULL;
}

static double mean3(vec3 v) { return (v.x + v.y + v.z) / 3.0; }

/* Variance from a count, a sum and a sum of squares (0 below two values). */
static double variance(double n, double s1, double s2)
{
    return n > 1.0 ? fmax(0.0, (s2 - s1 * s1 / n) / (n - 1.0)) : 0.0;
}

/* Pixel px's model (rd_probes_model, rd_probes.h). Returns 0 while there is none (the first
 * samples, or fewer than two probes to price and measure one). */
static int model_of(const struct rd_probe_px *px, rd_probes_model *m)
{
    if (px->n < PROBE_FIRST_SAMPLES || px->np < 2.0f) return 0;
    double n = px->n;
    m->vI = variance(n, px->i1, px->i2);
    m->cov = (px->ie - px->i1 * px->e1 / n) / (n - 1.0);
    m->v0 = variance(n, px->e1, px->e2);
    m->vp = variance(px->np, px->p1, px->p2);
    m->c = px->cost / n;
    m->cp = px->cost_p / px->np;
    m->chains = n + px->np;
    return m->cp > 0.0 && isfinite(m->vI + m->cov + m->v0 + m->vp + m->c);
}

static double model_V(const rd_probes_model *m, int M)
{
    return m->vI + 2.0 * m->cov / M + (m->v0 + (M - 1) * m->vp) / ((double)M * M);
}
static double model_C(const rd_probes_model *m, int M) { return m->c + (M - 1) * m->cp; }

/* A lower bound of V(M') + lambda C(M') over every M' >= M: (v0 + (M' - 1) vp) / M'^2 >= 0 (v0,
 * vp >= 0: variance()), a negative covariance's 2 C / M' is >= 2 C / M, and the cost grows with
 * M' (cp > 0: model_of). It grows with M. */
static double model_floor(const rd_probes_model *m, double lambda, int M)
{
    return m->vI + fmin(0.0, 2.0 * m->cov / M) + lambda * model_C(m, M);
}

/* The M in [1, RD_PROBES_MAX] that minimises V(M) + lambda C(M): each pixel's part of the least
 * V C_img (the head). It runs for every pixel in each of an epoch's fixed-point rounds, so the
 * search stops at the first M whose floor (model_floor) is clearly above the best so far (by
 * more than rounding): no later M can be better, and the M found is the full search's. */
int rd_probes_best_m(const rd_probes_model *m, double lambda)
{
    if (!(lambda > 0.0)) return 1;
    int best = 1;
    double fbest = model_V(m, 1) + lambda * model_C(m, 1);
    double slack = 1e-9 * (fabs(fbest) + m->vI + fabs(m->cov) + m->v0 + m->vp); /* rounding */
    for (int M = 2; M <= RD_PROBES_MAX; M++) {
        if (model_floor(m, lambda, M) > fbest + slack) break;
        double f = model_V(m, M) + lambda * model_C(m, M);
        if (f < fbest) best = M, fbest = f;
    }
    return best;
}

/* A pixel whose chains have seen no light (the head, "Where a pixel has seen no light") spends
 * on probes for it at most 1/PROBE_UNSEEN_SHARE of its sample's own cost: 1 + floor(c /
 * (PROBE_UNSEEN_SHARE cp)) chains. (A bound on the loss, chosen, not fitted.) */
#define PROBE_UNSEEN_SHARE 8.0

int rd_probes_choose_m(const rd_probes_model *m, double lambda, double bright)
{
    int best = rd_probes_best_m(m, lambda);
    if (m->v0 > 0.0 || m->vp > 0.0 || !(bright > 0.0) || !(m->cp > 0.0)) return best;
    /* the unseen light's variance: a chain ends on it with probability p, the posterior mean
     * after the model's chains all missed it (a uniform prior), and sees `bright` there */
    double p = 1.0 / (m->chains + 2.0);
    rd_probes_model u = *m;
    u.v0 = u.vp = p * (1.0 - p) * bright * bright;
    int want = rd_probes_best_m(&u, lambda);
    double budget = 1.0 + floor(m->c / (PROBE_UNSEEN_SHARE * m->cp));
    int least = budget < want ? (int)budget : want;
    return best > least ? best : least;
}

/* M for pixel px under "auto" (the head): what the last epoch chose for it. */
static int probes_auto(const struct rd_probe_px *px)
{
    if (px->n < PROBE_FIRST_SAMPLES) return PROBE_FIRST;
    return px->M > 0 ? px->M : 1;
}

int rd_probes_epoch_next(const rd_probes *p, int sample)
{
    if (!p->px) return INT_MAX;
    int b = PROBE_EPOCH_FIRST;
    while (b <= sample) {
        if (b > INT_MAX / PROBE_EPOCH_GROWTH) return INT_MAX;
        b *= PROBE_EPOCH_GROWTH;
    }
    return b;
}

/* Fixed-point rounds for lambda at an epoch. */
#define PROBE_ROUNDS 16
/* The doubles of one pixel's model as ranks exchange them: a flag, then rd_probes_model's
 * fields. */
#define PROBE_MODEL_DOUBLES 8

/* Pixel i's model at an epoch: from the ranks' summed array `all` when there is one, else from
 * its own statistics. Returns 0 where it has none. */
static int epoch_model(const rd_probes *p, const double *all, size_t i, rd_probes_model *m)
{
    if (!all) return model_of(&p->px[i], m);
    const double *a = all + i * PROBE_MODEL_DOUBLES;
    if (!(a[0] > 0.0)) return 0;
    *m = (rd_probes_model){a[1], a[2], a[3], a[4], a[5], a[6], a[7]};
    return 1;
}

/* lambda is V / C_img at the M_p it chooses (the head): from the pixels' models, starting at
 * M_p = 1, lambda <- V(M(lambda)) / C(M(lambda)) until it settles (each round's map is
 * increasing in lambda, so the rounds move one way). Pixels without a model (not rendered with
 * these probes yet: `guided`'s delta tiles, which take none) are left out. With several ranks
 * the models of every pixel are summed into one array first (each pixel is one rank's; the
 * others add exact zeros) and every rank runs the same rounds over it in pixel order, so
 * lambda, and the image, are those of one process. */
void rd_probes_epoch(const rd_render_ctx *ctx, rd_probes *p)
{
    if (!p->px) return;
    const rd_camera *cam = &ctx->scene->camera;
    const rd_comm *comm = ctx->comm;
    size_t n = (size_t)cam->width * (size_t)cam->height;
    double *all = NULL;
    if (comm && comm->size > 1) {
        all = calloc(n * PROBE_MODEL_DOUBLES, sizeof *all);
        for (size_t i = 0; all && i < n; i++) {
            rd_probes_model m;
            if (!model_of(&p->px[i], &m)) continue;
            double *a = all + i * PROBE_MODEL_DOUBLES;
            a[0] = 1.0, a[1] = m.vI, a[2] = m.cov, a[3] = m.v0, a[4] = m.vp, a[5] = m.c, a[6] = m.cp, a[7] = m.chains;
        }
        /* (every rank calls the reduce, even one that ran out of memory: its part is left out) */
        double *buf = all ? all : calloc(1, sizeof *buf);
        comm->reduce(comm->user, buf, all ? n * PROBE_MODEL_DOUBLES : 0, RD_COMM_DOUBLE, RD_COMM_SUM, -1);
        if (!all) free(buf);
    }
    double lambda = 0.0;
    for (int round = 0; round < PROBE_ROUNDS; round++) {
        double V = 0.0, C = 0.0;
        for (size_t i = 0; i < n; i++) {
            rd_probes_model m;
            if (!epoch_model(p, all, i, &m)) continue;
            int M = round == 0 ? 1 : rd_probes_choose_m(&m, lambda, p->bright);
            V += model_V(&m, M);
            C += model_C(&m, M);
        }
        double next = V > 0.0 && C > 0.0 ? V / C : 0.0;
        int settled = next == lambda || fabs(next - lambda) <= 1e-3 * next;
        lambda = next;
        if (settled) break;
    }
    /* Each pixel's M until the next epoch: chosen here once, not at every sample (the search
     * and the model's divisions there made a `delta` sample a fifth slower on smoke-vdb, where
     * almost no pixel takes probes: docs/guided-marching.md "The search's cost"). */
    for (size_t i = 0; i < n; i++) {
        rd_probes_model m;
        p->px[i].M = epoch_model(p, all, i, &m) ? rd_probes_choose_m(&m, lambda, p->bright) : 1;
    }
    free(all);
}

double rd_probes_cost(const rd_probes *p, const rd_select_work *w0, const rd_thread *th)
{
    return rd_select_work_cost(w0, th, p->cell_cost) + RD_SELECT_COST_SAMPLE;
}

vec3 rd_probes_add(const rd_render_ctx *ctx, rd_probes *p, rd_thread *th, vec3 I, vec3 E0, double cost,
                   pcg32 *rng)
{
    const rd_scene *s = ctx->scene;
    struct rd_probe_px *px = p->px && !th->pilot ? &p->px[th->pixel] : NULL;
    /* (the selection's pilot takes none under "auto": it learns the method without them) */
    int M = px ? probes_auto(px) : (p->M > 0 ? p->M : 1);
    vec3 E = E0;
    double cost_p = 0.0, p1 = 0.0, p2 = 0.0;
    if (M > 1) {
        const rd_camera *cam = &s->camera;
        double x = th->x, y = th->y;
        rd_select_work w0 = rd_select_work_now(th);
        for (int j = 1; j < M; j++) {
            double jx = pcg32_uniform(rng), jy = pcg32_uniform(rng);
            if (!cam->jitter) jx = jy = 0.5;
            vec3 Ej = rd_probes_chain(s, rd_camera_ray(cam, x + jx, y + jy), rng, &th->counters);
            E = v3_add(E, Ej);
            double e = mean3(Ej);
            p1 += e, p2 += e * e;
        }
        cost_p = rd_select_work_cost(&w0, th, p->cell_cost) + (M - 1) * RD_SELECT_COST_SAMPLE;
        th->probes += (uint64_t)(M - 1);
    }
    vec3 L = v3_add(I, M > 1 ? v3_scale(E, 1.0 / M) : E); /* (E x 1.0 is E: no division) */
    /* (a sample the film drops, not finite, is not learnt from either) */
    if (px && v3_finite(L)) {
        double i = mean3(I), e0 = mean3(E0);
        px->n += 1.0f;
        px->i1 += (float)i, px->i2 += (float)(i * i);
        px->e1 += (float)e0, px->e2 += (float)(e0 * e0), px->ie += (float)(i * e0);
        px->np += (float)(M - 1), px->p1 += (float)p1, px->p2 += (float)p2;
        px->cost += (float)cost, px->cost_p += (float)cost_p;
    }
    return L;
}

vec3 rd_probes_delta(const rd_render_ctx *ctx, rd_probes *p, rd_thread *th, ray3 r, rd_sampler *smp,
                     int equiangular)
{
    pcg32 rng = rd_sampler_stream(smp);
    if (!rd_probes_on(p)) return rd_delta_radiance_eq(ctx->scene, r, equiangular, &rng, &th->counters);
    /* the path less its camera chain's end, E, which the probes estimate again */
    vec3 E;
    rd_select_work w0 = rd_select_work_now(th);
    vec3 I = rd_delta_radiance_split(ctx->scene, r, equiangular, &rng, &th->counters, &E);
    return rd_probes_add(ctx, p, th, I, E, rd_probes_cost(p, &w0, th), &rng);
}
