/* rd_math.h: small open value types of the renderer (vec3, ray, PCG32) and the
 * Henyey-Greenstein phase function. Internal to renderer/ (tests include it too).
 * Everything here is static inline: no state, no globals. */
#ifndef RD_MATH_H
#define RD_MATH_H

#include <math.h>
#include <stdint.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif
#define RD_INV_4PI (1.0 / (4.0 * M_PI))

typedef struct { double x, y, z; } vec3;

static inline vec3 v3(double x, double y, double z) { vec3 r = {x, y, z}; return r; }
static inline vec3 v3_add(vec3 a, vec3 b) { return v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline vec3 v3_sub(vec3 a, vec3 b) { return v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline vec3 v3_mul(vec3 a, vec3 b) { return v3(a.x * b.x, a.y * b.y, a.z * b.z); }
static inline vec3 v3_scale(vec3 a, double s) { return v3(a.x * s, a.y * s, a.z * s); }
static inline vec3 v3_madd(vec3 a, vec3 b, double s) { return v3(a.x + b.x * s, a.y + b.y * s, a.z + b.z * s); }
static inline double v3_dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline vec3 v3_cross(vec3 a, vec3 b)
{
    return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline double v3_len(vec3 a) { return sqrt(v3_dot(a, a)); }
static inline vec3 v3_norm(vec3 a) { double l = v3_len(a); return l > 0 ? v3_scale(a, 1.0 / l) : a; }
static inline double v3_get(vec3 a, int i) { return i == 0 ? a.x : (i == 1 ? a.y : a.z); }
static inline double v3_maxc(vec3 a) { return fmax(a.x, fmax(a.y, a.z)); }
static inline double v3_lum(vec3 a) { return 0.2126 * a.x + 0.7152 * a.y + 0.0722 * a.z; }
static inline int v3_finite(vec3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }

/* Orthonormal basis around a unit vector n (Duff et al. 2017, "Building an orthonormal basis,
 * revisited"). */
static inline void v3_basis(vec3 n, vec3 *s, vec3 *t)
{
    double sign = copysign(1.0, n.z);
    double a = -1.0 / (sign + n.z);
    double b = n.x * n.y * a;
    *s = v3(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    *t = v3(b, sign + n.y * n.y * a, -n.y);
}

typedef struct { vec3 o, d; } ray3; /* d unit */
static inline vec3 ray_at(ray3 r, double t) { return v3_madd(r.o, r.d, t); }

/* ---- PCG32 (O'Neill 2014), seeded by hashing (pixel, sample, seed) ------------------------ */
typedef struct { uint64_t state, inc; } pcg32;

static inline uint64_t rd_mix64(uint64_t z) /* splitmix64 finaliser */
{
    z += 0x9e3779b97f4a7c15ULL;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}
static inline uint32_t pcg32_next(pcg32 *r)
{
    uint64_t old = r->state;
    r->state = old * 6364136223846793005ULL + r->inc;
    uint32_t xs = (uint32_t)(((old >> 18u) ^ old) >> 27u);
    uint32_t rot = (uint32_t)(old >> 59u);
    return (xs >> rot) | (xs << ((-rot) & 31));
}
/* A stream determined only by its keys: the same (a, b, seed) gives the same numbers whatever
 * thread draws them (DESIGN.md convention 6). */
static inline pcg32 pcg32_seed(uint64_t a, uint64_t b, uint64_t seed)
{
    pcg32 r;
    r.state = 0;
    r.inc = (rd_mix64(seed ^ rd_mix64(a * 0x9E3779B97F4A7C15ULL + b)) << 1u) | 1u;
    pcg32_next(&r);
    r.state += rd_mix64(a ^ rd_mix64(b ^ rd_mix64(seed)));
    pcg32_next(&r);
    return r;
}
/* Uniform double in [0, 1). */
static inline double pcg32_uniform(pcg32 *r)
{
    uint64_t hi = pcg32_next(r), lo = pcg32_next(r);
    return (double)(((hi << 21) ^ lo) & ((1ULL << 53) - 1)) * (1.0 / 9007199254740992.0);
}

/* ---- Random numbers keyed by (pixel, sample, dimension) (DESIGN.md convention 6) ---------- *
 * A sample's random numbers are addressed, not drawn in sequence: dimension k of sample i of
 * pixel p is a hash of (p, i, k, seed), so two methods that read the same dimensions (the
 * camera jitter, RD_DIM_FILM) see the same numbers, and a low-discrepancy sequence can later
 * replace the low dimensions without touching the integrators. The unbounded part of a path
 * (free flights, roulette, an unknown number of draws) takes a PCG32 stream keyed by one
 * dimension (rd_sampler_stream): still a function of (p, i, k, seed) only, so images do not
 * depend on the thread count. */
typedef struct {
    uint64_t key;  /* hash of (pixel, sample, seed) */
    uint32_t dim;  /* next dimension to hand out */
} rd_sampler;

enum {
    RD_DIM_FILM = 0,    /* 2 dimensions: the position inside the pixel */
    RD_DIM_METHOD = 2   /* first dimension a method may use */
};

static inline rd_sampler rd_sampler_start(uint64_t pixel, uint64_t sample, uint64_t seed)
{
    rd_sampler s;
    s.key = rd_mix64(rd_mix64(rd_mix64(seed) ^ pixel) + sample);
    s.dim = 0;
    return s;
}
/* Uniform double in [0, 1) for the next dimension. */
static inline double rd_sampler_1d(rd_sampler *s)
{
    uint64_t h = rd_mix64(s->key ^ rd_mix64((uint64_t)s->dim++ + 0x632be59bd9b4e019ULL));
    return (double)(h >> 11) * (1.0 / 9007199254740992.0);
}
/* A PCG32 stream owned by the next dimension (for the parts of a path of unbounded length). */
static inline pcg32 rd_sampler_stream(rd_sampler *s)
{
    uint32_t d = s->dim++;
    return pcg32_seed(s->key, d, 0x5851f42d4c957f2dULL);
}

/* ---- Henyey-Greenstein (THEORY.md §1) ---------------------------------------------------- */
/* p(cos) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos)^1.5), cos = w'.w, g > 0 forward. */
static inline double rd_hg_eval(double g, double cos_theta)
{
    double denom = 1.0 + g * g - 2.0 * g * cos_theta;
    return RD_INV_4PI * (1.0 - g * g) / (denom * sqrt(denom));
}
/* Sample cos_theta by inverting the HG CDF (Pharr et al., pbrt-v4 SampleHenyeyGreenstein). */
static inline double rd_hg_sample_cos(double g, double u)
{
    if (fabs(g) < 1e-3) return 1.0 - 2.0 * u;
    double sq = (1.0 - g * g) / (1.0 + g - 2.0 * g * u);
    double c = (1.0 + g * g - sq * sq) / (2.0 * g);
    return fmin(1.0, fmax(-1.0, c));
}
/* Sample an outgoing direction around the propagation direction wi (unit): the scattering
 * angle is measured from wi, so g > 0 keeps light going forward. Returns the new direction;
 * the pdf equals rd_hg_eval(g, dot(wi, wo)). */
static inline vec3 rd_hg_sample(double g, vec3 wi, double u1, double u2)
{
    double c = rd_hg_sample_cos(g, u1);
    double s = sqrt(fmax(0.0, 1.0 - c * c));
    double phi = 2.0 * M_PI * u2;
    vec3 a, b;
    v3_basis(wi, &a, &b);
    return v3_norm(v3_add(v3_scale(wi, c), v3_add(v3_scale(a, s * cos(phi)), v3_scale(b, s * sin(phi)))));
}
/* Uniform direction on the sphere, pdf 1/(4 pi). */
static inline vec3 rd_sample_sphere(double u1, double u2)
{
    double z = 1.0 - 2.0 * u1, r = sqrt(fmax(0.0, 1.0 - z * z)), phi = 2.0 * M_PI * u2;
    return v3(r * cos(phi), r * sin(phi), z);
}

/* ---- von Mises-Fisher lobe (guided directions: transport/directions.c) --------------------- *
 * p(w) = kappa / (2 pi (1 - e^{-2 kappa})) e^{kappa (mu.w - 1)} on the unit sphere, mean
 * direction mu (unit), concentration kappa >= 0 (0: uniform). Both forms are the numerically
 * stable ones of W. Jakob, "Numerically stable sampling of the von Mises Fisher distribution
 * on S^2" (2012): no e^{kappa} overflow at large kappa, no cancellation at small. */
static inline double rd_vmf_eval(vec3 mu, double kappa, vec3 w)
{
    if (kappa < 1e-6) return RD_INV_4PI;
    return kappa / (2.0 * M_PI * -expm1(-2.0 * kappa)) * exp(kappa * (v3_dot(mu, w) - 1.0));
}
/* Sample w with pdf rd_vmf_eval: the cosine to mu by inverting its CDF,
 *   W = 1 + log(u1 + (1 - u1) e^{-2 kappa}) / kappa,
 * the azimuth uniform. */
static inline vec3 rd_vmf_sample(vec3 mu, double kappa, double u1, double u2)
{
    double c = kappa < 1e-6 ? 1.0 - 2.0 * u1
                            : 1.0 + log(u1 + (1.0 - u1) * exp(-2.0 * kappa)) / kappa;
    c = fmin(1.0, fmax(-1.0, c));
    double s = sqrt(fmax(0.0, 1.0 - c * c)), phi = 2.0 * M_PI * u2;
    vec3 a, b;
    v3_basis(mu, &a, &b);
    return v3_norm(v3_add(v3_scale(mu, c), v3_add(v3_scale(a, s * cos(phi)), v3_scale(b, s * sin(phi)))));
}
/* The concentration whose mean cosine (coth kappa - 1/kappa) is rbar, in [0, 1): Banerjee et
 * al. 2005's approximation kappa = rbar (3 - rbar^2) / (1 - rbar^2), within a few per cent. */
static inline double rd_vmf_kappa(double rbar)
{
    rbar = fmin(fmax(rbar, 0.0), 0.999);
    return rbar * (3.0 - rbar * rbar) / (1.0 - rbar * rbar);
}

#endif /* RD_MATH_H */
