/* Volume data: OpenVDB grids are read with their transform honoured (also a rotated one),
 * broken .vdb files are rejected with a message, the procedural noise equals Perlin's 2002
 * formula and respects the bound its majorant uses (and the early-exit accept test that relies
 * on that bound answers as the full density does), and `voxelize` writes raw and VDB grids
 * that give back the same density.
 * Light transport through volumes: two media along one ray (single scattering against
 * quadrature, background against exp(-tau1 - tau2)) and an orthographic camera (its rays, and
 * a slab seen through it). Monte Carlo estimates come from rt_delta_mc or rd_render with fixed
 * seeds; tolerances are 5 standard errors (a false alarm per check has probability 6e-7). */
#include "support/rd_test.h"

#include "media/rd_vdb.h"
#include "support/perlin_2002.h"

Test(volume, vdb_roundtrip_honours_the_transform, .timeout = 60)
{
    /* 6x5x4 voxels, voxel size 0.25, voxel (0,0,0) centred at (1, 2, 3). */
    enum { NX = 6, NY = 5, NZ = 4 };
    float v[NX * NY * NZ];
    for (int i = 0; i < NX * NY * NZ; i++) v[i] = 0.1f * (float)(i % 17) + 0.05f;
    char path[256], err[RD_ERRLEN];
    snprintf(path, sizeof path, "%s/g.vdb", rt_tmpdir());
    const double origin[3] = {1, 2, 3};
    cr_assert(rd_vdb_save_dense(path, "density", v, NX, NY, NZ, 0.25, origin, err, sizeof err) == RD_OK, "%s", err);
    rd_scene *s = rt_scene("vdb.json",
                           "{\"camera\":{\"position\":[0,0,9],\"look_at\":[1,2,3],\"resolution\":[4,4]},"
                           "\"media\":[{\"density\":{\"type\":\"vdb\",\"file\":\"g.vdb\",\"grid\":\"density\"},\"sigma_t\":1}]}");
    const rd_medium *m = &s->media[0];
    cr_expect(m->grid.nx == NX && m->grid.ny == NY && m->grid.nz == NZ);
    /* World bounds: voxel centres from origin to origin + 0.25 (n-1), grown by one voxel. */
    cr_expect(fabs(m->bmin.x - 0.75) < 1e-9 && fabs(m->bmin.y - 1.75) < 1e-9 && fabs(m->bmin.z - 2.75) < 1e-9,
              "bmin (%g %g %g)", m->bmin.x, m->bmin.y, m->bmin.z);
    cr_expect(fabs(m->bmax.x - (1 + 0.25 * NX)) < 1e-9 && fabs(m->bmax.z - (3 + 0.25 * NZ)) < 1e-9,
              "bmax (%g %g %g)", m->bmax.x, m->bmax.y, m->bmax.z);
    /* At every voxel centre the density is that voxel's value. */
    for (int k = 0; k < NZ; k++)
        for (int j = 0; j < NY; j++)
            for (int i = 0; i < NX; i++) {
                double d = rd_medium_density(m, v3(1 + 0.25 * i, 2 + 0.25 * j, 3 + 0.25 * k));
                cr_expect(fabs(d - v[(k * NY + j) * NX + i]) < 1e-6, "voxel (%d %d %d): %g", i, j, k, d);
            }
    cr_expect(fabs(m->density_max - 0.1 * 16 - 0.05) < 1e-6);
    rd_scene_free(s);
}

Test(volume, truncated_and_wrong_vdb_files_are_rejected, .timeout = 60)
{
    float v[8] = {1, 1, 1, 1, 1, 1, 1, 1};
    char path[256], cut[256], err[RD_ERRLEN];
    snprintf(path, sizeof path, "%s/ok.vdb", rt_tmpdir());
    snprintf(cut, sizeof cut, "%s/cut.vdb", rt_tmpdir());
    const double origin[3] = {0, 0, 0};
    cr_assert(rd_vdb_save_dense(path, "density", v, 2, 2, 2, 1.0, origin, err, sizeof err) == RD_OK, "%s", err);
    FILE *f = fopen(path, "rb");
    char buf[65536];
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    rd_grid g;
    vec3 lo, hi;
    for (size_t len = 0; len < n; len += n / 7 + 1) {
        rt_write_file(cut, buf, len);
        memset(&g, 0, sizeof g);
        rd_status st = rd_vdb_load(cut, "density", &g, &lo, &hi, err, sizeof err);
        cr_expect(st != RD_OK, "a file cut at %zu of %zu bytes was accepted", len, n);
        cr_expect(strncmp(err, cut, strlen(cut)) == 0, "message names the file: %s", err);
        cr_expect(g.data == NULL);
    }
    cr_expect(rd_vdb_load(path, "temperature", &g, &lo, &hi, err, sizeof err) == RD_ERR_FORMAT);
    cr_expect(strstr(err, "no grid named \"temperature\" (grids: density)") != NULL, "%s", err);
    cr_expect(rd_vdb_load(path, "density", &g, &lo, &hi, err, sizeof err) == RD_OK, "%s", err);
    free(g.data);
}

Test(volume, noise_stays_within_its_majorant_bound)
{
    /* rd_noise_fbm_bound uses |noise| <= 1.04 per octave (see media/density.c). Check the envelope
     * E(f) = sum_c w_c (largest two |f - c|) on 200000 random points, and the noise itself (several
     * seeds) on 200000 points; a bound that a single sample beats is wrong. */
    pcg32 rng = pcg32_seed(8, 8, 8);
    double emax = 0, nmax = 0;
    for (int i = 0; i < 200000; i++) {
        double f[3] = {pcg32_uniform(&rng), pcg32_uniform(&rng), pcg32_uniform(&rng)}, w[3], e = 0;
        for (int a = 0; a < 3; a++) w[a] = f[a] * f[a] * f[a] * (f[a] * (f[a] * 6 - 15) + 10);
        for (int c = 0; c < 8; c++) {
            double wc = 1, d[3];
            for (int a = 0; a < 3; a++) {
                int bit = (c >> a) & 1;
                wc *= bit ? w[a] : 1 - w[a];
                d[a] = fabs(f[a] - bit);
            }
            double mn = fmin(d[0], fmin(d[1], d[2]));
            e += wc * (d[0] + d[1] + d[2] - mn);
        }
        emax = fmax(emax, e);
    }
    cr_expect(emax < 1.04 && emax > 1.0, "envelope maximum %.5f", emax);
    for (uint32_t seed = 1; seed <= 4; seed++) {
        rd_noise n = {.octaves = 1, .frequency = 1, .gain = 0.5, .lacunarity = 2, .seed = seed};
        rd_noise_init_perm(&n);
        for (int i = 0; i < 50000; i++) {
            vec3 x = v3(40 * pcg32_uniform(&rng), 40 * pcg32_uniform(&rng), 40 * pcg32_uniform(&rng));
            nmax = fmax(nmax, fabs(rd_noise_eval(&n, x)));
        }
    }
    cr_expect(nmax <= 1.04 && nmax > 0.5, "noise maximum %.5f", nmax);
    rd_noise n5 = {.octaves = 5, .gain = 0.5};
    cr_expect(fabs(rd_noise_fbm_bound(&n5) - 1.04 * (1 + 0.5 + 0.25 + 0.125 + 0.0625)) < 1e-12);
}

Test(volume, noise_equals_perlins_formula)
{
    /* rd_perlin_grad reads a table instead of branching (rd_medium.h). Its products are exact,
     * so every gradient term, the noise, the fBm and the density must equal the 2002 formula's
     * as doubles (==: equal values; an exact zero may differ in sign, which 1 + a fbm erases),
     * and the density bit for bit. Points: random in a wide box (negative coordinates, lattice
     * indices past 255), some on lattice planes (a fractional coordinate exactly 0). */
    pcg32 rng = pcg32_seed(21, 1, 0);
    for (int h = 0; h < 256; h++)
        for (int i = 0; i < 64; i++) {
            double x = 4 * pcg32_uniform(&rng) - 2, y = 4 * pcg32_uniform(&rng) - 2, z = 4 * pcg32_uniform(&rng) - 2;
            if (i == 0) x = y = z = 0.0;
            if (i == 1) x = 0.0;
            double a = rd_perlin_grad(h, x, y, z), b = perlin_grad_2002(h, x, y, z), g[3];
            cr_assert(a == b, "grad h %d at (%.17g, %.17g, %.17g): %.17g vs %.17g", h, x, y, z, a, b);
            rd_perlin_grad_vec(h, g);
            cr_assert(g[0] * x + g[1] * y + g[2] * z == b, "grad_vec h %d", h);
        }
    long checked = 0;
    for (uint32_t seed = 1; seed <= 3; seed++) {
        rd_medium m = {.bmin = v3(-300, -300, -300), .bmax = v3(300, 300, 300), .kind = RD_DENSITY_NOISE,
                       .sigma_t_scale = 1};
        rd_noise *n = &m.noise;
        *n = (rd_noise){.octaves = 6, .frequency = 1.7, .gain = 0.55, .lacunarity = 2.1, .amplitude = 2.5,
                        .seed = seed, .shape = seed == 2 ? RD_SHAPE_ELLIPSOID : RD_SHAPE_NONE,
                        .center = v3(0.3, -0.2, 0.1), .radii = v3(300, 300, 300), .edge = 0.5};
        rd_noise_init_perm(n);
        for (int i = 0; i < 100000; i++) {
            vec3 x = v3(600 * pcg32_uniform(&rng) - 300, 600 * pcg32_uniform(&rng) - 300,
                        600 * pcg32_uniform(&rng) - 300);
            if (i % 5 == 1) x.x = floor(x.x);
            if (i % 7 == 2) x = v3(floor(x.x), floor(x.y), floor(x.z));
            double a = rd_noise_eval(n, x), b = perlin_noise_2002(n, x);
            cr_assert(a == b, "noise at (%.17g, %.17g, %.17g): %.17g vs %.17g", x.x, x.y, x.z, a, b);
            double fa = rd_noise_fbm(n, x), fb = 0.0, amp = 1.0, f = n->frequency;
            vec3 q = v3_sub(x, n->center);
            for (int o = 0; o < n->octaves; o++) {
                fb += amp * perlin_noise_2002(n, v3_scale(q, f));
                amp *= n->gain;
                f *= n->lacunarity;
            }
            cr_assert(fa == fb, "fbm at (%.17g, %.17g, %.17g): %.17g vs %.17g", x.x, x.y, x.z, fa, fb);
            double da = rd_medium_density(&m, x), d = 1.0 + n->amplitude * fb, db = 0.0;
            if (n->shape == RD_SHAPE_NONE) db = d > 0.0 ? d : 0.0;
            else {
                vec3 e = v3_sub(x, n->center);
                double r = sqrt((e.x * e.x) / (n->radii.x * n->radii.x) + (e.y * e.y) / (n->radii.y * n->radii.y) +
                                (e.z * e.z) / (n->radii.z * n->radii.z));
                double s = rd_shape_of_r(n->edge, r);
                db = s <= 0.0 ? 0.0 : d > 0.0 ? s * d : 0.0;
            }
            cr_assert(memcmp(&da, &db, sizeof da) == 0, "density at (%.17g, %.17g, %.17g): %a vs %a", x.x, x.y,
                      x.z, da, db);
            checked++;
        }
    }
    cr_expect(checked == 300000);
}

Test(volume, early_exit_accept_test_equals_the_full_density)
{
    /* rd_medium_sigma_above stops adding octaves once their bound decides thr < sigma; its
     * answer must be the full evaluation's for every threshold, also thresholds within a few
     * ulps of sigma (where no early exit is allowed) and at 0. Media: the default scene's
     * smoke, and noise with other gains, octaves, a gain of 0 and 1, and a large amplitude. */
    const double gains[] = {0.5, 0.8, 0.0, 1.0, 0.3};
    const int octaves[] = {5, 7, 3, 2, 1};
    const double amps[] = {3.0, 1.0, 2.0, 0.5, 40.0};
    pcg32 rng = pcg32_seed(21, 2, 0);
    long early_checked = 0;
    for (int c = 0; c < 5; c++) {
        rd_medium m = {.bmin = v3(-1.4, -1, -1), .bmax = v3(1.4, 1, 1), .kind = RD_DENSITY_NOISE, .sigma_t_scale = 2};
        m.noise = (rd_noise){.octaves = octaves[c], .frequency = 2.2, .gain = gains[c], .lacunarity = 2.0,
                             .amplitude = amps[c], .seed = 7 + c, .shape = c == 4 ? RD_SHAPE_NONE : RD_SHAPE_ELLIPSOID,
                             .center = v3(0, 0, 0), .radii = v3(1.4, 1, 1), .edge = 0.6};
        rd_noise_init_perm(&m.noise);
        for (int i = 0; i < 40000; i++) {
            vec3 x = v3(3.0 * pcg32_uniform(&rng) - 1.5, 2.2 * pcg32_uniform(&rng) - 1.1, 2.2 * pcg32_uniform(&rng) - 1.1);
            double sig = rd_medium_density(&m, x) * m.sigma_t_scale;
            double thr[6] = {pcg32_uniform(&rng) * 2.0 * sig, pcg32_uniform(&rng) * 20.0, sig, nextafter(sig, 0.0),
                             nextafter(sig, INFINITY), 0.0};
            for (int k = 0; k < 6; k++) {
                int want = thr[k] < sig, got = rd_medium_sigma_above(&m, x, m.sigma_t_scale, thr[k]);
                cr_assert(got == want, "medium %d at (%.17g, %.17g, %.17g): thr %a, sigma %a: %d, full %d", c, x.x,
                          x.y, x.z, thr[k], sig, got, want);
                early_checked++;
            }
        }
    }
    cr_expect(early_checked == 5 * 40000 * 6);
}

/* ---- Two media along one ray ------------------------------------------------------------- */

/* Two disjoint boxes on the x axis with different sigma_t, albedo and g. */
#define TWO_MEDIA                                                                                  \
    "\"media\":[{\"bounds\":{\"min\":[-2,-1,-1],\"max\":[-0.5,1,1]},\"density\":1,"                 \
    "\"sigma_t\":1.0,\"albedo\":0.8,\"g\":0.5},"                                                    \
    "{\"bounds\":{\"min\":[0.5,-1,-1],\"max\":[2,1,1]},\"density\":1,"                              \
    "\"sigma_t\":1.6,\"albedo\":0.6,\"g\":-0.3}]"

/* Optical depth of the segment a->b through every medium of s (homogeneous media). */
static double optical_depth(const rd_scene *s, vec3 a, vec3 b)
{
    double tau = 0.0;
    for (int i = 0; i < s->n_media; i++)
        tau += s->media[i].sigma_t_scale * s->media[i].constant *
               rt_inside_length(s->media[i].bmin, s->media[i].bmax, a, b);
    return tau;
}

typedef struct {
    const rd_scene *s;
    const rd_medium *m; /* the medium this piece of the ray is in */
    ray3 ray;
} two_media_ctx;

/* T(o, x) sigma_s(x) p(d . wi) I / r^2 T(x, light) per unit intensity (THEORY.md §1, one
 * scattering event), x = o + t d inside medium m. */
static double two_media_integrand(double t, const void *p)
{
    const two_media_ctx *c = p;
    const rd_light *l = &c->s->lights[0];
    vec3 x = ray_at(c->ray, t), tol = v3_sub(l->pos, x);
    double r2 = v3_dot(tol, tol);
    vec3 wi = v3_scale(tol, 1.0 / sqrt(r2));
    double sigma_s = c->m->sigma_t_scale * c->m->albedo.y;
    return exp(-optical_depth(c->s, c->ray.o, x)) * sigma_s * rd_hg_eval(c->m->g, v3_dot(c->ray.d, wi)) / r2 *
           exp(-optical_depth(c->s, x, l->pos));
}

/* The single-scattering integral split at the media's faces, with n intervals per medium. */
static double two_media_quadrature(const rd_scene *s, ray3 r, int n)
{
    double q = 0.0;
    for (int i = 0; i < s->n_media; i++) {
        double t0, t1;
        cr_assert(rd_box_intersect(s->media[i].bmin, s->media[i].bmax, r, 0, INFINITY, &t0, &t1));
        two_media_ctx c = {s, &s->media[i], r};
        q += rt_simpson(two_media_integrand, &c, t0, t1, n);
    }
    return q;
}

Test(volume, two_media_single_scattering, .timeout = 60)
{
    /* A point light above the gap between the media lights both; the ray crosses both. */
    rd_scene *s = rt_scene("two.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]}," TWO_MEDIA ","
                           "\"lights\":[{\"type\":\"point\",\"position\":[0,1.5,0.2],\"intensity\":[4,5,6]}],"
                           "\"settings\":{\"max_depth\":1}}");
    ray3 r = {v3(-4, 0.1, 0.05), v3_norm(v3(1, 0.02, 0))};
    /* The light's path length in a box has kinks where its exit face changes, so Simpson is
     * second order there: the doubling check bounds the error. */
    double q = two_media_quadrature(s, r, 20000), q_half = two_media_quadrature(s, r, 10000);
    rt_mc mc = rt_delta_mc(s, r, 200000, 601);
    cr_assert(fabs(q - q_half) * 5.0 < 0.01 * mc.se.y, "quadrature not converged: %.3e vs %.3e", q, q_half);
    const double I[3] = {4, 5, 6};
    for (int k = 0; k < 3; k++) {
        double exact = I[k] * q, m = v3_get(mc.mean, k), se = v3_get(mc.se, k);
        cr_expect(fabs(m - exact) < 5.0 * se, "channel %d: delta %.6f vs quadrature %.6f (se %.6f)", k, m, exact, se);
        cr_expect(se < 0.02 * exact, "channel %d: se %.6f not below 2%% of %.6f", k, se, exact);
    }
    rd_scene_free(s);
}

Test(volume, background_through_two_media, .timeout = 60)
{
    /* No lights: the camera sees the background where the path crosses both media without a
     * real collision, which happens with probability exp(-tau1 - tau2). */
    rd_scene *s = rt_scene("two_bg.json",
                           "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]}," TWO_MEDIA ","
                           "\"background\":[1,0.5,0.25]}");
    ray3 r = {v3(-4, 0.3, -0.2), v3_norm(v3(1, -0.05, 0.08))};
    double tau1 = 1.0 * rt_inside_length(s->media[0].bmin, s->media[0].bmax, r.o, ray_at(r, 10));
    double tau2 = 1.6 * rt_inside_length(s->media[1].bmin, s->media[1].bmax, r.o, ray_at(r, 10));
    cr_assert(tau1 > 1.0 && tau2 > 2.0, "the ray must cross both media (tau %g, %g)", tau1, tau2);
    rt_mc mc = rt_delta_mc(s, r, 200000, 602);
    const double bg[3] = {1, 0.5, 0.25};
    for (int k = 0; k < 3; k++) {
        double exact = bg[k] * exp(-tau1 - tau2), m = v3_get(mc.mean, k), se = v3_get(mc.se, k);
        cr_expect(fabs(m - exact) < 5.0 * se, "channel %d: %.6f vs exp(-tau1-tau2) %.6f (se %.6f)", k, m, exact, se);
        cr_expect(se < 0.02 * exact, "channel %d: se %.6f not below 2%% of %.6f", k, se, exact);
        /* Power: missing either medium would be far outside the tolerance. */
        cr_expect(fabs(bg[k] * exp(-tau1) - exact) > 20 * se && fabs(bg[k] * exp(-tau2) - exact) > 20 * se);
    }
    rd_scene_free(s);
}

/* ---- Orthographic camera ----------------------------------------------------------------- */

static void expect_vec(vec3 a, vec3 b, const char *what)
{
    cr_expect(v3_len(v3_sub(a, b)) < 1e-12, "%s: (%.15g %.15g %.15g), expected (%g %g %g)", what, a.x, a.y, a.z, b.x,
              b.y, b.z);
}

Test(volume, orthographic_camera_rays)
{
    /* Looking along -x with up +y: forward (-1,0,0), right = forward x up = (0,0,-1), up (0,1,0).
     * Width 4 over 8 pixels, so the view is 4 x 2 (height = width * 4/8), centred on (5,1,2).
     * Film (px, py) maps to pos + right (px/8 - 0.5) 4 + up (0.5 - py/4) 2. */
    rd_scene *s = rt_scene("ortho.json",
                           "{\"camera\":{\"type\":\"orthographic\",\"position\":[5,1,2],\"direction\":[-3,0,0],"
                           "\"up\":[0,1,0],\"width\":4,\"resolution\":[8,4]},\"media\":[]}");
    const rd_camera *cam = &s->camera;
    expect_vec(rd_camera_ray(cam, 0, 0).o, v3(5, 2, 4), "top-left corner");
    expect_vec(rd_camera_ray(cam, 8, 0).o, v3(5, 2, 0), "top-right corner");
    expect_vec(rd_camera_ray(cam, 0, 4).o, v3(5, 0, 4), "bottom-left corner");
    expect_vec(rd_camera_ray(cam, 8, 4).o, v3(5, 0, 0), "bottom-right corner");
    expect_vec(rd_camera_ray(cam, 4, 2).o, v3(5, 1, 2), "centre");
    expect_vec(rd_camera_ray(cam, 0.5, 0.5).o, v3(5, 1.75, 3.75), "centre of pixel (0,0)");
    /* Every ray is parallel to the view direction. */
    for (int py = 0; py <= 8; py++)
        for (int px = 0; px <= 16; px++) expect_vec(rd_camera_ray(cam, 0.5 * px, 0.5 * py).d, v3(-1, 0, 0), "direction");
    rd_scene_free(s);
}

Test(volume, orthographic_view_of_a_slab, .timeout = 60)
{
    /* A slab 0.5 thick (sigma_t 1.2, no lights) in front of a constant background, seen
     * head-on through an orthographic camera: every ray crosses the same thickness, so every
     * pixel's expectation is background exp(-0.6). With no light the estimator of each sample
     * is background times a Bernoulli(T) (escape without a real collision), so the standard
     * error of a pixel is exactly background sqrt(T (1 - T) / spp). */
    rd_scene *s = rt_scene("ortho_slab.json",
                           "{\"camera\":{\"type\":\"orthographic\",\"position\":[0,0,5],\"direction\":[0,0,-1],"
                           "\"width\":4,\"resolution\":[16,12]},"
                           "\"media\":[{\"bounds\":{\"min\":[-3,-3,-0.25],\"max\":[3,3,0.25]},\"density\":1,"
                           "\"sigma_t\":1.2,\"albedo\":0.7,\"g\":0.3}],"
                           "\"background\":[1,2,3]}");
    const int spp = 3000;
    rd_render_opts o = {.method = "delta", .spp = spp, .seed = 77, .threads = 2};
    rd_render_result res;
    char err[RD_ERRLEN];
    cr_assert(rd_render(s, &o, &res, err, sizeof err) == RD_OK, "%s", err);
    const rd_image img = res.image;
    double T = exp(-1.2 * 0.5), se1 = sqrt(T * (1 - T) / spp), sum = 0;
    int npix = img.w * img.h;
    for (int p = 0; p < npix; p++)
        for (int k = 0; k < 3; k++) {
            double bg = k + 1, v = img.rgb[3 * p + k];
            cr_expect(fabs(v - bg * T) < 5 * bg * se1, "pixel %d channel %d: %.5f vs %.5f (se %.5f)", p, k, v, bg * T,
                      bg * se1);
            if (k == 0) sum += v;
        }
    /* The image mean: independent pixels, standard error se1 / sqrt(npix). */
    double mean = sum / npix;
    cr_expect(fabs(mean - T) < 5 * se1 / sqrt(npix), "image mean %.6f vs %.6f (se %.6f)", mean, T, se1 / sqrt(npix));
    cr_expect(se1 < 0.02 * T);
    /* The film's own standard error of every pixel is that exact value: the sample standard
     * deviation of n Bernoulli draws has relative error about sqrt((1 - 3 T (1 - T)) /
     * (4 n T (1 - T))) (delta method on the fourth moment); 5 of those. */
    double q = T * (1 - T), rel = 5.0 * sqrt((1.0 - 3.0 * q) / (4.0 * spp * q));
    for (int p = 0; p < npix; p++)
        for (int k = 0; k < 3; k++) {
            double bg = k + 1, e = res.stderr_img.rgb[3 * p + k];
            cr_expect(fabs(e / (bg * se1) - 1.0) < rel, "pixel %d channel %d: stderr %.6f vs %.6f", p, k, e, bg * se1);
        }
    rd_render_result_free(&res);
    rd_scene_free(s);
}

/* ---- voxelize round trips ---------------------------------------------------------------- */

/* Run `photonmarch voxelize scene --res 32 -o out`; returns the dims it printed. */
static void voxelize(const char *bin, const char *scene, const char *out, int dims[3])
{
    char so[4096], se[4096];
    char *argv[] = {(char *)bin, "voxelize", (char *)scene, "--res", "32", "-o", (char *)out, NULL};
    int code = rt_run(argv, so, sizeof so, se, sizeof se, NULL);
    cr_assert(code == 0, "voxelize %s: exit %d: %s", out, code, se);
    const char *p = strstr(so, ": ");
    cr_assert(p && sscanf(p + 2, "%dx%dx%d", &dims[0], &dims[1], &dims[2]) == 3, "no dims in: %s", so);
}

Test(volume, voxelize_raw_and_vdb_round_trip, .timeout = 60)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL, "PHOTONMARCH_BIN is not set (run through make test)");
    /* Bounds 2 x 1 x 2 at 32 voxels along the longest axis: cubic voxels of 1/16, dims
     * 32x16x32, so the raw grid (cells of bounds/dims) and the VDB grid (cubic voxels from
     * min) put their voxel centres at the same points. Amplitude 0.5 keeps the density above
     * 1 - 0.5 * 1.04 * 1.75 > 0, so no VDB voxel is inactive. */
    const char *noise = "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                        "\"media\":[{\"bounds\":{\"min\":[-1,-0.5,-1],\"max\":[1,0.5,1]},"
                        "\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":1.5,\"amplitude\":0.5,"
                        "\"shape\":\"none\",\"seed\":3},\"sigma_t\":1}]}";
    rd_scene *orig = rt_scene("noise.json", noise);
    char scene[256], raw[256], vdb[256], json[1024];
    snprintf(scene, sizeof scene, "%s/noise.json", rt_tmpdir());
    snprintf(raw, sizeof raw, "%s/n.raw", rt_tmpdir());
    snprintf(vdb, sizeof vdb, "%s/n.vdb", rt_tmpdir());
    int dr[3], dv[3];
    voxelize(bin, scene, raw, dr);
    voxelize(bin, scene, vdb, dv);
    cr_assert(dr[0] == 32 && dr[1] == 16 && dr[2] == 32, "raw dims %dx%dx%d", dr[0], dr[1], dr[2]);
    cr_assert(dv[0] == 32 && dv[1] == 16 && dv[2] == 32, "vdb dims %dx%dx%d", dv[0], dv[1], dv[2]);
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
             "\"media\":[{\"bounds\":{\"min\":[-1,-0.5,-1],\"max\":[1,0.5,1]},"
             "\"density\":{\"type\":\"raw\",\"file\":\"n.raw\",\"dims\":[%d,%d,%d]},\"sigma_t\":1}]}",
             dr[0], dr[1], dr[2]);
    rd_scene *sr = rt_scene("raw.json", json);
    rd_scene *sv = rt_scene("vdb.json", "{\"camera\":{\"position\":[0,0,5],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                                        "\"media\":[{\"density\":{\"type\":\"vdb\",\"file\":\"n.vdb\"},\"sigma_t\":1}]}");
    const rd_medium *mo = &orig->media[0], *mr = &sr->media[0], *mv = &sv->media[0];
    cr_expect(mv->grid.nx == 32 && mv->grid.ny == 16 && mv->grid.nz == 32, "every VDB voxel is active");
    /* VDB bounds: the voxel box grown by one voxel for the trilinear support. */
    const double h = 1.0 / 16;
    cr_expect(v3_len(v3_sub(mv->bmin, v3(-1 - 0.5 * h, -0.5 - 0.5 * h, -1 - 0.5 * h))) < 1e-9);
    cr_expect(v3_len(v3_sub(mv->bmax, v3(1 + 0.5 * h, 0.5 + 0.5 * h, 1 + 0.5 * h))) < 1e-9);
    /* At every voxel centre both give the original noise, rounded to float. */
    for (int k = 0; k < 32; k++)
        for (int j = 0; j < 16; j++)
            for (int i = 0; i < 32; i++) {
                vec3 x = v3(-1 + (i + 0.5) * h, -0.5 + (j + 0.5) * h, -1 + (k + 0.5) * h);
                double d = rd_medium_density(mo, x), a = rd_medium_density(mr, x), b = rd_medium_density(mv, x);
                cr_assert(fabs(a - d) <= 1e-6 * d && fabs(b - d) <= 1e-6 * d,
                          "voxel (%d %d %d): noise %.9g, raw %.9g, vdb %.9g", i, j, k, d, a, b);
            }
    /* Anywhere inside the bounds (including the outer half voxel, where both fade toward the
     * empty border) the two grids interpolate the same floats between the same centres. */
    pcg32 rng = pcg32_seed(6, 6, 6);
    for (int n = 0; n < 100000; n++) {
        vec3 x = v3(-1 + 2 * pcg32_uniform(&rng), -0.5 + pcg32_uniform(&rng), -1 + 2 * pcg32_uniform(&rng));
        double a = rd_medium_density(mr, x), b = rd_medium_density(mv, x);
        cr_assert(fabs(a - b) <= 1e-6 * fmax(a, 1e-3), "at (%g %g %g): raw %.9g, vdb %.9g", x.x, x.y, x.z, a, b);
    }
    rd_scene_free(orig);
    rd_scene_free(sr);
    rd_scene_free(sv);
}

/* ---- Rotated VDB transforms -------------------------------------------------------------- */

/* Trilinear interpolation of a dense nx*ny*nz array at continuous index u (voxel (i,j,k) at
 * integer u), 0 outside the voxels: the reference the loader is compared with. */
static double trilinear_index(const float *v, const int n[3], const double u[3])
{
    int i0[3];
    double f[3];
    for (int a = 0; a < 3; a++) {
        i0[a] = (int)floor(u[a]);
        f[a] = u[a] - i0[a];
    }
    double sum = 0.0;
    for (int c = 0; c < 8; c++) {
        int idx[3];
        double w = 1.0;
        for (int a = 0; a < 3; a++) {
            int bit = (c >> a) & 1;
            idx[a] = i0[a] + bit;
            w *= bit ? f[a] : 1.0 - f[a];
        }
        if (idx[0] < 0 || idx[1] < 0 || idx[2] < 0 || idx[0] >= n[0] || idx[1] >= n[1] || idx[2] >= n[2]) continue;
        sum += w * v[(idx[2] * n[1] + idx[1]) * n[0] + idx[0]];
    }
    return sum;
}

/* world = M (u, 1) */
static vec3 affine_apply(const double M[4][4], const double u[3])
{
    double w[3];
    for (int r = 0; r < 3; r++) w[r] = M[r][0] * u[0] + M[r][1] * u[1] + M[r][2] * u[2] + M[r][3];
    return v3(w[0], w[1], w[2]);
}

Test(volume, rotated_vdb_transform, .timeout = 60)
{
    /* Index to world: scale (0.2, 0.3, 0.25), then a rotation of 35 degrees about (1, 2, 3),
     * then a translation (0.5, -1, 2): M = T R S. */
    enum { NX = 5, NY = 4, NZ = 6 };
    const int n[3] = {NX, NY, NZ};
    float v[NX * NY * NZ];
    for (int i = 0; i < NX * NY * NZ; i++) v[i] = 0.2f + 0.05f * (float)((i * 7) % 23);
    vec3 ax = v3_norm(v3(1, 2, 3));
    double th = 35 * M_PI / 180, c = cos(th), sn = sin(th), a[3] = {ax.x, ax.y, ax.z}, R[3][3];
    for (int r = 0; r < 3; r++) /* Rodrigues: R = c I + s [a]x + (1 - c) a a^T */
        for (int q = 0; q < 3; q++) R[r][q] = (r == q ? c : 0.0) + (1 - c) * a[r] * a[q];
    R[0][1] -= sn * a[2], R[0][2] += sn * a[1], R[1][0] += sn * a[2];
    R[1][2] -= sn * a[0], R[2][0] -= sn * a[1], R[2][1] += sn * a[0];
    const double scale[3] = {0.2, 0.3, 0.25}, trans[3] = {0.5, -1, 2};
    double M[4][4] = {{0}};
    for (int r = 0; r < 3; r++) {
        for (int q = 0; q < 3; q++) M[r][q] = R[r][q] * scale[q];
        M[r][3] = trans[r];
    }
    M[3][3] = 1;
    char path[256], err[RD_ERRLEN];
    snprintf(path, sizeof path, "%s/rot.vdb", rt_tmpdir());
    cr_assert(rd_vdb_save_dense_affine(path, "density", v, NX, NY, NZ, M, err, sizeof err) == RD_OK, "%s", err);
    rd_scene *s = rt_scene("rot.json", "{\"camera\":{\"position\":[0,0,9],\"look_at\":[0,0,0],\"resolution\":[4,4]},"
                                       "\"media\":[{\"density\":{\"type\":\"vdb\",\"file\":\"rot.vdb\"},\"sigma_t\":1}]}");
    const rd_medium *m = &s->media[0];
    cr_expect(m->grid.nx == NX && m->grid.ny == NY && m->grid.nz == NZ);
    /* The bounds contain the rotated box of the trilinear support (index -1 .. n). */
    for (int corner = 0; corner < 8; corner++) {
        double u[3];
        for (int q = 0; q < 3; q++) u[q] = (corner >> q) & 1 ? n[q] : -1.0;
        vec3 w = affine_apply(M, u);
        for (int q = 0; q < 3; q++)
            cr_expect(v3_get(w, q) >= v3_get(m->bmin, q) - 1e-9 && v3_get(w, q) <= v3_get(m->bmax, q) + 1e-9,
                      "corner %d axis %d: %g outside [%g, %g]", corner, q, v3_get(w, q), v3_get(m->bmin, q),
                      v3_get(m->bmax, q));
    }
    /* At the world position of every voxel centre, that voxel's value. */
    for (int k = 0; k < NZ; k++)
        for (int j = 0; j < NY; j++)
            for (int i = 0; i < NX; i++) {
                double u[3] = {i, j, k};
                double d = rd_medium_density(m, affine_apply(M, u));
                cr_expect(fabs(d - v[(k * NY + j) * NX + i]) < 1e-6, "voxel (%d %d %d): %g, expected %g", i, j, k, d,
                          (double)v[(k * NY + j) * NX + i]);
            }
    /* Between centres, the trilinear interpolation in index space of the points they map to. */
    pcg32 rng = pcg32_seed(7, 7, 7);
    for (int t = 0; t < 20000; t++) {
        double u[3];
        for (int q = 0; q < 3; q++) u[q] = -0.9 + (n[q] - 0.2) * pcg32_uniform(&rng);
        double d = rd_medium_density(m, affine_apply(M, u)), e = trilinear_index(v, n, u);
        cr_assert(fabs(d - e) < 1e-6, "index (%g %g %g): %.9g, expected %.9g", u[0], u[1], u[2], d, e);
    }
    rd_scene_free(s);
}

Test(volume, affine_vdb_writer_refuses_singular_matrices)
{
    float v[8] = {1, 1, 1, 1, 1, 1, 1, 1};
    double M[4][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {1, 0, 0, 0}, {0, 0, 0, 1}};
    char path[256], err[RD_ERRLEN];
    snprintf(path, sizeof path, "%s/singular.vdb", rt_tmpdir());
    cr_expect(rd_vdb_save_dense_affine(path, "density", v, 2, 2, 2, M, err, sizeof err) == RD_ERR_ARG);
    cr_expect(strstr(err, path) && strstr(err, "singular"), "%s", err);
    cr_expect(access(path, F_OK) != 0, "nothing is written");
}

/* ---- Sparse OpenVDB grids (brick map) ------------------------------------------------------- */

/* A test grid with leaves, tiles and (optionally) a non-zero background inside its active box:
 * a 37x29x21 block of values (a third of them zero) at index (-13, 5, 3), whose origin is not a
 * multiple of 8, plus a filled 16^3 box at an aligned place (two 8^3 tiles per axis) and a
 * filled 5^3 box that cuts leaves. Returns the file's path in `path`. */
static void write_mixed_grid(char *path, size_t n, const char *name, float background)
{
    enum { NX = 37, NY = 29, NZ = 21 };
    static float v[NX * NY * NZ];
    pcg32 rng = pcg32_seed(12, 1, 0);
    for (int q = 0; q < NX * NY * NZ; q++) {
        double u = pcg32_uniform(&rng);
        v[q] = u < 1.0 / 3.0 ? 0.0f : (float)(4.0 * u);
    }
    const int origin[3] = {-13, 5, 3};
    const int boxes[2][6] = {{8, 40, 8, 23, 55, 23}, {-20, 1, 1, -16, 5, 5}};
    const float values[2] = {0.75f, 2.5f};
    char err[RD_ERRLEN];
    snprintf(path, n, "%s/%s", rt_tmpdir(), name);
    cr_assert(rd_vdb_save_test(path, "density", "float", background, v, NX, NY, NZ, origin, boxes, values, 2, err,
                               sizeof err) == RD_OK, "%s", err);
}

/* The sparse grid gives the dense grid's voxels, trilinear lookups and box bounds exactly (the
 * same floats through the same arithmetic, so equality is bit-exact, not a tolerance). */
static void check_sparse_matches_dense(float background)
{
    char path[256], err[RD_ERRLEN];
    write_mixed_grid(path, sizeof path, "mixed.vdb", background);
    rd_grid sp, de;
    vec3 slo, shi, dlo, dhi;
    memset(&sp, 0, sizeof sp);
    memset(&de, 0, sizeof de);
    cr_assert(rd_vdb_load_sparse(path, "density", &sp, &slo, &shi, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(rd_vdb_load_dense(path, "density", &de, &dlo, &dhi, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(sp.data == NULL && sp.bricks != NULL && de.data != NULL);
    cr_expect(sp.nx == de.nx && sp.ny == de.ny && sp.nz == de.nz);
    cr_expect(memcmp(sp.w2g, de.w2g, sizeof sp.w2g) == 0);
    cr_expect(v3_len(v3_sub(slo, dlo)) == 0.0 && v3_len(v3_sub(shi, dhi)) == 0.0);
    cr_expect(sp.vmin == de.vmin && sp.vmax == de.vmax, "vmin %g/%g vmax %g/%g", sp.vmin, de.vmin, sp.vmax, de.vmax);
    /* Active box: x from -20 (the small box) to 23, y 1..55, z 1..23: 44 x 55 x 23 voxels. */
    cr_expect(sp.nx == 44 && sp.ny == 55 && sp.nz == 23, "%dx%dx%d", sp.nx, sp.ny, sp.nz);
    const rd_bricks *b = sp.bricks;
    size_t cells = (size_t)b->nb[0] * b->nb[1] * b->nb[2], tiles = 0;
    for (size_t c = 0; c < cells; c++) tiles += b->brick[c] < 0 && b->cmax[c] == 0.75f;
    cr_expect(tiles == 8, "the 16^3 fill is 8 constant cells, found %zu", tiles);
    cr_expect(b->n_bricks < cells);
    /* Every voxel, one layer of border beyond the grid included. */
    for (int k = -1; k <= sp.nz; k++)
        for (int j = -1; j <= sp.ny; j++)
            for (int i = -1; i <= sp.nx; i++)
                cr_assert(rd_grid_voxel(&sp, i, j, k) == rd_grid_voxel(&de, i, j, k), "voxel (%d %d %d)", i, j, k);
    /* Lookups at random points of the bounds grown by 10%, and bounds of random boxes (as the
     * majorant grids ask them: rd_medium_box_bound on a grid medium). */
    rd_medium ms, md;
    memset(&ms, 0, sizeof ms);
    memset(&md, 0, sizeof md);
    ms.kind = md.kind = RD_DENSITY_GRID;
    ms.grid = sp;
    md.grid = de;
    vec3 ext = v3_sub(shi, slo), lo0 = v3_sub(slo, v3_scale(ext, 0.05));
    pcg32 rng = pcg32_seed(12, 2, 0);
    for (int n = 0; n < 200000; n++) {
        vec3 x = v3(lo0.x + 1.1 * ext.x * pcg32_uniform(&rng), lo0.y + 1.1 * ext.y * pcg32_uniform(&rng),
                    lo0.z + 1.1 * ext.z * pcg32_uniform(&rng));
        double a = rd_grid_lookup(&sp, x), d = rd_grid_lookup(&de, x);
        cr_assert(a == d, "lookup at (%g %g %g): sparse %.17g, dense %.17g", x.x, x.y, x.z, a, d);
    }
    for (int n = 0; n < 20000; n++) {
        vec3 p = v3(lo0.x + 1.1 * ext.x * pcg32_uniform(&rng), lo0.y + 1.1 * ext.y * pcg32_uniform(&rng),
                    lo0.z + 1.1 * ext.z * pcg32_uniform(&rng));
        double s = n < 10000 ? 3.0 : 25.0; /* boxes of up to 3 and up to 25 voxels per side */
        vec3 q = v3(p.x + s * pcg32_uniform(&rng), p.y + s * pcg32_uniform(&rng), p.z + s * pcg32_uniform(&rng));
        double smin, smax, dmin, dmax;
        rd_medium_box_bound(&ms, p, q, &smin, &smax);
        rd_medium_box_bound(&md, p, q, &dmin, &dmax);
        cr_assert(smin == dmin && smax == dmax, "box bound: sparse [%g, %g], dense [%g, %g]", smin, smax, dmin, dmax);
    }
    cr_expect(rd_grid_bytes(&sp) < rd_grid_bytes(&de));
    rd_grid_free(&sp);
    rd_grid_free(&de);
    cr_expect(sp.bricks == NULL && de.data == NULL);
}

Test(volume, sparse_vdb_matches_dense, .timeout = 60)
{
    check_sparse_matches_dense(0.0f);
}

Test(volume, sparse_vdb_matches_dense_with_a_background, .timeout = 60)
{
    /* Inactive voxels inside the active box read the background (0.125), as a dense read does. */
    check_sparse_matches_dense(0.125f);
}

Test(volume, vdb_grid_errors_are_one_line, .timeout = 60)
{
    char path[256], garbage[256], err[RD_ERRLEN];
    float one = 1.0f;
    const int origin[3] = {0, 0, 0};
    snprintf(path, sizeof path, "%s/typed.vdb", rt_tmpdir());
    rd_grid g;
    vec3 lo, hi;
    static const char *const types[] = {"double", "vec3s"};
    for (int t = 0; t < 2; t++) {
        cr_assert(rd_vdb_save_test(path, "density", types[t], 0.0f, &one, 1, 1, 1, origin, NULL, NULL, 0, err,
                                   sizeof err) == RD_OK, "%s", err);
        memset(&g, 0, sizeof g);
        cr_expect(rd_vdb_load(path, "density", &g, &lo, &hi, err, sizeof err) == RD_ERR_FORMAT);
        char want[128];
        snprintf(want, sizeof want, "grid \"density\" is of type %s, expected float", types[t]);
        cr_expect(strstr(err, want) && strncmp(err, path, strlen(path)) == 0 && !strchr(err, '\n'), "%s", err);
        cr_expect(g.data == NULL && g.bricks == NULL);
    }
    /* A missing grid name lists the grids there are. */
    cr_assert(rd_vdb_save_test(path, "smoke", "float", 0.0f, &one, 1, 1, 1, origin, NULL, NULL, 0, err,
                               sizeof err) == RD_OK, "%s", err);
    cr_expect(rd_vdb_load(path, "density", &g, &lo, &hi, err, sizeof err) == RD_ERR_FORMAT);
    cr_expect(strstr(err, "no grid named \"density\" (grids: smoke)") && !strchr(err, '\n'), "%s", err);
    /* A damaged file: the header of a good one followed by garbage. */
    FILE *f = fopen(path, "rb");
    char buf[4096];
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    for (size_t q = 64; q < n; q++) buf[q] = (char)(q * 131 + 7);
    snprintf(garbage, sizeof garbage, "%s/damaged.vdb", rt_tmpdir());
    rt_write_file(garbage, buf, n);
    memset(&g, 0, sizeof g);
    rd_status st = rd_vdb_load(garbage, "smoke", &g, &lo, &hi, err, sizeof err);
    cr_expect(st == RD_ERR_FORMAT, "status %d: %s", st, err);
    cr_expect(strncmp(err, garbage, strlen(garbage)) == 0 && !strchr(err, '\n'), "%s", err);
    cr_expect(g.data == NULL && g.bricks == NULL);
}

/* A sparse VDB (random 10^3 values, plus two clumps at opposite corners of a 133^3 box, so the
 * brick form is far smaller than the box) written as NAME.vdb in the test folder, and a scene
 * over it with the extra JSON `extra` (members after the medium). */
static rd_scene *sparse_scene(const char *name, uint64_t seed, const char *medium_extra, const char *extra)
{
    enum { N = 10 };
    float v[N * N * N];
    pcg32 rng = pcg32_seed(seed, 4, 0);
    for (int q = 0; q < N * N * N; q++) v[q] = (float)(3.0 * pcg32_uniform(&rng));
    const int origin[3] = {-3, -3, -3}, boxes[2][6] = {{120, 120, 120, 129, 129, 129}, {112, 0, 0, 127, 15, 15}};
    const float values[2] = {2.0f, 0.5f};
    char path[256], err[RD_ERRLEN], json[1024], file[300];
    snprintf(path, sizeof path, "%s/%s.vdb", rt_tmpdir(), name);
    cr_assert(rd_vdb_save_test(path, "density", "float", 0.0f, v, N, N, N, origin, boxes, values, 2, err,
                               sizeof err) == RD_OK, "%s", err);
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[60,60,400],\"look_at\":[60,60,60],\"resolution\":[4,4]},"
             "\"media\":[{\"density\":{\"type\":\"vdb\",\"file\":\"%s.vdb\"},\"sigma_t\":0.01%s}]%s}",
             name, medium_extra, extra);
    snprintf(file, sizeof file, "%s.json", name);
    return rt_scene(file, json);
}

Test(volume, vdb_scene_medium_is_sparse, .timeout = 60)
{
    /* A scene's VDB medium is held as bricks, and its majorant grid bounds the density: the
     * maximum over many random points of each super-voxel never exceeds its bound. */
    rd_scene *s = sparse_scene("sparse", 12, ",\"majorant\":{\"type\":\"grid\",\"resolution\":8}", "");
    pcg32 rng = pcg32_seed(99, 4, 0);
    const rd_medium *m = &s->media[0];
    cr_assert(m->grid.bricks != NULL && m->grid.data == NULL);
    const rd_majorant *mj = m->majorant;
    cr_assert(mj && mj->kind == RD_MAJ_GRID);
    cr_expect(rd_grid_bytes(&m->grid) * 20 < (size_t)133 * 133 * 133 * sizeof(float), "%zu bytes", rd_grid_bytes(&m->grid));
    for (int n = 0; n < 100000; n++) {
        vec3 u = v3(pcg32_uniform(&rng), pcg32_uniform(&rng), pcg32_uniform(&rng));
        vec3 x = v3(m->bmin.x + u.x * (m->bmax.x - m->bmin.x), m->bmin.y + u.y * (m->bmax.y - m->bmin.y),
                    m->bmin.z + u.z * (m->bmax.z - m->bmin.z));
        int c[3];
        for (int a = 0; a < 3; a++) {
            c[a] = (int)(v3_get(u, a) * mj->n[a]);
            if (c[a] >= mj->n[a]) c[a] = mj->n[a] - 1;
        }
        size_t cell = ((size_t)c[2] * mj->n[1] + c[1]) * mj->n[0] + c[0];
        cr_assert(rd_medium_density(m, x) <= mj->dmax[cell], "density above the cell's majorant");
    }
    rd_scene_free(s);
}

Test(volume, exact_transmittance_through_a_sparse_vdb, .timeout = 60)
{
    /* settings.transmittance exact on a VDB medium held as bricks (it read the dense array and
     * crashed): the closed-form optical depth along rays through both clumps equals a fine
     * midpoint quadrature of the trilinear density (20000 steps: error far below 1e-6 here). */
    rd_scene *s = sparse_scene("sparse_exact", 13, "", ",\"settings\":{\"transmittance\":\"exact\"}");
    pcg32 rng = pcg32_seed(98, 4, 0);
    const rd_medium *m = &s->media[0];
    cr_assert(m->grid.bricks != NULL && m->grid.data == NULL, "the medium must be held sparse");
    const vec3 from[3] = {v3(-10, 119.5, 124.3), v3(119.7, -10, 7.2), v3(-10, -10, -10)};
    const vec3 to[3] = {v3(140, 124.2, 126.1), v3(121.3, 140, 9.9), v3(140, 140, 140)};
    for (int q = 0; q < 3; q++) {
        vec3 d = v3_sub(to[q], from[q]);
        double len = v3_len(d);
        ray3 r = {from[q], v3_scale(d, 1.0 / len)};
        double tau = 0.0, h = len / 20000;
        for (int i = 0; i < 20000; i++) tau += rd_medium_sigma_t(m, ray_at(r, (i + 0.5) * h)) * h;
        rd_track_counters c = {0};
        double T = rd_transmittance(s, -1, r, 0.0, len, &rng, &c);
        cr_assert(tau > 0.01, "ray %d must cross medium (tau %g)", q, tau);
        cr_expect(fabs(T - exp(-tau)) < 1e-6 + 1e-5 * exp(-tau), "ray %d: exact T %.9g, quadrature %.9g", q, T, exp(-tau));
    }
    rd_scene_free(s);
}
