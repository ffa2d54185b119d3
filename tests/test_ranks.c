/* rd_render on several ranks through its hooks (rd_render_opts.comm, renderer.h), without MPI:
 * the ranks are threads of this process and the reduce is done in shared memory behind a
 * barrier. So the render's part of the work split (tile ownership, the agreements between
 * passes, the selection's epoch sums, the probes' model sums, the films summed onto rank 0) is
 * tested in every suite,
 * the sanitizer run included, while tests/test_mpi.c tests the command line under mpirun.
 *  - three ranks give rank 0 one process's image and standard error bit for bit (guided with the
 *    tile selection, whose epochs need the ranks' sums);
 *  - "auto" probes (delta, guided, guided-unbiased), whose epochs choose M from the whole
 *    image's models, give rank 0 one process's image, standard error and probe count bit for
 *    bit;
 *  - a cancel flag set on one rank stops every rank at the next agreement (none waits);
 *  - rd_bake on three ranks (each traces a range of the photon blocks, gathered in block order)
 *    gives every rank one process's photons, segments, indirect photons, power sums and guides
 *    bit for bit (the guides' files but for the bake time they record), and a cancel flag on one rank fails the bake on all (none waits);
 *  - a render with progressive photon passes (each pass traced by the ranks together) gives
 *    rank 0 one process's image bit for bit. */
#include "support/rd_test.h"
#include "integrators/rd_method.h"
#include "bake/rd_photons.h"
#include "sh.h"

#include <pthread.h>

enum { MAX_RANKS = 4 };

typedef struct {
    pthread_barrier_t bar;
    int size;
    void *bufs[MAX_RANKS];
    void *result;
} fake_world;

typedef struct {
    fake_world *w;
    int rank;
    rd_comm comm;
    /* the render of this rank, or its bake (do_bake) */
    const rd_scene *scene;
    rd_render_opts opts;
    rd_render_result res;
    int do_bake;
    rd_bake_opts bopts;
    rd_baked *baked;
    rd_status st;
    char err[RD_ERRLEN];
} fake_rank;

static size_t elem_size(rd_comm_type t)
{
    return t == RD_COMM_DOUBLE ? sizeof(double) : t == RD_COMM_UINT32 ? sizeof(uint32_t)
           : t == RD_COMM_UINT64 ? sizeof(uint64_t) : sizeof(int);
}

#define COMBINE(T)                                                                       \
    do {                                                                                 \
        T *out = w->result;                                                              \
        for (size_t i = 0; i < count; i++) {                                             \
            T v = ((T *)w->bufs[0])[i];                                                  \
            for (int k = 1; k < w->size; k++) {                                          \
                T x = ((T *)w->bufs[k])[i];                                              \
                v = op == RD_COMM_SUM ? v + x : op == RD_COMM_MIN ? (x < v ? x : v) : (x > v ? x : v); \
            }                                                                            \
            out[i] = v;                                                                  \
        }                                                                                \
    } while (0)

/* rd_comm.reduce: every rank posts its buffer, rank 0 combines them in rank order (as MPI's
 * reduce may: the sums here add zeros to one owner's value, exact in any order), the receivers
 * copy the result. */
static void fake_reduce(void *user, void *buf, size_t count, rd_comm_type type, rd_comm_op op, int root)
{
    fake_rank *r = user;
    fake_world *w = r->w;
    w->bufs[r->rank] = buf;
    pthread_barrier_wait(&w->bar);
    if (r->rank == 0) {
        w->result = malloc(count * elem_size(type) + 1);
        if (!w->result) abort(); /* (not cr_assert: this is not the test's thread) */
        switch (type) {
        case RD_COMM_DOUBLE: COMBINE(double); break;
        case RD_COMM_UINT32: COMBINE(uint32_t); break;
        case RD_COMM_UINT64: COMBINE(uint64_t); break;
        default: COMBINE(int); break;
        }
    }
    pthread_barrier_wait(&w->bar);
    if (root < 0 || root == r->rank) memcpy(buf, w->result, count * elem_size(type));
    pthread_barrier_wait(&w->bar);
    if (r->rank == 0) free(w->result);
}

/* rd_comm.allgatherv: every rank posts its part, then each copies every rank's part in rank
 * order into its own recv. */
static void fake_allgatherv(void *user, const void *send, void *recv, const size_t *counts, size_t elem_bytes)
{
    fake_rank *r = user;
    fake_world *w = r->w;
    w->bufs[r->rank] = (void *)send;
    pthread_barrier_wait(&w->bar);
    char *at = recv;
    for (int k = 0; k < w->size; k++) {
        size_t bytes = counts[k] * elem_bytes;
        if (!bytes) continue; /* (recv may be NULL when every count is 0: no arithmetic on it) */
        if (at != w->bufs[k]) memcpy(at, w->bufs[k], bytes); /* (else in place) */
        at += bytes;
    }
    pthread_barrier_wait(&w->bar);
}

static void *rank_main(void *arg)
{
    fake_rank *r = arg;
    if (r->do_bake) {
        r->bopts.comm = &r->comm;
        r->st = rd_bake(r->scene, &r->bopts, &r->baked, r->err, sizeof r->err);
        return NULL;
    }
    r->opts.comm = &r->comm;
    r->st = rd_render(r->scene, &r->opts, &r->res, r->err, sizeof r->err);
    return NULL;
}

/* Run ranks[0..n) (set up by the caller, comm included) on n threads sharing one world. */
static void run_ranks(int n, fake_rank *ranks)
{
    fake_world *w = calloc(1, sizeof *w);
    cr_assert(w != NULL);
    w->size = n;
    pthread_barrier_init(&w->bar, NULL, (unsigned)n);
    pthread_t th[MAX_RANKS];
    for (int k = 0; k < n; k++) {
        ranks[k].w = w;
        ranks[k].rank = k;
        ranks[k].comm = (rd_comm){.rank = k, .size = n, .user = &ranks[k], .reduce = fake_reduce,
                                  .allgatherv = fake_allgatherv};
    }
    for (int k = 0; k < n; k++) cr_assert(pthread_create(&th[k], NULL, rank_main, &ranks[k]) == 0);
    for (int k = 0; k < n; k++) pthread_join(th[k], NULL);
    pthread_barrier_destroy(&w->bar);
    free(w);
}

/* Render `o` on `n` threaded ranks into ranks[0..n) (each rank's own copy of o). */
static void render_on_ranks(const rd_scene *s, const rd_render_opts *o, int n, fake_rank *ranks)
{
    for (int k = 0; k < n; k++) ranks[k] = (fake_rank){.scene = s, .opts = *o};
    run_ranks(n, ranks);
    for (int k = 0; k < n; k++) {
        cr_assert(ranks[k].st == RD_OK, "rank %d: %s", k, ranks[k].err);
        ranks[k].opts.comm = NULL;
    }
}

/* test_select.c's scene (rt_spot_fog_json) at 48x24: 3x2 render tiles, so with three ranks each
 * holds two tiles and part of the medium. guided's marcher against delta's path, no third
 * estimator (march.equiangular false): with the third, every tile here takes delta's path with
 * the strategy since session 42 (select_rule.c, "Tiles no sample has lit"), and the selection would
 * mix nothing. */
static const char *ranks_scene(void)
{
    return rt_spot_fog_json_with(48, 24, "{\"select\":\"tiles\"}",
                                 "\"photons\":{\"count\":40000},\"march\":{\"equiangular\":false}");
}

/* guided on scene s (JSON) to 20 samples (past the selection's epochs at 4 and 16), on one
 * process and on three ranks: rank 0's image, standard error and counters are one process's, and
 * the selection mixed estimators. */
static void three_ranks_match_one_process(const char *json)
{
    rd_scene *s = rt_scene("ranks.json", json);
    rd_bake_opts bo = {.seed = -1, .threads = 1};
    rd_bake_opts_for(&bo, rd_method_needs_for("guided", s));
    rd_baked *b = NULL;
    char err[RD_ERRLEN];
    cr_assert(rd_bake(s, &bo, &b, err, sizeof err) == RD_OK, "%s", err);
    /* 20 samples: past the selection's epochs at 4 and 16 */
    rd_render_opts o = {.method = "guided", .spp = 20, .seed = 4, .threads = 1, .baked = b};
    rd_render_result one;
    cr_assert(rd_render(s, &o, &one, err, sizeof err) == RD_OK, "%s", err);
    fake_rank ranks[3];
    render_on_ranks(s, &o, 3, ranks);
    const rd_render_result *r0 = &ranks[0].res;
    size_t n = (size_t)one.image.w * one.image.h * 3;
    cr_assert(memcmp(one.image.rgb, r0->image.rgb, n * sizeof(float)) == 0, "rank 0's image is not one process's");
    cr_assert(memcmp(one.stderr_img.rgb, r0->stderr_img.rgb, n * sizeof(float)) == 0,
              "rank 0's standard error is not one process's");
    cr_assert(one.stats.paths == r0->stats.paths && one.stats.delta_samples == r0->stats.delta_samples &&
                  one.stats.lookups == r0->stats.lookups && one.stats.spp == r0->stats.spp,
              "counters: paths %llu / %llu, delta samples %llu / %llu",
              (unsigned long long)one.stats.paths, (unsigned long long)r0->stats.paths,
              (unsigned long long)one.stats.delta_samples, (unsigned long long)r0->stats.delta_samples);
    double share = (double)one.stats.delta_samples / (double)one.stats.paths,
           eq = (double)one.stats.delta_eq_samples / (double)one.stats.paths;
    /* the marcher and delta's path, or delta's path in both equiangular modes (select.c) */
    cr_assert((share > 0.0 && share < 1.0) || (eq > 0.0 && eq < share),
              "delta's share %g (%g with equiangular sampling): the selection must mix estimators", share, eq);
    cr_assert(one.stats.delta_eq_samples == r0->stats.delta_eq_samples && one.stats.eq_flights == r0->stats.eq_flights,
              "the third kind's samples or the equiangular set-ups differ");
    /* Each other rank holds only its own tiles: fewer samples than the image. */
    for (int k = 1; k < 3; k++) cr_assert(ranks[k].res.stats.spp_mean < r0->stats.spp_mean, "rank %d", k);
    for (int k = 0; k < 3; k++) rd_render_result_free(&ranks[k].res);
    rd_render_result_free(&one);
    rd_baked_free(b);
    rd_scene_free(s);
}

Test(ranks, three_ranks_give_rank_0_one_process_s_image_bit_for_bit, .timeout = 600)
{
    three_ranks_match_one_process(ranks_scene());
}

/* settings.adaptive: the shares and the weights (integrators/select_share.c) are read from
 * statistics every rank folds alike, and the film's weighted sums are summed onto rank 0 with
 * the rest (render.c): one process's image and standard error, bit for bit. */
Test(ranks, shares_and_weights_on_three_ranks_give_rank_0_one_process_s_image_bit_for_bit, .timeout = 600)
{
    three_ranks_match_one_process(rt_spot_fog_json_with(48, 24, "{\"select\":\"tiles\",\"adaptive\":true}",
                                                        "\"photons\":{\"count\":40000},\"march\":{\"equiangular\":false}"));
}

/* "auto" probes (settings.probes for delta, march.probes for guided, guide.probes for
 * guided-unbiased; integrators/probes.c): at every epoch each pixel's M is chosen from its
 * model and from one rate, lambda, a fixed point over the whole image, so each rank needs
 * every other rank's pixels (the models are summed over the ranks first). Three ranks give
 * rank 0 one process's image, standard error and probe count bit for bit, past the epochs at
 * 4 and 16, on a small sphere light seen through haze (test_surface_images.c's scene 6 without
 * the glass ball, at 48x36 with the default source and selection), where the chains that end
 * on the light's edge are the noisy part: the 16-pixel render tiles put the light's edge on
 * two ranks and none on rank 0. The probes must go past the first samples' (2 a pixel, one
 * each), or the epochs chose nothing. A planted fault, the models' sum over the ranks skipped
 * (rd_probes_epoch), fails it (guided-unbiased: 8852 probes on three ranks against 8872). */
Test(ranks, auto_probes_on_three_ranks_give_rank_0_one_process_s_image, .timeout = 600)
{
    rd_scene *s = rt_scene("ranksq.json",
        "{\"camera\":{\"position\":[0.1,0.05,3],\"look_at\":[0,0,0],\"fov\":24,\"resolution\":[48,36]},"
        "\"media\":[{\"bounds\":{\"min\":[-1.5,-1.2,-2.2],\"max\":[1.5,1.2,3.5]},"
        "\"density\":1,\"sigma_t\":0.25,\"albedo\":0.8,\"g\":0.3}],"
        "\"lights\":[{\"type\":\"sphere\",\"center\":[0.35,0.1,-1.5],\"radius\":0.1,\"radiance\":[100,90,80]}],"
        "\"photons\":{\"count\":10000},\"march\":{\"probes\":\"auto\"},\"guide\":{\"probes\":\"auto\"},"
        "\"settings\":{\"max_depth\":8,\"probes\":\"auto\"}}");
    static const char *const methods[] = {"delta", "guided", "guided-unbiased"};
    for (int i = 0; i < 3; i++) {
        rd_render_opts o = {.method = methods[i], .spp = 20, .seed = 9, .threads = 1};
        rd_render_result one;
        char err[RD_ERRLEN];
        cr_assert(rd_render(s, &o, &one, err, sizeof err) == RD_OK, "%s: %s", methods[i], err);
        uint64_t first = 2 * (uint64_t)one.image.w * one.image.h;
        cr_log_info("%s: %llu probes (the first samples' %llu)", methods[i], (unsigned long long)one.stats.probes,
                    (unsigned long long)first);
        cr_expect(one.stats.probes > first, "%s: %llu probes, no more than the first samples' %llu", methods[i],
                  (unsigned long long)one.stats.probes, (unsigned long long)first);
        fake_rank ranks[3];
        render_on_ranks(s, &o, 3, ranks);
        const rd_render_result *r0 = &ranks[0].res;
        size_t n = (size_t)one.image.w * one.image.h * 3;
        cr_expect(memcmp(one.image.rgb, r0->image.rgb, n * sizeof(float)) == 0, "%s: rank 0's image is not one process's",
                  methods[i]);
        cr_expect(memcmp(one.stderr_img.rgb, r0->stderr_img.rgb, n * sizeof(float)) == 0,
                  "%s: rank 0's standard error is not one process's", methods[i]);
        cr_expect(one.stats.probes == r0->stats.probes && one.stats.paths == r0->stats.paths,
                  "%s: probes %llu / %llu, paths %llu / %llu", methods[i], (unsigned long long)one.stats.probes,
                  (unsigned long long)r0->stats.probes, (unsigned long long)one.stats.paths,
                  (unsigned long long)r0->stats.paths);
        for (int k = 0; k < 3; k++) rd_render_result_free(&ranks[k].res);
        rd_render_result_free(&one);
    }
    rd_scene_free(s);
}

Test(ranks, a_cancel_on_one_rank_stops_them_all, .timeout = 300)
{
    rd_scene *s = rt_scene("ranksc.json", ranks_scene());
    /* delta, no bake; rank 1's flag is set from the start, the others' never */
    rd_render_opts o = {.method = "delta", .spp = 1 << 20, .seed = 1, .threads = 1};
    static volatile int set = 1;
    fake_rank ranks[2];
    for (int k = 0; k < 2; k++) ranks[k] = (fake_rank){.scene = s, .opts = o};
    ranks[1].opts.cancel = &set; /* rank 1's flag alone */
    run_ranks(2, ranks);
    for (int k = 0; k < 2; k++) {
        cr_assert(ranks[k].st == RD_OK, "rank %d: %s", k, ranks[k].err);
        cr_assert(ranks[k].res.stats.cancelled && ranks[k].res.stats.spp == 0,
                  "rank %d: cancelled %d after %d spp", k, ranks[k].res.stats.cancelled, ranks[k].res.stats.spp);
        rd_render_result_free(&ranks[k].res);
    }
    rd_scene_free(s);
}

/* The bytes sh_guide_write writes for g (a caller-freed buffer, its size in *n). */
static char *guide_bytes(const struct sh_guide *g, size_t *n)
{
    char *buf = NULL, err[RD_ERRLEN];
    FILE *f = open_memstream(&buf, n);
    cr_assert(f != NULL);
    cr_assert(sh_guide_write(g, f, "guide", err, sizeof err) == SH_OK, "%s", err);
    fclose(f);
    return buf;
}

static void expect_same_map(const pm_map *a, const pm_map *b, const char *what, int rank)
{
    cr_assert(pm_map_photon_count(a) == pm_map_photon_count(b) && pm_map_segment_count(a) == pm_map_segment_count(b),
              "rank %d, %s: %zu photons and %zu segments, one process %zu and %zu", rank, what,
              pm_map_photon_count(b), pm_map_segment_count(b), pm_map_photon_count(a), pm_map_segment_count(a));
    cr_assert(memcmp(pm_map_photons(a), pm_map_photons(b), pm_map_photon_count(a) * sizeof(pm_photon)) == 0,
              "rank %d, %s: the photons differ", rank, what);
    if (pm_map_segment_count(a))
        cr_assert(memcmp(pm_map_segments(a), pm_map_segments(b), pm_map_segment_count(a) * sizeof(pm_segment)) == 0,
                  "rank %d, %s: the segments differ", rank, what);
}

static void expect_same_guide(const struct sh_guide *a, const struct sh_guide *b, const char *what, int rank)
{
    size_t na, nb;
    char *x = guide_bytes(a, &na), *y = guide_bytes(b, &nb);
    cr_assert(rt_same_guide_bytes(x, na, y, nb), "rank %d, %s: the guide's bytes differ (bake time aside)", rank, what);
    free(x);
    free(y);
}

Test(ranks, three_ranks_bake_one_process_s_photons_and_guides_bit_for_bit, .timeout = 600)
{
    /* 40000 photons: 10 blocks of 4096, split 3 + 3 + 4; segments stored too, and the indirect
     * map and its guide (one trace for both maps) */
    rd_scene *s = rt_scene("ranksb.json", ranks_scene());
    s->photons.segments = 1;
    rd_bake_opts bo = {.seed = -1, .threads = 1, .indirect = 1, .indirect_guide = 1};
    rd_baked *one = NULL;
    char err[RD_ERRLEN];
    cr_assert(rd_bake(s, &bo, &one, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(pm_map_segment_count(rd_baked_map(one)) > 0 && pm_map_photon_count(rd_baked_indirect_map(one)) > 0);
    fake_rank ranks[3];
    for (int k = 0; k < 3; k++) ranks[k] = (fake_rank){.scene = s, .do_bake = 1, .bopts = bo};
    ranks[2].bopts.threads = 2; /* the thread count changes nothing either */
    run_ranks(3, ranks);
    const rd_bake_stats *a = rd_baked_stats(one);
    for (int k = 0; k < 3; k++) {
        cr_assert(ranks[k].st == RD_OK, "rank %d: %s", k, ranks[k].err);
        const rd_baked *b = ranks[k].baked;
        expect_same_map(rd_baked_map(one), rd_baked_map(b), "map", k);
        expect_same_map(rd_baked_indirect_map(one), rd_baked_indirect_map(b), "indirect map", k);
        expect_same_guide(rd_baked_guide(one), rd_baked_guide(b), "guide", k);
        expect_same_guide(rd_baked_indirect_guide(one), rd_baked_indirect_guide(b), "indirect guide", k);
        const rd_bake_stats *c = rd_baked_stats(b);
        /* the power sums in block order: the same additions, so the same bits */
        cr_assert(a->power_emitted == c->power_emitted && a->power_absorbed == c->power_absorbed &&
                      a->power_escaped == c->power_escaped && a->power_cut == c->power_cut &&
                      a->collisions_per_photon == c->collisions_per_photon && a->emitted == c->emitted,
                  "rank %d: power emitted %.17g / %.17g, absorbed %.17g / %.17g", k, a->power_emitted,
                  c->power_emitted, a->power_absorbed, c->power_absorbed);
        cr_assert(c->ranks == 3 && c->gather_bytes > 0, "rank %d: ranks %d, gathered %zu bytes", k, c->ranks,
                  c->gather_bytes);
        rd_baked_free(ranks[k].baked);
    }
    rd_baked_free(one);
    rd_scene_free(s);
}

Test(ranks, a_cancel_on_one_rank_fails_the_bake_on_all, .timeout = 300)
{
    rd_scene *s = rt_scene("ranksbc.json", ranks_scene());
    static volatile int set = 1;
    fake_rank ranks[2];
    for (int k = 0; k < 2; k++) ranks[k] = (fake_rank){.scene = s, .do_bake = 1, .bopts = {.seed = -1, .threads = 1}};
    ranks[1].bopts.cancel = &set; /* rank 1's flag alone */
    run_ranks(2, ranks);
    for (int k = 0; k < 2; k++) {
        cr_assert(ranks[k].st == RD_ERR_CANCELLED && ranks[k].baked == NULL, "rank %d: status %d: %s", k,
                  ranks[k].st, ranks[k].err);
    }
    cr_assert(strstr(ranks[0].err, RD_ON_ANOTHER_RANK) != NULL, "rank 0 says another rank stopped: %s", ranks[0].err);
    rd_scene_free(s);
}

Test(ranks, beams_mixed_with_delta_pace_their_photon_passes_alike_on_two_ranks, .timeout = 600)
{
    /* guided with nee+beams mixed with delta's path per tile (select "tiles") and a photon pass
     * per 768 samples of the beams (pass_spp 1, 32x24 pixels): every rank must compute the same
     * tiles and so the same pass schedule (the passes are collective), and the image is one
     * process's. */
    rd_scene *s = rt_scene("ranksb.json", rt_spot_fog_json_with(32, 24, "{\"select\":\"tiles\"}",
        "\"photons\":{\"count\":40000,\"progressive\":true,\"pass_count\":4000,\"pass_spp\":1},"
        "\"march\":{\"ls\":\"nee+beams\"}"));
    rd_render_opts o = {.method = "guided", .spp = 20, .seed = 5, .threads = 1};
    rd_render_result one;
    char err[RD_ERRLEN];
    cr_assert(rd_render(s, &o, &one, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(one.stats.delta_samples > 0 && one.stats.photon_passes < 20, "%llu delta samples, %d photon passes",
              (unsigned long long)one.stats.delta_samples, one.stats.photon_passes);
    fake_rank ranks[2];
    render_on_ranks(s, &o, 2, ranks);
    const rd_render_result *r0 = &ranks[0].res;
    size_t n = (size_t)one.image.w * one.image.h * 3;
    cr_assert(memcmp(one.image.rgb, r0->image.rgb, n * sizeof(float)) == 0, "rank 0's image is not one process's");
    cr_assert(r0->stats.photon_passes == one.stats.photon_passes && r0->stats.delta_samples == one.stats.delta_samples,
              "rank 0: %d passes, %llu delta samples; one process %d, %llu", r0->stats.photon_passes,
              (unsigned long long)r0->stats.delta_samples, one.stats.photon_passes,
              (unsigned long long)one.stats.delta_samples);
    for (int k = 0; k < 2; k++) rd_render_result_free(&ranks[k].res);
    rd_render_result_free(&one);
    rd_scene_free(s);
}

Test(ranks, progressive_photon_passes_on_two_ranks_give_one_process_s_image, .timeout = 600)
{
    /* uniform marching with the photons as its source, a photon pass every 2 samples: 6
     * samples trace 3 passes of 8192 photons, each by the two ranks together */
    rd_scene *s = rt_scene("ranksp.json", rt_spot_fog_json_with(32, 16, "{\"method\":\"uniform\"}",
        "\"photons\":{\"count\":8192,\"progressive\":true,\"pass_spp\":2},\"march\":{\"ls\":\"photons\"}"));
    rd_render_opts o = {.method = "uniform", .spp = 6, .seed = 3, .threads = 1};
    rd_render_result one;
    char err[RD_ERRLEN];
    cr_assert(rd_render(s, &o, &one, err, sizeof err) == RD_OK, "%s", err);
    cr_assert(one.stats.photon_passes == 3, "%d photon passes", one.stats.photon_passes);
    fake_rank ranks[2];
    render_on_ranks(s, &o, 2, ranks);
    const rd_render_result *r0 = &ranks[0].res;
    size_t n = (size_t)one.image.w * one.image.h * 3;
    cr_assert(memcmp(one.image.rgb, r0->image.rgb, n * sizeof(float)) == 0, "rank 0's image is not one process's");
    cr_assert(r0->stats.photon_passes == 3 && r0->stats.photons_traced == one.stats.photons_traced,
              "rank 0: %d passes, %llu photons", r0->stats.photon_passes, (unsigned long long)r0->stats.photons_traced);
    for (int k = 0; k < 2; k++) rd_render_result_free(&ranks[k].res);
    rd_render_result_free(&one);
    rd_scene_free(s);
}
