/* path.c: the unbiased volumetric path loop (THEORY.md §1-2) shared by `delta` and
 * `guided-unbiased`, and delta tracking's free flight, which makes it `delta`'s path.
 *
 * Free flights come from a pluggable sampler (rd_flight_sampler: delta tracking over the
 * free-path engine here, guided distances in integrators/guided_unbiased.c); at every
 * scattering vertex next-event estimation (rd_nee: one light chosen by power, unbiased shadow
 * transmittance), Henyey-Greenstein phase sampling (or the sampler's vertex policy), Russian
 * roulette on the path weight, and multiple importance sampling (power heuristic) between light
 * sampling and phase sampling for the lights a path can hit (sphere, environment), and the
 * beam connections of settings.beam_connect, weighted against the collisions that build the
 * same vertices (beam_connect.c). Surfaces: rd_surface_event (docs/surfaces.md). */
#include "scene/rd_geom.h"
#include "transport/rd_path.h"

/* Light reached by an escaping ray, or by a ray that hits sphere light `hit_light`. `phase_pdf`
 * is the pdf with which the direction was sampled (0 for camera rays: no MIS, full weight);
 * the light's pdf in the MIS weight includes its probability of being chosen by rd_nee. */
static vec3 escaped_radiance(const rd_scene *s, ray3 r, int hit_light, double phase_pdf)
{
    if (hit_light >= 0) {
        double w = phase_pdf > 0.0 ? rd_power_heuristic(phase_pdf, rd_light_mis_pdf(s, hit_light, r.o, r.d)) : 1.0;
        return v3_scale(s->lights[hit_light].value, w);
    }
    vec3 L = v3(0, 0, 0);
    for (int i = 0; i < s->n_lights; i++) {
        const rd_light *l = &s->lights[i];
        if (l->kind != RD_LIGHT_ENVIRONMENT) continue;
        double w = phase_pdf > 0.0 ? rd_power_heuristic(phase_pdf, rd_light_mis_pdf(s, i, r.o, r.d)) : 1.0;
        L = v3_madd(L, l->value, w);
    }
    return L;
}

vec3 rd_flight_behind(const rd_scene *s, const rd_flight_in *in)
{
    if (in->hit_shape >= 0) return v3(0, 0, 0); /* a surface: the path loop goes on from it */
    vec3 L = escaped_radiance(s, in->r, in->hit_light, in->phase_pdf);
    if (in->camera_chain && in->hit_light < 0) L = v3_add(L, s->background);
    return L;
}

/* A tracker's collision as a flight of the path loop. */
static rd_flight flight_of(rd_collision col)
{
    rd_flight f;
    f.kind = col.hit ? RD_FLIGHT_SCATTER : RD_FLIGHT_PASS;
    f.t = col.t;
    f.medium = col.medium;
    /* Delta tracking draws t with density sigma_t(t) T(0,t) and passes with probability
     * T(0,t_end), so the vertex weight T sigma_s / (sigma_t T) is the albedo and the pass
     * weight T / T is 1 (rd_flight); weighted trackers (seed 002 Alg. 2-3) add their own
     * factor, 1 for delta tracking. */
    f.weight = col.hit ? v3_scale(col.medium->albedo, col.weight) : v3(col.weight, col.weight, col.weight);
    f.pdf = 0.0; /* not known: the equiangular weights take the majorant stand-in */
    return f;
}

rd_flight rd_flight_delta(const rd_scene *s, const rd_flight_in *in, pcg32 *rng,
                          rd_track_counters *c)
{
    if (in->iv) return flight_of(rd_sample_free_path_iv(s, in->iv, in->n_iv, in->r, in->t_light, rng, c));
    return flight_of(rd_sample_free_path(s, in->region, in->r, in->t_light, rng, c));
}

double rd_thin_bias_q(const rd_scene *s, const rd_flight_in *in)
{
    if (!(s->settings.thin_bias > 0.0)) return 0.0;
    if (in->hit_shape < 0) {
        vec3 b = rd_flight_behind(s, in);
        if (b.x == 0.0 && b.y == 0.0 && b.z == 0.0) return 1.0;
    }
    return s->settings.thin_bias;
}

/* `delta`'s flight: delta tracking, or with settings.thin_bias its biased form (tracking.c
 * derives the weights; the vertex weight is the albedo times the chain's weight W, as for
 * the weighted trackers). */
static rd_flight delta_flight(const rd_flight_sampler *fs, const rd_scene *s,
                              const rd_flight_in *in, pcg32 *rng, rd_track_counters *c)
{
    (void)fs;
    double q = rd_thin_bias_q(s, in);
    if (!(q > 0.0)) return rd_flight_delta(s, in, rng, c);
    if (in->iv) return flight_of(rd_sample_free_path_thin_iv(s, in->iv, in->n_iv, in->r, in->t_light, q, rng, c));
    return flight_of(rd_sample_free_path_thin(s, in->region, in->r, in->t_light, q, rng, c));
}

int rd_surface_event(const rd_scene *s, const rd_hit *h, int depth, rd_surface_step *st,
                     pcg32 *rng, rd_track_counters *c)
{
    const rd_material *mat = &s->shapes[h->shape].material;
    vec3 d = st->r.d;
    st->L = v3(0, 0, 0);
    /* A diffuse surface: next-event estimation with its BSDF, MIS against the BSDF sampling
     * below (rd_nee_surface). */
    if (mat->kind == RD_MAT_DIFFUSE) st->L = v3_mul(st->beta, rd_nee_surface(s, h, d, rng, c));
    /* Russian roulette on the throughput, as at a medium vertex (without the radiance
     * factors of the refractions: eta_scale). */
    if (depth >= s->settings.rr_depth) {
        vec3 b = st->beta;
        double q = fmin(1.0, fmax(fabs(b.x), fmax(fabs(b.y), fabs(b.z))) * st->eta_scale);
        if (q <= 0.0 || pcg32_uniform(rng) >= q) return 0;
        st->beta = v3_scale(b, 1.0 / q);
    }
    /* Fresnel reflection or refraction chosen with its probability (weight 1, times
     * (n_i/n_t)^2 on refraction: radiance mode, rd_geom.h), a cosine-weighted diffuse
     * direction (weight = albedo), or straight on through an interface. */
    double ue = pcg32_uniform(rng), u1 = pcg32_uniform(rng), u2 = pcg32_uniform(rng);
    rd_surface_sample ss;
    if (!rd_material_sample(mat, d, h->ng, h->ns, RD_TRANSPORT_RADIANCE, ue, u1, u2, &ss)) return 0;
    st->beta = v3_mul(st->beta, ss.weight);
    /* A dielectric refraction's weight is (n_i/n_t)^2 in every channel (rd_geom.h). */
    if (mat->kind == RD_MAT_DIELECTRIC && ss.crossed && ss.weight.x > 0.0) st->eta_scale /= ss.weight.x;
    st->pdf = ss.specular ? 0.0 : ss.pdf; /* no MIS after a delta event */
    st->camera_chain = st->camera_chain && ss.specular;
    st->region = ss.crossed ? h->medium_to : h->medium_from;
    st->r = rd_hit_spawn(h, ss.d);
    return 1;
}

/* The loop from a free flight along r on, with unit throughput: returns the radiance estimate
 * of L(r.o, -r.d). `region` is where r starts (rd_scene.h "Surfaces in the transport"),
 * `phase_pdf` the pdf with which r.d was drawn (0 for the camera ray), `depth` the scattering
 * events before this flight, *budget the extra copies splitting may still add to this camera
 * sample, beta0 the throughput from the camera to r.o (the vertex policy weighs the whole
 * path's: in a split copy, beta0 holds the copy's share). With `scattered_only`, the first
 * flight's pass-through and its vertex's next-event estimate are left to the caller
 * (rd_delta_scattered). `from_vertex`: r.o is a scattering vertex of the calling loop, which
 * connected to the beam (a split copy: continue_from). */
static vec3 trace(const rd_scene *s, ray3 r, int region, double phase_pdf, int depth0,
                  int camera_chain, int scattered_only, const rd_flight_sampler *fs, pcg32 *rng,
                  rd_track_counters *c, int *budget, vec3 beta0, int from_vertex, vec3 *E_chain);

/* The flight whose vertex a next-event estimate serves, when the flight had the equiangular
 * strategy: its set-up and the vertex's distance t and density pdf (rd_flight.pdf). */
typedef struct {
    const rd_eq_flight *ef;
    double t, pdf;
} vertex_eq;

/* Next-event estimation at a medium vertex against the direction mixture mx (NULL: phase
 * sampling), its light's share weighted against the flight's equiangular strategy when it had
 * one (v->ef; equiangular.c: w_d = 1 - w_e), and the beam's against its connection. */
static vec3 vertex_nee(const rd_scene *s, int region, vec3 x, vec3 d, const rd_medium *m,
                       const rd_dir_mix *mx, const vertex_eq *v, double wa_beam, pcg32 *rng,
                       rd_track_counters *c)
{
    int j = -1;
    vec3 L = rd_nee_mix(s, region, x, d, m->g, mx, rng, c, &j);
    if (v->ef) L = v3_scale(L, rd_eq_weight(s, v->ef, v->t, j, v->pdf));
    /* the beam's light: weighted by wa_beam, the vertex's weight w_A against the beam connection
     * that could have built it (transport/beam_connect.c; 1 where none could) */
    return j >= 0 && j == s->beam_connect.light ? v3_scale(L, wa_beam) : L;
}

/* One copy of a continuation from vertex x (arrived along d) with the vertex policy's
 * direction mixture: next-event estimation plus the continued path, with unit throughput
 * (an estimate of L_s(x, -d)); beta0 is the copy's throughput from the camera, for the vertex
 * policies further on. */
static vec3 continue_from(const rd_scene *s, vec3 x, vec3 d, int region, const rd_medium *m,
                          const rd_dir_mix *mx, const vertex_eq *v, double wa_beam, int depth,
                          const rd_flight_sampler *fs, pcg32 *rng, rd_track_counters *c, int *budget,
                          vec3 beta0)
{
    vec3 L = vertex_nee(s, region, x, d, m, mx, v, wa_beam, rng, c);
    double pdf;
    vec3 wo = rd_dir_mix_sample(mx, m->g, d, rng, &pdf);
    if (!(pdf > 0.0)) return L;
    /* Weight p / pdf: 1 for phase sampling alone, the mixture's ratio otherwise. */
    double w = rd_hg_eval(m->g, v3_dot(d, wo)) / pdf;
    ray3 next = {x, wo};
    return v3_add(L, v3_scale(trace(s, next, region, pdf, depth, 0, 0, fs, rng, c, budget, v3_scale(beta0, w), 1, NULL), w));
}

/* The sampler's density (rd_flight_sampler.density) in the form rd_eq_flight holds it. */
static double flight_density(const void *user, double t)
{
    const rd_flight_sampler *fs = user;
    return fs->density(fs, t);
}

/* Surface crossings of one path that do not count as scattering events (index-matched
 * interfaces): a bound on the loop should geometry ever trap a ray. */
#define MAX_CROSSINGS 4096

static vec3 trace(const rd_scene *s, ray3 r, int region, double phase_pdf, int depth0,
                  int camera_chain, int scattered_only, const rd_flight_sampler *fs, pcg32 *rng,
                  rd_track_counters *c, int *budget, vec3 beta0, int from_vertex, vec3 *E_chain)
{
    vec3 L = v3(0, 0, 0), beta = v3(1, 1, 1);
    rd_hit hit, prev;
    const rd_hit *from = NULL; /* the surface the current ray leaves, if any */
    int crossings = 0;
    double eta_scale = 1.0; /* rd_surface_step */
    /* settings.beam_connect (transport/beam_connect.c): every scattering vertex connects to the
     * beam, but not where the flights after a scattering event sample the beam's chord
     * themselves (the equiangular mode `true`, as the guided methods' third estimator has it).
     * prev_scatter: the current flight starts at a scattering vertex (r.o) that connected, so
     * the next-event estimate at its collision takes the weight w_A. */
    const int connect = s->beam_connect.light >= 0 && fs->equiangular != RD_EQ_ALL;
    int prev_scatter = from_vertex;
    for (int depth = depth0;; depth++) {
        /* What the ray meets first (a sphere light or a surface) ends the free flight. */
        rd_flight_in in = {.r = r, .depth = depth, .phase_pdf = phase_pdf, .region = region,
                           .camera_chain = camera_chain, .hit_light = -1, .hit_shape = -1,
                           .t_light = INFINITY};
        if (rd_scene_intersect(s, r, INFINITY, from, &hit)) {
            in.t_light = hit.t;
            in.hit_light = hit.light;
            in.hit_shape = hit.shape;
        }
        /* The flights' equiangular mode (settings.equiangular for `delta`, march.equiangular for
         * the marchers' paths, guide.equiangular for guided-unbiased's): `delta`'s second
         * strategy for the single scattering from the set's lights (point and spot lights; beams in
         * `true` and "camera") along this flight
         * (transport/equiangular.c), with the throughput up to the flight; the collision's
         * next-event estimate below takes the other weight. Its set-up needs the flight's media
         * intervals, which delta tracking's flight needs too: found once, here, for both (on
         * hard-dense-block the second search was half of "auto"'s cost). */
        int eq = 0;
        rd_eq_flight ef;
        int first = scattered_only && depth == depth0; /* the caller's flight (see above) */
        int eq_here = !first && fs->equiangular != RD_EQ_OFF && depth + 1 <= s->settings.max_depth &&
                      (fs->equiangular != RD_EQ_CAMERA || depth == 0);
        ef.n = 0;
        if (eq_here && rd_eq_has_lights(s, rd_eq_mode_beams(fs->equiangular))) {
            ef.n = rd_media_intervals(s, region, r, 0.0, in.t_light, ef.iv);
            in.iv = ef.iv;
            in.n_iv = ef.n;
        }
        rd_flight f = fs->sample(fs, s, &in, rng, c);
        if (eq_here) {
            /* thin bias is `delta`'s own flights' (a sampler with a density has none) */
            eq = rd_eq_flight_choose(s, r, region, fs->density ? 0.0 : rd_thin_bias_q(s, &in), fs->equiangular,
                                     &ef);
            c->eq_flights += ef.n > 0; /* a set-up that did the work: media, and a light to choose */
            if (eq && fs->density) {
                ef.density = flight_density;
                ef.density_user = fs;
            }
            if (eq) L = v3_add(L, v3_mul(beta, rd_eq_nee(s, &ef, rng, c)));
        }
        if (f.kind == RD_FLIGHT_END || (first && f.kind == RD_FLIGHT_PASS)) break;
        beta = v3_mul(beta, f.weight);
        if (f.kind == RD_FLIGHT_PASS && in.hit_shape < 0) {
            vec3 Lb = v3_mul(beta, rd_flight_behind(s, &in));
            if (E_chain && camera_chain) *E_chain = Lb; /* the camera chain's end (probes.c) */
            else L = v3_add(L, Lb);
            break;
        }
        if (f.kind == RD_FLIGHT_PASS) {
            prev_scatter = 0;
            /* At a surface (docs/surfaces.md). An interface only changes the region: the same
             * ray goes on, no event counted, no random number drawn. */
            prev = hit;
            from = &prev;
            if (s->shapes[hit.shape].material.kind == RD_MAT_INTERFACE) {
                if (++crossings > MAX_CROSSINGS) break;
                region = prev.medium_to;
                r = rd_hit_spawn(&prev, r.d);
                depth--; /* not a scattering event */
                continue;
            }
            if (depth + 1 > s->settings.max_depth) break;
            rd_surface_step st = {.r = r, .beta = beta, .region = region, .camera_chain = camera_chain,
                                  .eta_scale = eta_scale};
            int go = rd_surface_event(s, &prev, depth + 1, &st, rng, c);
            L = v3_add(L, st.L);
            if (!go) break;
            r = st.r, beta = st.beta, region = st.region, camera_chain = st.camera_chain;
            eta_scale = st.eta_scale;
            phase_pdf = st.pdf;
            continue;
        }
        if (depth + 1 > s->settings.max_depth) break; /* this would be scattering event depth+1 */
        const rd_medium *m = f.medium;
        vec3 x = ray_at(r, f.t);
        const vertex_eq ve = {.ef = eq ? &ef : NULL, .t = f.t, .pdf = f.pdf};
        /* The beam's light at x: the connection from r.o could have built this vertex too;
         * this side's balance weight w_A (beam_connect.c) */
        double wa_beam = 1.0;
        if (connect && prev_scatter) {
            double pb = rd_beam_connect_pdf(s, r.o, x);
            if (pb > 0.0) {
                double pa = rd_beam_connect_path_pdf(s, phase_pdf, f.t);
                wa_beam = 1.0 / (1.0 + pb / pa); /* 1 where pa is infinite (f.t = 0) */
            }
        }
        from = NULL;
        camera_chain = 0;
        /* Scattering vertex: beta now carries T sigma_s / pdf (rd_flight), so what follows
         * estimates L_s(x, -d) = integral of p L (THEORY.md §1): next-event estimation for the
         * direct part, the sampled continuation for the rest. */
        if (fs->vertex) {
            /* The sampler's vertex policy: roulette or splitting, and the direction mixture.
             * Every copy but the last recurses; the last continues this loop. */
            rd_vertex_in vi = {.x = x, .d = r.d, .medium = m, .region = region, .depth = depth + 1,
                               .beta = v3_mul(beta0, beta)};
            rd_vertex_out vo;
            fs->vertex(fs, s, &vi, rng, &vo);
            int n = vo.n;
            if (n <= 0) break;
            if (n - 1 > *budget) n = 1 + *budget;
            *budget -= n - 1;
            beta = v3_scale(beta, vo.rr_scale / n);
            /* One connection to the beam for the vertex (its weight the surviving path's, all
             * copies together), against the mixture's directions that every copy draws. */
            if (connect && depth + 2 <= s->settings.max_depth)
                L = v3_add(L, v3_mul(v3_scale(beta, n), rd_beam_connect_estimate(s, region, x, r.d, m, &vo.mix, rng, c)));
            for (int k = 1; k < n; k++)
                L = v3_add(L, v3_mul(beta, continue_from(s, x, r.d, region, m, &vo.mix, &ve, wa_beam, depth + 1,
                                                         fs, rng, c, budget, v3_mul(beta0, beta))));
            L = v3_add(L, v3_mul(beta, vertex_nee(s, region, x, r.d, m, &vo.mix, &ve, wa_beam, rng, c)));
            double pdf;
            vec3 wo = rd_dir_mix_sample(&vo.mix, m->g, r.d, rng, &pdf);
            if (!(pdf > 0.0)) break;
            beta = v3_scale(beta, rd_hg_eval(m->g, v3_dot(r.d, wo)) / pdf);
            phase_pdf = pdf;
            prev_scatter = 1;
            r.o = x;
            r.d = wo;
            continue;
        }
        if (!first) /* (else the caller estimated this vertex's direct light) */
            L = v3_add(L, v3_mul(beta, vertex_nee(s, region, x, r.d, m, NULL, &ve, wa_beam, rng, c)));

        /* Russian roulette on the throughput. Weighted trackers with non-bounding majorants
         * can make weights negative: survive with the largest magnitude, not the largest value. */
        if (depth + 1 >= s->settings.rr_depth) {
            double q = fmin(1.0, fmax(fabs(beta.x), fmax(fabs(beta.y), fabs(beta.z))) * eta_scale);
            if (q <= 0.0 || pcg32_uniform(rng) >= q) break;
            beta = v3_scale(beta, 1.0 / q);
        }

        /* The connection to the beam from x (its vertex y would be scattering event depth + 2). */
        if (connect && depth + 2 <= s->settings.max_depth)
            L = v3_add(L, v3_mul(beta, rd_beam_connect_estimate(s, region, x, r.d, m, NULL, rng, c)));
        /* Phase sampling: the weight p/pdf is 1 for HG importance sampling. */
        vec3 wo = rd_hg_sample(m->g, r.d, pcg32_uniform(rng), pcg32_uniform(rng));
        phase_pdf = rd_hg_eval(m->g, v3_dot(r.d, wo));
        prev_scatter = 1;
        r.o = x;
        r.d = wo;
    }
    return L;
}

vec3 rd_path_radiance(const rd_scene *s, ray3 r, const rd_flight_sampler *fs, pcg32 *rng,
                      rd_track_counters *c)
{
    int budget = RD_SPLIT_BUDGET;
    /* The camera's region (rd_scene_camera_region: found once for a perspective camera). */
    return trace(s, r, rd_scene_camera_region(s, r), 0.0, 0, 1, 0, fs, rng, c, &budget, v3(1, 1, 1), 0, NULL);
}

vec3 rd_delta_continue(const rd_scene *s, ray3 r, int region, double pdf, int depth,
                       int camera_chain, int equiangular, pcg32 *rng, rd_track_counters *c)
{
    const rd_flight_sampler fs = {.sample = delta_flight, .vertex = NULL, .user = NULL,
                                  .equiangular = equiangular};
    int budget = 0;
    return trace(s, r, region, pdf, depth, camera_chain, 0, &fs, rng, c, &budget, v3(1, 1, 1), 0, NULL);
}

vec3 rd_delta_scattered(const rd_scene *s, ray3 r, int region, int depth, int equiangular,
                        pcg32 *rng, rd_track_counters *c)
{
    const rd_flight_sampler fs = {.sample = delta_flight, .vertex = NULL, .user = NULL,
                                  .equiangular = equiangular};
    int budget = 0;
    return trace(s, r, region, 0.0, depth, 1, 1, &fs, rng, c, &budget, v3(1, 1, 1), 0, NULL);
}

vec3 rd_delta_radiance_eq(const rd_scene *s, ray3 r, int equiangular, pcg32 *rng, rd_track_counters *c)
{
    const rd_flight_sampler fs = {.sample = delta_flight, .vertex = NULL, .user = NULL,
                                  .equiangular = equiangular};
    return rd_path_radiance(s, r, &fs, rng, c);
}

vec3 rd_path_radiance_split(const rd_scene *s, ray3 r, const rd_flight_sampler *fs, pcg32 *rng,
                            rd_track_counters *c, vec3 *E)
{
    int budget = RD_SPLIT_BUDGET;
    *E = v3(0, 0, 0);
    return trace(s, r, rd_scene_camera_region(s, r), 0.0, 0, 1, 0, fs, rng, c, &budget, v3(1, 1, 1), 0, E);
}

vec3 rd_delta_radiance_split(const rd_scene *s, ray3 r, int equiangular, pcg32 *rng, rd_track_counters *c,
                             vec3 *E)
{
    const rd_flight_sampler fs = {.sample = delta_flight, .vertex = NULL, .user = NULL,
                                  .equiangular = equiangular};
    return rd_path_radiance_split(s, r, &fs, rng, c, E);
}

vec3 rd_delta_radiance(const rd_scene *s, ray3 r, pcg32 *rng, rd_track_counters *c)
{
    return rd_delta_radiance_eq(s, r, rd_eq_path_mode(s->settings.equiangular), rng, c);
}

