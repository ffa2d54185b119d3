/* rd_render on several ranks through its hooks (rd_render_opts.comm, renderer.h), without MPI:
 * the ranks are threads of this process and the reduce is done in shared memory behind a
 * barrier. So the render's part of the work split (tile ownership, the agreements between
 * passes, the selection's epoch sums, the films summed onto rank 0) is tested in every suite,
 * the sanitizer run included, while tests/test_mpi.c tests the command line under mpirun.
 *  - three ranks give rank 0 one process's image and standard error bit for bit (guided with the
 *    tile selection, whose epochs need the ranks' sums);
 *  - a cancel flag set on one rank stops every rank at the next agreement (none waits). */
#include "support/rd_test.h"
#include "integrators/rd_method.h"

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
    /* the render of this rank */
    const rd_scene *scene;
    rd_render_opts opts;
    rd_render_result res;
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

static void *rank_main(void *arg)
{
    fake_rank *r = arg;
    r->opts.comm = &r->comm;
    r->st = rd_render(r->scene, &r->opts, &r->res, r->err, sizeof r->err);
    return NULL;
}

/* Render `o` on `n` threaded ranks into ranks[0..n) (each rank's own copy of o). */
static void render_on_ranks(const rd_scene *s, const rd_render_opts *o, int n, fake_rank *ranks)
{
    fake_world *w = calloc(1, sizeof *w);
    cr_assert(w != NULL);
    w->size = n;
    pthread_barrier_init(&w->bar, NULL, (unsigned)n);
    pthread_t th[MAX_RANKS];
    for (int k = 0; k < n; k++) {
        ranks[k] = (fake_rank){.w = w, .rank = k, .scene = s, .opts = *o};
        ranks[k].comm = (rd_comm){.rank = k, .size = n, .user = &ranks[k], .reduce = fake_reduce};
    }
    for (int k = 0; k < n; k++) cr_assert(pthread_create(&th[k], NULL, rank_main, &ranks[k]) == 0);
    for (int k = 0; k < n; k++) pthread_join(th[k], NULL);
    pthread_barrier_destroy(&w->bar);
    free(w);
    for (int k = 0; k < n; k++) {
        cr_assert(ranks[k].st == RD_OK, "rank %d: %s", k, ranks[k].err);
        ranks[k].opts.comm = NULL;
    }
}

/* test_select.c's scene (rt_spot_fog_json) at 48x24: 3x2 render tiles, so with three ranks each
 * holds two tiles and part of the medium. */
static const char *ranks_scene(void)
{
    return rt_spot_fog_json(48, 24, "{\"select\":\"tiles\"}");
}

Test(ranks, three_ranks_give_rank_0_one_process_s_image_bit_for_bit, .timeout = 600)
{
    rd_scene *s = rt_scene("ranks.json", ranks_scene());
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
    double share = (double)one.stats.delta_samples / (double)one.stats.paths;
    cr_assert(share > 0.0 && share < 1.0, "delta's share %g: the selection must mix both estimators", share);
    /* Each other rank holds only its own tiles: fewer samples than the image. */
    for (int k = 1; k < 3; k++) cr_assert(ranks[k].res.stats.spp_mean < r0->stats.spp_mean, "rank %d", k);
    for (int k = 0; k < 3; k++) rd_render_result_free(&ranks[k].res);
    rd_render_result_free(&one);
    rd_baked_free(b);
    rd_scene_free(s);
}

Test(ranks, a_cancel_on_one_rank_stops_them_all, .timeout = 300)
{
    rd_scene *s = rt_scene("ranksc.json", ranks_scene());
    /* delta, no bake; rank 1's flag is set from the start, the others' never */
    rd_render_opts o = {.method = "delta", .spp = 1 << 20, .seed = 1, .threads = 1};
    static volatile int set = 1;
    fake_rank ranks[2];
    /* render_on_ranks copies o to every rank; give rank 1 its flag through a second copy */
    fake_world *w = calloc(1, sizeof *w);
    cr_assert(w != NULL);
    w->size = 2;
    pthread_barrier_init(&w->bar, NULL, 2);
    pthread_t th[2];
    for (int k = 0; k < 2; k++) {
        ranks[k] = (fake_rank){.w = w, .rank = k, .scene = s, .opts = o};
        ranks[k].comm = (rd_comm){.rank = k, .size = 2, .user = &ranks[k], .reduce = fake_reduce};
    }
    ranks[1].opts.cancel = &set;
    for (int k = 0; k < 2; k++) cr_assert(pthread_create(&th[k], NULL, rank_main, &ranks[k]) == 0);
    for (int k = 0; k < 2; k++) pthread_join(th[k], NULL);
    pthread_barrier_destroy(&w->bar);
    free(w);
    for (int k = 0; k < 2; k++) {
        cr_assert(ranks[k].st == RD_OK, "rank %d: %s", k, ranks[k].err);
        cr_assert(ranks[k].res.stats.cancelled && ranks[k].res.stats.spp == 0,
                  "rank %d: cancelled %d after %d spp", k, ranks[k].res.stats.cancelled, ranks[k].res.stats.spp);
        rd_render_result_free(&ranks[k].res);
    }
    rd_scene_free(s);
}
