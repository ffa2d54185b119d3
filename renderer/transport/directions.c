/* directions.c: how a path continues from a scattering vertex (rd_transport.h rd_dir_mix): with
 * probability a a von Mises-Fisher lobe (the guide's incident light), else the Henyey-Greenstein
 * phase function; one-sample MIS over the two (Veach 1997 §9.2.4), so the weight of any draw is
 * hg / (a vmf + (1 - a) hg). With a = 0 it is phase sampling alone, drawing what `delta` draws. */
#include "transport/rd_transport.h"

double rd_dir_mix_pdf(const rd_dir_mix *mx, double g, vec3 d, vec3 wo)
{
    double p = rd_hg_eval(g, v3_dot(d, wo));
    if (!(mx->a > 0.0)) return p;
    return mx->a * rd_vmf_eval(mx->mu, mx->kappa, wo) + (1.0 - mx->a) * p;
}

vec3 rd_dir_mix_sample(const rd_dir_mix *mx, double g, vec3 d, pcg32 *rng, double *pdf)
{
    /* One-sample MIS (Veach 1997 §9.2.4): pick a strategy, draw from it, and weight by the
     * mixture's pdf, which any draw from either strategy shares. */
    int lobe = mx->a > 0.0 && pcg32_uniform(rng) < mx->a;
    double u1 = pcg32_uniform(rng), u2 = pcg32_uniform(rng);
    vec3 wo = lobe ? rd_vmf_sample(mx->mu, mx->kappa, u1, u2) : rd_hg_sample(g, d, u1, u2);
    *pdf = rd_dir_mix_pdf(mx, g, d, wo);
    return wo;
}

