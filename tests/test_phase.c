/* Henyey-Greenstein phase function: normalisation, mean cosine, and a chi-square test of the
 * sampling routine (THEORY.md §1). */
#include "support/rd_test.h"

static const double G[] = {-0.7, -0.2, 0.0, 0.3, 0.7, 0.95};

/* Gauss-Legendre-free check: composite Simpson over mu in [-1, 1] with many intervals is exact
 * to ~1e-9 for these smooth integrands (the peak at g = 0.95 has width ~ (1-g) = 0.05). */
static double simpson(double g, int moment)
{
    int n = 200000;
    double h = 2.0 / n, s = 0;
    for (int i = 0; i <= n; i++) {
        double mu = -1.0 + i * h;
        double f = 2.0 * M_PI * rd_hg_eval(g, mu) * (moment ? mu : 1.0);
        s += f * (i == 0 || i == n ? 1 : (i % 2 ? 4 : 2));
    }
    return s * h / 3.0;
}

Test(phase, hg_normalised_and_mean_cosine_is_g)
{
    for (size_t i = 0; i < sizeof G / sizeof G[0]; i++) {
        cr_expect(fabs(simpson(G[i], 0) - 1.0) < 1e-6, "g=%g: integral %.9f", G[i], simpson(G[i], 0));
        cr_expect(fabs(simpson(G[i], 1) - G[i]) < 1e-6, "g=%g: mean cosine %.9f", G[i], simpson(G[i], 1));
    }
}

Test(phase, hg_sampled_mean_cosine_is_g)
{
    /* Monte Carlo mean of sampled cos: tolerance 5 standard errors of the sample mean. */
    for (size_t i = 0; i < sizeof G / sizeof G[0]; i++) {
        pcg32 rng = pcg32_seed(11, i, 2024);
        int n = 400000;
        double s = 0, s2 = 0;
        for (int k = 0; k < n; k++) {
            double c = rd_hg_sample_cos(G[i], pcg32_uniform(&rng));
            s += c;
            s2 += c * c;
        }
        double mean = s / n, se = sqrt((s2 / n - mean * mean) / n);
        cr_expect(fabs(mean - G[i]) < 5 * se, "g=%g: sampled mean cos %.5f, se %.5f", G[i], mean, se);
    }
}

/* P(cos <= mu) for HG, the analytic CDF in the cosine. */
static double hg_cdf(double g, double mu)
{
    if (fabs(g) < 1e-3) return 0.5 * (mu + 1.0);
    return (1.0 - g * g) / (2.0 * g) * (1.0 / sqrt(1.0 + g * g - 2.0 * g * mu) - 1.0 / (1.0 + g));
}

Test(phase, hg_sampling_chi_square)
{
    /* Directions sampled around random propagation directions, binned in (cos theta, phi) in
     * the frame of that direction; expected counts from the analytic CDF (uniform in phi).
     * Cells with expected count < 5 are pooled (pbrt-v4 bsdfs_test). Reject at p = 1e-4. */
    enum { NC = 40, NP = 16 };
    for (size_t gi = 0; gi < sizeof G / sizeof G[0]; gi++) {
        double g = G[gi];
        static double obs[NC][NP];
        memset(obs, 0, sizeof obs);
        int n = 300000;
        pcg32 rng = pcg32_seed(5, gi, 99);
        for (int k = 0; k < n; k++) {
            vec3 wi = rd_sample_sphere(pcg32_uniform(&rng), pcg32_uniform(&rng));
            vec3 wo = rd_hg_sample(g, wi, pcg32_uniform(&rng), pcg32_uniform(&rng));
            vec3 a, b;
            v3_basis(wi, &a, &b);
            double c = fmin(1.0, fmax(-1.0, v3_dot(wi, wo)));
            double phi = atan2(v3_dot(wo, b), v3_dot(wo, a));
            if (phi < 0) phi += 2 * M_PI;
            int ci = (int)((c + 1.0) * 0.5 * NC), pi = (int)(phi / (2 * M_PI) * NP);
            ci = ci >= NC ? NC - 1 : ci;
            pi = pi >= NP ? NP - 1 : pi;
            obs[ci][pi] += 1;
        }
        double chi2 = 0, pool_o = 0, pool_e = 0;
        int dof = -1;
        for (int ci = 0; ci < NC; ci++) {
            double lo = -1.0 + 2.0 * ci / NC, hi = -1.0 + 2.0 * (ci + 1) / NC;
            double e = n * (hg_cdf(g, hi) - hg_cdf(g, lo)) / NP;
            for (int pi = 0; pi < NP; pi++) {
                if (e < 5) { pool_o += obs[ci][pi]; pool_e += e; continue; }
                chi2 += (obs[ci][pi] - e) * (obs[ci][pi] - e) / e;
                dof++;
            }
        }
        if (pool_e >= 5) { chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e; dof++; }
        double crit = rt_chi2_quantile(dof, 3.719);
        cr_expect(chi2 < crit, "g=%g: chi2 %.1f >= %.1f (dof %d)", g, chi2, crit, dof);
    }
}

Test(phase, hg_sampler_rejects_a_wrong_distribution)
{
    /* The chi-square test must have teeth: samples of g = 0.5 judged against g = 0.45 fail. */
    enum { NC = 40 };
    double obs[NC] = {0};
    int n = 300000;
    pcg32 rng = pcg32_seed(1, 2, 3);
    for (int k = 0; k < n; k++) {
        double c = rd_hg_sample_cos(0.5, pcg32_uniform(&rng));
        int ci = (int)((c + 1.0) * 0.5 * NC);
        obs[ci >= NC ? NC - 1 : ci] += 1;
    }
    double chi2 = 0;
    for (int ci = 0; ci < NC; ci++) {
        double e = n * (hg_cdf(0.45, -1.0 + 2.0 * (ci + 1) / NC) - hg_cdf(0.45, -1.0 + 2.0 * ci / NC));
        chi2 += (obs[ci] - e) * (obs[ci] - e) / e;
    }
    cr_expect(chi2 > rt_chi2_quantile(NC - 1, 3.719), "chi2 %.1f did not detect g 0.5 vs 0.45", chi2);
}

Test(phase, uniform_sphere_sampling_chi_square)
{
    /* rd_sample_sphere: uniform in (z, phi), so every cell of a 20 x 16 grid in (z, phi) expects
     * n / 320 samples. Reject at p = 1e-4. */
    enum { NZ = 20, NPHI = 16 };
    static double obs[NZ][NPHI];
    int n = 320000;
    pcg32 rng = pcg32_seed(2, 4, 6);
    for (int k = 0; k < n; k++) {
        vec3 w = rd_sample_sphere(pcg32_uniform(&rng), pcg32_uniform(&rng));
        double phi = atan2(w.y, w.x);
        if (phi < 0) phi += 2 * M_PI;
        int zi = (int)((w.z + 1.0) * 0.5 * NZ), pi = (int)(phi / (2 * M_PI) * NPHI);
        obs[zi >= NZ ? NZ - 1 : zi][pi >= NPHI ? NPHI - 1 : pi] += 1;
    }
    double e = (double)n / (NZ * NPHI), chi2 = 0;
    for (int i = 0; i < NZ; i++)
        for (int j = 0; j < NPHI; j++) chi2 += (obs[i][j] - e) * (obs[i][j] - e) / e;
    double crit = rt_chi2_quantile(NZ * NPHI - 1, 3.719);
    cr_expect(chi2 < crit, "chi2 %.1f >= %.1f", chi2, crit);
}

Test(phase, sphere_light_cone_sampling_chi_square)
{
    /* rd_light_sample_li on a sphere light: directions uniform in the cone the sphere subtends,
     * pdf 1 / (2 pi (1 - cos_max)). Bin cos(angle to the axis) in [cos_max, 1] and phi around
     * the axis; each cell expects the same count. Also: every sampled direction hits the
     * sphere, and rd_light_pdf agrees with the sampler's pdf. Reject at p = 1e-4. */
    rd_light l = {.kind = RD_LIGHT_SPHERE, .pos = v3(0.3, -0.2, 2.0), .radius = 0.7, .value = v3(1, 1, 1)};
    vec3 x = v3(0.1, 0.4, -0.5);
    vec3 axis = v3_norm(v3_sub(l.pos, x)), a, b;
    v3_basis(axis, &a, &b);
    double d = v3_len(v3_sub(l.pos, x)), cos_max = sqrt(1.0 - l.radius * l.radius / (d * d));
    enum { NC = 20, NPHI = 12 };
    static double obs[NC][NPHI];
    int n = 240000, missed = 0;
    pcg32 rng = pcg32_seed(7, 7, 7);
    for (int k = 0; k < n; k++) {
        rd_light_sample ls;
        cr_assert(rd_light_sample_li(&l, x, pcg32_uniform(&rng), pcg32_uniform(&rng), &ls));
        if (k < 1000) {
            cr_expect(fabs(ls.pdf - 1.0 / (2 * M_PI * (1 - cos_max))) < 1e-9 * ls.pdf);
            cr_expect(fabs(rd_light_pdf(&l, x, ls.wi) - ls.pdf) < 1e-9 * ls.pdf);
        }
        if (!isfinite(rd_light_hit(&l, (ray3){x, ls.wi}))) missed++;
        double c = v3_dot(ls.wi, axis);
        double phi = atan2(v3_dot(ls.wi, b), v3_dot(ls.wi, a));
        if (phi < 0) phi += 2 * M_PI;
        int ci = (int)((c - cos_max) / (1.0 - cos_max) * NC), pi = (int)(phi / (2 * M_PI) * NPHI);
        ci = ci < 0 ? 0 : (ci >= NC ? NC - 1 : ci);
        obs[ci][pi >= NPHI ? NPHI - 1 : pi] += 1;
    }
    /* grazing directions may miss by round-off; they must be very rare */
    cr_expect(missed < n / 10000, "%d sampled directions miss the sphere", missed);
    double e = (double)n / (NC * NPHI), chi2 = 0;
    for (int i = 0; i < NC; i++)
        for (int j = 0; j < NPHI; j++) chi2 += (obs[i][j] - e) * (obs[i][j] - e) / e;
    double crit = rt_chi2_quantile(NC * NPHI - 1, 3.719);
    cr_expect(chi2 < crit, "chi2 %.1f >= %.1f", chi2, crit);
}

/* ---- Guided directions (transport/directions.c): the von Mises-Fisher lobe and the mixture --- */

/* P(mu.w <= c) for the vMF: (e^{kappa (c - 1)} - e^{-2 kappa}) / (1 - e^{-2 kappa}). */
static double vmf_cdf(double kappa, double c)
{
    return (exp(kappa * (c - 1.0)) - exp(-2.0 * kappa)) / -expm1(-2.0 * kappa);
}

Test(phase, vmf_sampling_chi_square)
{
    /* rd_vmf_sample binned in (cos to the mean, phi about it), expected counts from the CDF
     * above (uniform in phi); kappa from nearly uniform to sharp. Pooling as the HG test;
     * reject at p = 1e-4. Also: rd_vmf_eval integrates to 1 (Simpson in cos, 1e-6). */
    const double K[] = {1e-7, 0.3, 3.0, 40.0, 2000.0};
    enum { NC = 40, NP = 12 };
    for (size_t ki = 0; ki < sizeof K / sizeof K[0]; ki++) {
        double kappa = K[ki];
        vec3 mu = v3_norm(v3(0.3, -0.5, 0.8));
        int m = 200000;
        double h = 2.0 / m, integral = 0.0;
        for (int i = 0; i <= m; i++) { /* the pdf depends on mu.w only: 2 pi int p dcos */
            double c = -1.0 + i * h;
            double p = kappa < 1e-6 ? 1.0 / (4 * M_PI) : kappa / (2 * M_PI * -expm1(-2 * kappa)) * exp(kappa * (c - 1));
            integral += 2 * M_PI * p * (i == 0 || i == m ? 1 : (i % 2 ? 4 : 2));
        }
        integral *= h / 3.0;
        cr_expect(fabs(integral - 1.0) < 1e-6, "kappa %g: integral %.9f", kappa, integral);
        static double obs[NC][NP];
        memset(obs, 0, sizeof obs);
        int n = 300000;
        pcg32 rng = pcg32_seed(11, ki, 5);
        vec3 a, b;
        v3_basis(mu, &a, &b);
        for (int k = 0; k < n; k++) {
            vec3 w = rd_vmf_sample(mu, kappa, pcg32_uniform(&rng), pcg32_uniform(&rng));
            if (k < 1000) {
                double c = v3_dot(mu, w);
                double p = kappa < 1e-6 ? 1.0 / (4 * M_PI) : kappa / (2 * M_PI * -expm1(-2 * kappa)) * exp(kappa * (c - 1));
                cr_expect(fabs(rd_vmf_eval(mu, kappa, w) - p) <= 1e-9 * p, "kappa %g: eval", kappa);
                cr_expect(fabs(v3_len(w) - 1.0) < 1e-12);
            }
            double c = fmin(1.0, fmax(-1.0, v3_dot(mu, w)));
            double phi = atan2(v3_dot(w, b), v3_dot(w, a));
            if (phi < 0) phi += 2 * M_PI;
            int ci = (int)((c + 1.0) * 0.5 * NC), pi = (int)(phi / (2 * M_PI) * NP);
            obs[ci >= NC ? NC - 1 : ci][pi >= NP ? NP - 1 : pi] += 1;
        }
        double chi2 = 0, pool_o = 0, pool_e = 0;
        int dof = -1;
        for (int ci = 0; ci < NC; ci++) {
            double lo = -1.0 + 2.0 * ci / NC, hi = -1.0 + 2.0 * (ci + 1) / NC;
            double e = kappa < 1e-6 ? (double)n / (NC * NP) : n * (vmf_cdf(kappa, hi) - vmf_cdf(kappa, lo)) / NP;
            for (int pi = 0; pi < NP; pi++) {
                if (e < 5) { pool_o += obs[ci][pi]; pool_e += e; continue; }
                chi2 += (obs[ci][pi] - e) * (obs[ci][pi] - e) / e;
                dof++;
            }
        }
        if (pool_e >= 5) { chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e; dof++; }
        if (dof < 1) { /* everything in the last band: the lobe is that sharp */
            cr_expect(kappa > 100, "kappa %g: no degrees of freedom", kappa);
            continue;
        }
        double crit = rt_chi2_quantile(dof, 3.719);
        cr_expect(chi2 < crit, "kappa %g: chi2 %.1f >= %.1f (dof %d)", kappa, chi2, crit, dof);
    }
}

/* The continuation's mixture (rd_dir_mix_sample) against its own pdf (rd_dir_mix_pdf): bins
 * in (z, phi) of the world frame, expected counts by integrating the pdf over each bin (a
 * 12 x 12 midpoint rule inside every bin: the pdf is smooth at these kappa and g, and the rule
 * errs by far less than the test's resolution, sqrt(e) per bin). Cells expecting < 5 are pooled;
 * reject at p = 1e-4. A mixture whose pdf forgot the phase's share fails (the teeth check). */
static double mix_chi2(const rd_dir_mix *mx, const rd_dir_mix *judge, double g, vec3 d, uint64_t seed, int *dof_out)
{
    enum { NZ = 24, NP = 24, SUB = 12 };
    static double obs[NZ][NP];
    memset(obs, 0, sizeof obs);
    int n = 400000;
    pcg32 rng = pcg32_seed(seed, 1, 2);
    for (int k = 0; k < n; k++) {
        double pdf;
        vec3 w = rd_dir_mix_sample(mx, g, d, &rng, &pdf);
        if (k < 1000) cr_expect(fabs(pdf - rd_dir_mix_pdf(mx, g, d, w)) <= 1e-12 * pdf);
        double phi = atan2(w.y, w.x);
        if (phi < 0) phi += 2 * M_PI;
        int zi = (int)((w.z + 1.0) * 0.5 * NZ), pi = (int)(phi / (2 * M_PI) * NP);
        obs[zi >= NZ ? NZ - 1 : zi][pi >= NP ? NP - 1 : pi] += 1;
    }
    double chi2 = 0, pool_o = 0, pool_e = 0;
    int dof = -1;
    for (int zi = 0; zi < NZ; zi++)
        for (int pi = 0; pi < NP; pi++) {
            double e = 0.0, dz = 2.0 / NZ / SUB, dp = 2 * M_PI / NP / SUB;
            for (int a = 0; a < SUB; a++)
                for (int b = 0; b < SUB; b++) {
                    double z = -1.0 + zi * 2.0 / NZ + (a + 0.5) * dz, phi = pi * 2 * M_PI / NP + (b + 0.5) * dp;
                    double r = sqrt(fmax(0.0, 1 - z * z));
                    e += rd_dir_mix_pdf(judge, g, d, v3(r * cos(phi), r * sin(phi), z)) * dz * dp;
                }
            e *= n;
            if (e < 5) { pool_o += obs[zi][pi]; pool_e += e; continue; }
            chi2 += (obs[zi][pi] - e) * (obs[zi][pi] - e) / e;
            dof++;
        }
    if (pool_e >= 5) { chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e; dof++; }
    *dof_out = dof;
    return chi2;
}

Test(phase, direction_mixture_chi_square)
{
    const struct { double a, kappa, g; } c[] = {{0.5, 4.0, 0.7}, {0.3, 20.0, -0.4}, {0.8, 1.0, 0.0}, {0.0, 5.0, 0.5}};
    vec3 d = v3_norm(v3(0.2, 0.9, -0.3)), mu = v3_norm(v3(-0.6, 0.1, 0.7));
    for (size_t i = 0; i < sizeof c / sizeof c[0]; i++) {
        rd_dir_mix mx = {.a = c[i].a, .mu = mu, .kappa = c[i].kappa};
        int dof;
        double chi2 = mix_chi2(&mx, &mx, c[i].g, d, 40 + i, &dof);
        double crit = rt_chi2_quantile(dof, 3.719);
        cr_expect(dof > 50 && chi2 < crit, "case %zu: chi2 %.1f >= %.1f (dof %d)", i, chi2, crit, dof);
    }
    /* Teeth: samples of a = 0.5 judged as a = 0.4 must fail. */
    rd_dir_mix mx = {.a = 0.5, .mu = mu, .kappa = 4.0}, wrong = {.a = 0.4, .mu = mu, .kappa = 4.0};
    int dof;
    double chi2 = mix_chi2(&mx, &wrong, 0.7, d, 99, &dof);
    cr_expect(chi2 > rt_chi2_quantile(dof, 3.719), "a 0.5 judged as 0.4 passed: chi2 %.1f (dof %d)", chi2, dof);
}
