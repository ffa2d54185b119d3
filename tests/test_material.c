/* test_material.c: the surface materials of rd_geom.h: Fresnel reflectance against the
 * Fresnel equations written independently (angles, amplitude transmission), Snell's law and
 * total internal reflection exactly, the dielectric's event frequencies (binomial, 5 sigma),
 * the diffuse sampler (chi-square against its pdf), the sampled weights in both transport
 * modes, and a plane-parallel glass slab followed through the sampler (the analytic check the
 * transport step will use: (1 - R) / (1 + R) at normal incidence). */
#include "support/rd_test.h"
#include "scene/rd_geom.h"

static vec3 unit(double x, double y, double z) { return v3_norm(v3(x, y, z)); }

/* A travel direction arriving at the surface with normal n at angle theta from -n. */
static vec3 incoming(vec3 n, double theta)
{
    vec3 a, b;
    v3_basis(n, &a, &b);
    return v3_norm(v3_add(v3_scale(n, -cos(theta)), v3_scale(a, sin(theta))));
}

Test(material, fresnel_normal_incidence)
{
    const double etas[] = {1.0, 1.2, 1.33, 1.5, 2.0, 2.42, 4.0};
    for (int i = 0; i < 7; i++) {
        double n = etas[i], R = ((n - 1) / (n + 1)) * ((n - 1) / (n + 1));
        cr_expect(fabs(rd_fresnel_dielectric(1.0, n) - R) < 1e-15, "n %g: %.17g vs %.17g", n, rd_fresnel_dielectric(1.0, n), R);
        cr_expect(fabs(rd_fresnel_dielectric(1.0, 1.0 / n) - R) < 1e-15, "from inside, n %g", n);
    }
}

/* The Fresnel equations in their angle form (Born & Wolf §1.5.2 eqs. 35-36; Hecht §4.6):
 * r_s = -sin(ti - tt) / sin(ti + tt), r_p = tan(ti - tt) / tan(ti + tt); the transmitted
 * power fraction from the amplitude coefficients t_s = 2 sin tt cos ti / sin(ti + tt),
 * t_p = t_s / cos(ti - tt), T = (n_t cos tt) / (n_i cos ti) t^2. */
Test(material, fresnel_matches_the_angle_form_and_conserves_energy)
{
    const double etas[] = {1.33, 1.5, 2.0, 1 / 1.5, 1 / 1.33};
    int checked = 0;
    for (int e = 0; e < 5; e++) {
        double eta = etas[e];
        for (int k = 1; k < 90; k++) {
            double ti = k * M_PI / 180.0, st = sin(ti) / eta;
            if (st >= 1.0) {
                cr_expect_eq(rd_fresnel_dielectric(cos(ti), eta), 1.0, "TIR at %d deg, eta %g", k, eta);
                continue;
            }
            double tt = asin(st);
            double rs = -sin(ti - tt) / sin(ti + tt), rp = tan(ti - tt) / tan(ti + tt);
            double R = 0.5 * (rs * rs + rp * rp);
            double ts = 2 * sin(tt) * cos(ti) / sin(ti + tt), tp = ts / cos(ti - tt);
            double T = eta * cos(tt) / cos(ti) * 0.5 * (ts * ts + tp * tp);
            double F = rd_fresnel_dielectric(cos(ti), eta);
            cr_expect(fabs(F - R) < 1e-12, "eta %g, %d deg: F %.15g, angle form %.15g", eta, k, F, R);
            cr_expect(fabs(R + T - 1.0) < 1e-12, "eta %g, %d deg: R + T = %.15g", eta, k, R + T);
            /* Reciprocity: the same reflectance seen from the other side at the refracted angle. */
            cr_expect(fabs(F - rd_fresnel_dielectric(cos(tt), 1.0 / eta)) < 1e-12, "eta %g, %d deg: not reciprocal", eta, k);
            checked++;
        }
    }
    cr_expect(checked > 300);
    /* Brewster's angle tan(theta_B) = eta: the p-wave is not reflected, F = r_s^2 / 2. */
    double eta = 1.5, tb = atan(eta), tt = asin(sin(tb) / eta), rs = sin(tb - tt) / sin(tb + tt);
    cr_expect(fabs(rd_fresnel_dielectric(cos(tb), eta) - 0.5 * rs * rs) < 1e-14);
}

Test(material, snell_and_total_internal_reflection_exactly)
{
    pcg32 rng = pcg32_seed(14, 10, 1);
    for (int i = 0; i < 10000; i++) {
        vec3 n = rd_sample_sphere(pcg32_uniform(&rng), pcg32_uniform(&rng));
        vec3 d = rd_sample_sphere(pcg32_uniform(&rng), pcg32_uniform(&rng));
        double eta = 0.5 + 2.0 * pcg32_uniform(&rng);
        double cos_i = fabs(v3_dot(d, n)), sin_i = sqrt(fmax(0, 1 - cos_i * cos_i));
        vec3 t;
        int ok = rd_refract(d, n, eta, &t);
        if (sin_i / eta >= 1.0) {
            cr_expect(!ok, "TIR not reported: sin_i %g eta %g", sin_i, eta);
            cr_expect_eq(rd_fresnel_dielectric(cos_i, eta), 1.0);
            continue;
        }
        cr_assert(ok, "refraction refused: sin_i %g eta %g", sin_i, eta);
        double cos_t = fabs(v3_dot(t, n)), sin_t = sqrt(fmax(0, 1 - cos_t * cos_t));
        cr_expect(fabs(v3_len(t) - 1) < 1e-14);
        cr_expect(fabs(sin_i - eta * sin_t) < 1e-9, "Snell: sin_i %.15g, eta sin_t %.15g", sin_i, eta * sin_t);
        cr_expect(v3_dot(t, n) * v3_dot(d, n) > 0, "the refracted ray must cross the surface");
        cr_expect(fabs(v3_dot(t, v3_cross(d, n))) < 1e-12, "not in the plane of incidence");
        /* The tangential parts point the same way. */
        vec3 dt = v3_madd(d, n, -v3_dot(d, n)), tt = v3_madd(t, n, -v3_dot(t, n));
        cr_expect(v3_dot(dt, tt) >= -1e-15);
        /* The reflection is the mirror image. */
        vec3 r = rd_reflect(d, n);
        cr_expect(fabs(v3_dot(r, n) + v3_dot(d, n)) < 1e-15 && v3_len(v3_sub(v3_madd(r, n, -v3_dot(r, n)), dt)) < 1e-14);
    }
    /* The critical angle of glass (1.5) from inside: sin = 1/1.5. */
    double tc = asin(1 / 1.5);
    vec3 n = v3(0, 0, 1), t;
    cr_expect(rd_refract(incoming(n, tc - 1e-6), n, 1 / 1.5, &t) == 1);
    cr_expect(rd_refract(incoming(n, tc + 1e-6), n, 1 / 1.5, &t) == 0);
    cr_expect(rd_fresnel_dielectric(cos(tc + 1e-6), 1 / 1.5) == 1.0);
    cr_expect(rd_fresnel_dielectric(cos(tc - 1e-3), 1 / 1.5) < 1.0);
}

/* The dielectric picks reflection with probability F: over N samples the count of reflections
 * is Binomial(N, F); the test allows 5 standard deviations sqrt(N F (1 - F)). */
Test(material, dielectric_event_frequencies_follow_fresnel)
{
    rd_material m = {RD_MAT_DIELECTRIC, 1.5, v3(0, 0, 0)};
    vec3 ng = unit(0.3, -0.2, 1.0);
    const double angles[] = {0, 30, 60, 80, 89};
    const int N = 200000;
    for (int side = 0; side < 2; side++)
        for (int a = 0; a < 5; a++) {
            vec3 nside = side ? v3_scale(ng, -1) : ng;
            vec3 d = incoming(nside, angles[a] * M_PI / 180.0);
            double eta = side ? 1 / 1.5 : 1.5;
            double F = rd_fresnel_dielectric(cos(angles[a] * M_PI / 180.0), eta);
            pcg32 rng = pcg32_seed(14, 20 + a, side);
            long refl = 0;
            for (int i = 0; i < N; i++) {
                rd_surface_sample s;
                cr_assert(rd_material_sample(&m, d, ng, ng, RD_TRANSPORT_RADIANCE, pcg32_uniform(&rng), 0.5, 0.5, &s));
                cr_assert(s.specular);
                if (!s.crossed) {
                    refl++;
                    cr_assert(fabs(s.pdf - F) < 1e-15 && s.weight.x == 1.0);
                } else {
                    cr_assert(fabs(s.pdf - (1 - F)) < 1e-15);
                    cr_assert(fabs(s.weight.x - 1.0 / (eta * eta)) < 1e-15, "radiance weight %g", s.weight.x);
                }
            }
            double sd = sqrt(N * F * (1 - F));
            if (F == 1.0) cr_expect_eq(refl, N, "TIR: every sample reflects");
            else cr_expect(fabs(refl - N * F) <= 5 * sd + 1e-9, "side %d, %g deg: %ld reflections, expected %.1f +- %.1f", side,
                           angles[a], refl, N * F, sd);
        }
}

Test(material, dielectric_weights_by_transport_mode)
{
    rd_material m = {RD_MAT_DIELECTRIC, 1.5, v3(0, 0, 0)};
    vec3 n = v3(0, 0, 1);
    rd_surface_sample s;
    /* u_event = 0.999 > F: refraction. Entering glass: radiance x (1/1.5)^2, importance x 1. */
    cr_assert(rd_material_sample(&m, incoming(n, 0.4), n, n, RD_TRANSPORT_RADIANCE, 0.999, 0, 0, &s) && s.crossed);
    cr_expect(fabs(s.weight.y - 1 / 2.25) < 1e-15);
    cr_assert(rd_material_sample(&m, incoming(n, 0.4), n, n, RD_TRANSPORT_IMPORTANCE, 0.999, 0, 0, &s) && s.crossed);
    cr_expect_eq(s.weight.y, 1.0);
    /* Leaving glass: radiance x 1.5^2. */
    cr_assert(rd_material_sample(&m, incoming(v3(0, 0, -1), 0.3), n, n, RD_TRANSPORT_RADIANCE, 0.999, 0, 0, &s) && s.crossed);
    cr_expect(fabs(s.weight.z - 2.25) < 1e-14);
    cr_expect(s.d.z > 0, "leaving through the front");
    /* An index of 1 is invisible: nothing reflects and the direction is unchanged. */
    rd_material one = {RD_MAT_DIELECTRIC, 1.0, v3(0, 0, 0)};
    pcg32 rng = pcg32_seed(14, 30, 0);
    for (int i = 0; i < 1000; i++) {
        vec3 d = incoming(n, 1.5 * pcg32_uniform(&rng));
        cr_assert(rd_material_sample(&one, d, n, n, RD_TRANSPORT_RADIANCE, pcg32_uniform(&rng), 0, 0, &s));
        cr_expect(s.crossed && s.weight.x == 1.0 && v3_len(v3_sub(s.d, d)) < 1e-14);
    }
    /* The interface passes everything straight on. */
    rd_material itf = {RD_MAT_INTERFACE, 1, v3(0, 0, 0)};
    vec3 d = unit(0.2, 0.1, -1);
    cr_assert(rd_material_sample(&itf, d, n, n, RD_TRANSPORT_RADIANCE, 0.3, 0.1, 0.2, &s));
    cr_expect(s.crossed && s.specular && s.weight.x == 1.0 && v3_len(v3_sub(s.d, d)) == 0.0);
    cr_expect(rd_material_eval(&itf, d, s.d, n, NULL).x == 0.0);
}

/* The diffuse sampler against its pdf cos/pi: cells of equal width in theta (0..pi/2) and phi
 * around the normal, each with the exact probability (sin^2 theta1 - sin^2 theta0) dphi /
 * (2 pi); Pearson's chi-square over the cells (cells expecting < 5 pooled), against the
 * 1e-4 upper quantile. */
Test(material, diffuse_sampler_chi_square)
{
    rd_material m = {RD_MAT_DIFFUSE, 1, v3(0.2, 0.5, 0.9)};
    enum { NT = 12, NP = 24 };
    const int N = 400000;
    vec3 ngs[2] = {unit(0.4, -0.7, 0.2), unit(-0.1, 0.05, -1)};
    for (int q = 0; q < 2; q++) {
        vec3 ng = ngs[q];
        for (int back = 0; back < 2; back++) {
            vec3 nside = back ? v3_scale(ng, -1) : ng; /* the side the path comes from */
            vec3 d = incoming(nside, 0.7);
            vec3 a, b;
            v3_basis(nside, &a, &b);
            static long count[NT][NP];
            memset(count, 0, sizeof count);
            pcg32 rng = pcg32_seed(14, 40 + q, back);
            for (int i = 0; i < N; i++) {
                rd_surface_sample s;
                cr_assert(rd_material_sample(&m, d, ng, ng, RD_TRANSPORT_RADIANCE, 0.5, pcg32_uniform(&rng), pcg32_uniform(&rng), &s));
                cr_assert(!s.specular && !s.crossed);
                double c = v3_dot(s.d, nside);
                cr_assert(c > 0, "the diffuse direction must leave on the side the path came from");
                cr_assert(fabs(s.pdf - c / M_PI) < 1e-12);
                cr_assert(v3_len(v3_sub(s.weight, m.albedo)) < 1e-15);
                double pdf;
                vec3 f = rd_material_eval(&m, d, s.d, ng, &pdf);
                cr_assert(fabs(pdf - s.pdf) < 1e-12 && fabs(f.y * c / pdf - m.albedo.y) < 1e-12);
                double th = acos(fmin(1.0, c)), ph = atan2(v3_dot(s.d, b), v3_dot(s.d, a)) + M_PI;
                int it = (int)(th / (M_PI / 2) * NT), ip = (int)(ph / (2 * M_PI) * NP);
                if (it >= NT) it = NT - 1;
                if (ip >= NP) ip = NP - 1;
                count[it][ip]++;
            }
            double chi2 = 0, pool_o = 0, pool_e = 0;
            int cells = 0;
            for (int it = 0; it < NT; it++)
                for (int ip = 0; ip < NP; ip++) {
                    double s0 = sin(it * (M_PI / 2) / NT), s1 = sin((it + 1) * (M_PI / 2) / NT);
                    double e = N * (s1 * s1 - s0 * s0) / NP;
                    if (e < 5) {
                        pool_o += count[it][ip], pool_e += e;
                        continue;
                    }
                    chi2 += (count[it][ip] - e) * (count[it][ip] - e) / e;
                    cells++;
                }
            if (pool_e > 0) {
                chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
                cells++;
            }
            double lim = rt_chi2_quantile(cells - 1, 3.719);
            cr_expect(chi2 < lim, "normal %d side %d: chi2 %.1f over %d cells, limit %.1f", q, back, chi2, cells, lim);
        }
    }
    /* Transmission direction: eval is 0 and its pdf too. */
    double pdf;
    vec3 n = v3(0, 0, 1);
    cr_expect(rd_material_eval(&m, incoming(n, 0.2), v3(0, 0, -1), n, &pdf).x == 0.0 && pdf == 0.0);
}

/* ---- the glass slab, followed through the Fresnel sampler ---------------------------------
 * A plane-parallel slab of relative index n between the planes z = 0 and z = L in vacuum (no
 * medium), entered at angle theta from the front (z < 0). The ray's fate depends only on the
 * sequence of events: at each face it reflects with probability F (the same F at both faces
 * and inside and outside, by the reciprocity tested above), so the fraction that leaves
 * through z = L is sum_k (1-F)^2 F^(2k) = (1 - F) / (1 + F), at normal incidence with
 * F = R = ((n-1)/(n+1))^2. This follows the sampler's directions, so TIR, Snell and the
 * side bookkeeping are exercised too (a wrong side would never exit). */
static double slab_transmission(double n, double theta, int paths, uint64_t seed, double *weight_mean)
{
    rd_material glass = {RD_MAT_DIELECTRIC, n, v3(0, 0, 0)};
    const double L = 1.0;
    long through = 0;
    double wsum = 0;
    for (int i = 0; i < paths; i++) {
        pcg32 rng = pcg32_seed(seed, (uint64_t)i, 7);
        vec3 p = v3(0, 0, -1), d = v3(sin(theta), 0, cos(theta));
        double w = 1.0;
        for (int bounce = 0; bounce < 10000; bounce++) {
            /* The next face along d: z = 0 or z = L; leaving the slab region ends the path. */
            double zf;
            vec3 ng;  /* the face's front (outside) normal */
            if (p.z < 0) { if (d.z <= 0) break; zf = 0; ng = v3(0, 0, -1); }
            else if (p.z > L) { if (d.z >= 0) break; zf = L; ng = v3(0, 0, 1); }
            else if (d.z > 0) { zf = L; ng = v3(0, 0, 1); }
            else { zf = 0; ng = v3(0, 0, -1); }
            double t = (zf - p.z) / d.z;
            p = v3_madd(p, d, t);
            rd_surface_sample s;
            if (!rd_material_sample(&glass, d, ng, ng, RD_TRANSPORT_IMPORTANCE, pcg32_uniform(&rng), 0, 0, &s)) break;
            w *= s.weight.x;
            d = s.d;
            p.z = zf + (d.z > 0 ? 1e-9 : -1e-9); /* just past the face, the way the path goes */
        }
        if (p.z > L) {
            through++;
            wsum += w;
        }
    }
    *weight_mean = through ? wsum / through : 0;
    return (double)through / paths;
}

Test(material, glass_slab_transmits_one_minus_r_over_one_plus_r, .timeout = 120)
{
    const int N = 200000;
    /* 1 / 1.5: a bubble (the slab's inside of lower index, scene-format.md "ior"); the same law. */
    const double ns[] = {1.5, 2.4, 1.0 / 1.5};
    for (int k = 0; k < 3; k++) {
        double n = ns[k], R = ((n - 1) / (n + 1)) * ((n - 1) / (n + 1));
        double expect = (1 - R) / (1 + R), wm;
        double got = slab_transmission(n, 0.0, N, 14 + k, &wm);
        double sd = sqrt(expect * (1 - expect) / N);
        cr_expect(fabs(got - expect) < 5 * sd, "n %g: transmitted %.5f, (1-R)/(1+R) = %.5f +- %.5f", n, got, expect, sd);
        cr_expect(fabs(wm - 1.0) < 1e-12, "importance weights must be 1, mean %g", wm);
        /* Oblique (40 deg): the same law with the unpolarised F of that angle. */
        double th = 40 * M_PI / 180, F = rd_fresnel_dielectric(cos(th), n);
        expect = (1 - F) / (1 + F);
        got = slab_transmission(n, th, N, 24 + k, &wm);
        sd = sqrt(expect * (1 - expect) / N);
        cr_expect(fabs(got - expect) < 5 * sd, "n %g at 40 deg: %.5f vs %.5f +- %.5f", n, got, expect, sd);
    }
}
