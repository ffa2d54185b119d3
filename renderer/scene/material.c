/* material.c: surface scattering (rd_geom.h): the index-matched interface, the smooth Fresnel
 * dielectric and the Lambertian diffuse reflector, sampled in the path's direction of travel. */
#include "scene/rd_geom.h"

/* Unpolarised Fresnel reflectance of a dielectric boundary (Born & Wolf §1.5.3, eqs. 20-21
 * squared and averaged; pbrt-v4 FrDielectric), eta = n_t / n_i. */
double rd_fresnel_dielectric(double cos_i, double eta)
{
    cos_i = fmin(1.0, fmax(0.0, cos_i));
    double sin2_i = fmax(0.0, 1.0 - cos_i * cos_i);
    double sin2_t = sin2_i / (eta * eta); /* Snell: n_i sin_i = n_t sin_t */
    if (sin2_t >= 1.0) return 1.0;         /* total internal reflection */
    double cos_t = sqrt(1.0 - sin2_t);
    double r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    double r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5 * (r_par * r_par + r_perp * r_perp);
}

vec3 rd_reflect(vec3 d, vec3 n) { return v3_madd(d, n, -2.0 * v3_dot(d, n)); }

/* Snell's law in vector form (pbrt-v4 Refract, written for the travel direction):
 * with n turned against d (cos_i = -d.n > 0), t = d / eta + (cos_i / eta - cos_t) n. */
int rd_refract(vec3 d, vec3 n, double eta, vec3 *t)
{
    double cos_i = -v3_dot(d, n);
    if (cos_i < 0.0) {
        n = v3_scale(n, -1.0);
        cos_i = -cos_i;
    }
    double sin2_t = fmax(0.0, 1.0 - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0) return 0;
    double cos_t = sqrt(1.0 - sin2_t);
    *t = v3_norm(v3_madd(v3_scale(d, 1.0 / eta), n, cos_i / eta - cos_t));
    return 1;
}

int rd_material_sample(const rd_material *m, vec3 d, vec3 ng, vec3 ns, rd_transport mode,
                       double u_event, double u1, double u2, rd_surface_sample *s)
{
    double dn = v3_dot(d, ng);
    if (dn == 0.0) return 0; /* grazing: the path does not meet the surface's sides */
    int from_front = dn < 0.0;
    switch (m->kind) {
    case RD_MAT_INTERFACE:
        /* No scattering: the path goes on unchanged into the other side's medium. */
        s->d = d;
        s->weight = v3(1, 1, 1);
        s->pdf = 1.0;
        s->specular = 1;
        s->crossed = 1;
        return 1;
    case RD_MAT_DIELECTRIC: {
        /* Choose reflection with probability F and refraction with 1 - F, so that the
         * estimator's weight is f cos / p = F / F = 1 (reflection) and (1 - F) / (1 - F) times
         * the radiance factor (refraction) (pbrt-v4 DielectricBxDF::Sample_f). */
        double eta = from_front ? m->ior : 1.0 / m->ior; /* n_t / n_i */
        vec3 n = v3_dot(ns, ng) < 0.0 ? v3_scale(ns, -1.0) : ns; /* shading normal on ng's side */
        double cos_i = fabs(v3_dot(d, n));
        double F = rd_fresnel_dielectric(cos_i, eta);
        if (u_event < F) {
            s->d = v3_norm(rd_reflect(d, n));
            s->weight = v3(1, 1, 1);
            s->pdf = F;
            s->crossed = 0;
            /* It must leave on the side it came from. */
            if ((v3_dot(s->d, ng) < 0.0) != !from_front || v3_dot(s->d, ng) == 0.0) return 0;
        } else {
            vec3 t;
            if (!rd_refract(d, n, eta, &t)) return 0; /* F = 1 under TIR: unreachable */
            s->d = t;
            /* Radiance: (n_i / n_t)^2 = 1 / eta^2 (Veach eq. 5.13); importance (flux): 1. */
            double k = mode == RD_TRANSPORT_RADIANCE ? 1.0 / (eta * eta) : 1.0;
            s->weight = v3(k, k, k);
            s->pdf = 1.0 - F;
            s->crossed = 1;
            if ((v3_dot(s->d, ng) < 0.0) != from_front || v3_dot(s->d, ng) == 0.0) return 0;
        }
        s->specular = 1;
        return 1;
    }
    case RD_MAT_DIFFUSE: {
        /* Cosine-weighted hemisphere (Malley's method: a uniform disk point lifted to the
         * hemisphere; pbrt-v4 SampleCosineHemisphere), around the normal on the side the path
         * came from: pdf = cos / pi, f = albedo / pi, weight = albedo. */
        vec3 n = from_front ? ng : v3_scale(ng, -1.0);
        double r = sqrt(u1), phi = 2.0 * M_PI * u2;
        double x = r * cos(phi), y = r * sin(phi), z = sqrt(fmax(0.0, 1.0 - u1));
        if (!(z > 0.0)) return 0;
        vec3 a, b;
        v3_basis(n, &a, &b);
        s->d = v3_norm(v3_add(v3_scale(n, z), v3_add(v3_scale(a, x), v3_scale(b, y))));
        s->weight = m->albedo;
        s->pdf = z / M_PI;
        s->specular = 0;
        s->crossed = 0;
        (void)u_event;
        return 1;
    }
    }
    return 0;
}

vec3 rd_material_eval(const rd_material *m, vec3 d_in, vec3 d_out, vec3 ng, double *pdf)
{
    if (pdf) *pdf = 0.0;
    if (m->kind != RD_MAT_DIFFUSE) return v3(0, 0, 0);
    double a = v3_dot(d_in, ng), b = v3_dot(d_out, ng);
    /* Reflection only: d_out leaves on the side d_in arrived from (their dots with ng differ
     * in sign). */
    if (!(a * b < 0.0)) return v3(0, 0, 0);
    if (pdf) *pdf = fabs(b) / M_PI;
    return v3_scale(m->albedo, 1.0 / M_PI);
}
