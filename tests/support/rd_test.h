/* rd_test.h: header-only helpers for the renderer tests (scene from a JSON string, a temporary
 * folder, running the CLI). Everything is static so each test file gets its own copy. */
#ifndef RD_TEST_H
#define RD_TEST_H

#define _DEFAULT_SOURCE
#include "core/rd_core.h"
#include "transport/rd_path.h"

#include <criterion/criterion.h>
#include <fcntl.h>
#include <signal.h>
#include <stdatomic.h>
#include <time.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

/* A fresh folder under /tmp for this test process, removed when the process exits. */
static char rt_dir_[64]; /* written once per process (each Criterion test runs in its own) */
static inline void rt_tmpdir_remove(void)
{
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", rt_dir_);
    if (rt_dir_[0] && system(cmd) != 0) fprintf(stderr, "could not remove %s\n", rt_dir_);
}
static inline const char *rt_tmpdir(void)
{
    if (!rt_dir_[0]) {
        snprintf(rt_dir_, sizeof rt_dir_, "/tmp/rdtest.XXXXXX");
        cr_assert(mkdtemp(rt_dir_) != NULL, "mkdtemp failed");
        atexit(rt_tmpdir_remove);
    }
    return rt_dir_;
}

static inline void rt_write_file(const char *path, const void *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    cr_assert(f != NULL, "cannot write %s", path);
    cr_assert(fwrite(data, 1, n, f) == n);
    fclose(f);
}

/* <tmp>/<name>, in one of four rotating buffers (valid until the fourth call after it). */
static inline const char *rt_tmp_path(const char *name)
{
    static char path[4][256];
    static int k = 0;
    k = (k + 1) % 4;
    snprintf(path[k], sizeof path[k], "%s/%s", rt_tmpdir(), name);
    return path[k];
}

/* Write `json` to <tmp>/<name> and load it; the test fails with the loader's message if the
 * scene does not load. The guided methods' tile selection (settings.select, on by default) is
 * turned off unless the scene names it: a test of a method's estimator must render the method
 * at every pixel, not hand some tiles to delta's path (tests/test_select.c tests the mix). So is
 * `delta`'s own (settings.equiangular, "tiles" by default since session 72) unless the scene
 * names the key: a test that takes `delta` as its reference renders its plain path, the
 * independent estimator, at a sanitizer build's cost as before (tests/test_select.c tests the
 * tiles and the default, which the CLI's tests render). */
static inline rd_scene *rt_scene(const char *name, const char *json)
{
    char path[256], err[RD_ERRLEN];
    snprintf(path, sizeof path, "%s/%s", rt_tmpdir(), name);
    rt_write_file(path, json, strlen(json));
    rd_scene *s = NULL;
    rd_status st = rd_scene_load(&s, path, NULL, 0, err, sizeof err);
    cr_assert(st == RD_OK, "scene %s did not load: %s", name, err);
    if (!strstr(json, "\"select\"")) s->settings.select = RD_SELECT_OFF;
    if (!s->settings.equiangular_given) s->settings.equiangular = RD_EQ_OFF;
    return s;
}

/* A fog box [-1, 1]^3 (the scene-wide medium, sigma_t 1, albedo 0.9) with a glass ball of
 * vacuum at its centre (scenes/data/icosphere-3.obj, radius 0.3, ior 1.5) and `light` (one JSON
 * light), seen at width x width from 4 m: the light-through-glass scenes of
 * tests/test_photons.c and tests/test_compare.c (rd_hidden_light). Run from the repository root. */
static inline rd_scene *rt_glass_ball_in_fog(const char *name, const char *light, int width)
{
    char json[2048], cwd[1024];
    cr_assert(getcwd(cwd, sizeof cwd) != NULL);
    snprintf(json, sizeof json,
             "{\"camera\":{\"position\":[0,0,4],\"look_at\":[0,0,0],\"resolution\":[%d,%d]},\"medium\":\"fog\","
             "\"media\":[{\"name\":\"fog\",\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},"
             "\"density\":{\"type\":\"constant\",\"value\":1},\"sigma_t\":1,\"albedo\":0.9}],"
             "\"shapes\":[{\"name\":\"ball\",\"file\":\"%s/scenes/data/icosphere-3.obj\",\"transform\":{\"scale\":0.3},"
             "\"material\":{\"type\":\"dielectric\",\"ior\":1.5},\"inside\":null,\"outside\":\"fog\"}],"
             "\"lights\":[%s],\"photons\":{\"count\":20000}}",
             width, width, cwd, light);
    return rt_scene(name, json);
}

/* 1 when two .guide files' bytes (a, na; b, nb) are the same but for what a bake's clock puts
 * there: the bake seconds in the header (offset 112, docs/guide-grid.md) and so the checksum
 * of every byte before the end (the last 8). Two bakes of one map are equal so, never byte for
 * byte. */
static inline int rt_same_guide_bytes(const char *a, size_t na, const char *b, size_t nb)
{
    if (na != nb || na < 136) return 0;
    return memcmp(a, b, 112) == 0 && memcmp(a + 120, b + 120, na - 128) == 0;
}

/* The guided methods' selection scene (tests/test_select.c, test_mpi.c, test_ranks.c): a
 * narrow spot (3 degrees) across a thin fog seen side-on (scenes/hard-narrow-spot.json made
 * small), the fog cut at x = 0 so that the right half of the image sees none; width x height
 * pixels, `settings` the scene's "settings" object; `photons` the scene's "photons" member and
 * any further top-level members (rt_spot_fog_json: "photons":{"count":40000}). Returns the JSON
 * (a static buffer, valid until the next call). */
static inline const char *rt_spot_fog_json_with(int width, int height, const char *settings, const char *photons)
{
    static char buf[2048];
    snprintf(buf, sizeof buf,
             "{\"camera\":{\"position\":[0,0.3,4.5],\"look_at\":[0,0,0],\"fov\":40,\"resolution\":[%d,%d]},"
             "\"media\":[{\"bounds\":{\"min\":[-2.2,-1,-1.2],\"max\":[0.0,1,1.2]},"
             "\"density\":{\"type\":\"noise\",\"octaves\":3,\"frequency\":1.2,\"amplitude\":0.4,\"seed\":5,"
             "\"shape\":\"none\"},\"sigma_t\":0.15,\"albedo\":0.9,\"g\":0.3}],"
             "\"lights\":[{\"type\":\"spot\",\"position\":[-3.2,0.9,-0.4],\"look_at\":[2.2,-0.5,0.3],\"angle\":3,"
             "\"falloff\":0.3,\"intensity\":[1600,1500,1300]}],"
             "%s,\"settings\":%s}",
             width, height, photons, settings);
    return buf;
}

static inline const char *rt_spot_fog_json(int width, int height, const char *settings)
{
    return rt_spot_fog_json_with(width, height, settings, "\"photons\":{\"count\":40000}");
}

/* Run `argv` (argv[0] is the program path) with stdout/stderr captured into the given buffers;
 * returns the exit status, or 1000 + signal number when it died of a signal. When cpu_seconds is
 * not NULL it gets the child's CPU time (user + system, from wait4): what a test measures of a
 * child's cost, since the wall time depends on the machine's load. Every child runs under a CPU
 * limit (RT_CHILD_CPU_LIMIT seconds; SIGXCPU past it, returned as 1000 + SIGXCPU), so a child
 * that spins for ever ends the test instead of hanging it. */
#define RT_CHILD_CPU_LIMIT 600
static inline int rt_run(char *const argv[], char *out, size_t outlen, char *errbuf, size_t errlen,
                         double *cpu_seconds)
{
    char fo[256], fe[256];
    snprintf(fo, sizeof fo, "%s/stdout.XXXXXX", rt_tmpdir());
    snprintf(fe, sizeof fe, "%s/stderr.XXXXXX", rt_tmpdir());
    int ofd = mkstemp(fo), efd = mkstemp(fe);
    cr_assert(ofd >= 0 && efd >= 0);
    pid_t pid = fork();
    cr_assert(pid >= 0);
    if (pid == 0) {
        dup2(ofd, 1);
        dup2(efd, 2);
        int nul = open("/dev/null", O_RDONLY);
        dup2(nul, 0);
        setenv("ASAN_OPTIONS", "exitcode=86:detect_leaks=1", 1);
        setenv("UBSAN_OPTIONS", "halt_on_error=1:exitcode=87:print_stacktrace=1", 1);
        struct rlimit cpu = {RT_CHILD_CPU_LIMIT, RT_CHILD_CPU_LIMIT};
        setrlimit(RLIMIT_CPU, &cpu);
        execv(argv[0], argv);
        _exit(127);
    }
    int status;
    struct rusage ru;
    cr_assert(wait4(pid, &status, 0, &ru) == pid);
    if (cpu_seconds)
        *cpu_seconds = ru.ru_utime.tv_sec + 1e-6 * ru.ru_utime.tv_usec + ru.ru_stime.tv_sec + 1e-6 * ru.ru_stime.tv_usec;
    FILE *f;
    if (out && (f = fdopen(ofd, "r"))) {
        rewind(f);
        size_t n = fread(out, 1, outlen - 1, f);
        out[n] = 0;
        fclose(f);
    } else close(ofd);
    if (errbuf && (f = fdopen(efd, "r"))) {
        rewind(f);
        size_t n = fread(errbuf, 1, errlen - 1, f);
        errbuf[n] = 0;
        fclose(f);
    } else close(efd);
    unlink(fo);
    unlink(fe);
    if (WIFSIGNALED(status)) return 1000 + WTERMSIG(status);
    return WEXITSTATUS(status);
}

/* Monte Carlo estimate of the radiance the `delta` integrator carries along camera ray r:
 * the mean of n samples and its standard error, per channel. Sample i draws from the PCG32
 * stream pcg32_seed(seed, i, 1234). Every integrator test goes through this one helper, so
 * only it changes when rd_delta_radiance's signature does. */
typedef struct {
    vec3 mean, se;
} rt_mc;

static inline rt_mc rt_delta_mc(const rd_scene *s, ray3 r, int n, uint64_t seed)
{
    rd_track_counters c = {0};
    double sum[3] = {0, 0, 0}, sum2[3] = {0, 0, 0};
    for (int i = 0; i < n; i++) {
        pcg32 rng = pcg32_seed(seed, (uint64_t)i, 1234);
        vec3 L = rd_delta_radiance(s, r, &rng, &c);
        for (int k = 0; k < 3; k++) {
            double v = v3_get(L, k);
            sum[k] += v;
            sum2[k] += v * v;
        }
    }
    double mean[3], se[3];
    for (int k = 0; k < 3; k++) {
        mean[k] = sum[k] / n;
        se[k] = sqrt(fmax(0.0, sum2[k] / n - mean[k] * mean[k]) / n);
    }
    rt_mc m = {v3(mean[0], mean[1], mean[2]), v3(se[0], se[1], se[2])};
    return m;
}

/* Composite Simpson rule for the integral of f over [a, b] with n (even) intervals. Its error
 * is -(b-a) h^4 f''''(xi)/180 for a smooth f: callers split at every jump of their integrand. */
static inline double rt_simpson(double (*f)(double t, const void *ctx), const void *ctx, double a,
                                double b, int n)
{
    if (!(b > a)) return 0.0;
    if (n % 2) n++;
    double h = (b - a) / n, q = f(a, ctx) + f(b, ctx);
    for (int i = 1; i < n; i++) q += (i % 2 ? 4.0 : 2.0) * f(a + i * h, ctx);
    return q * h / 3.0;
}

/* Length of the segment a->b inside the box [bmin, bmax]. */
static inline double rt_inside_length(vec3 bmin, vec3 bmax, vec3 a, vec3 b)
{
    vec3 d = v3_sub(b, a);
    double len = v3_len(d), t0, t1;
    if (len <= 0.0) return 0.0;
    ray3 r = {a, v3_scale(d, 1.0 / len)};
    if (!rd_box_intersect(bmin, bmax, r, 0.0, len, &t0, &t1)) return 0.0;
    return t1 - t0;
}

/* Pearson's chi-square of nb bins' counts obs against n samples of the expected fractions
 * frac, the bins with an expected count below 5 pooled into one (pbrt-v4 bsdfs_test); *dof its
 * degrees of freedom (bins kept, the pool counting as one, less one). */
static inline double rt_chi2_pooled(const double *obs, const double *frac, int nb, int n, int *dof)
{
    double chi2 = 0, pool_o = 0, pool_e = 0;
    *dof = -1;
    for (int i = 0; i < nb; i++) {
        double e = n * frac[i];
        if (e < 5) { pool_o += obs[i]; pool_e += e; continue; }
        chi2 += (obs[i] - e) * (obs[i] - e) / e;
        (*dof)++;
    }
    if (pool_e >= 5) { chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e; (*dof)++; }
    return chi2;
}

/* Wilson-Hilferty approximation of the chi-square quantile for `dof` degrees of freedom at
 * standard-normal quantile z (z = 3.719 for an upper tail of 1e-4). */
static inline double rt_chi2_quantile(int dof, double z)
{
    double k = dof, a = 2.0 / (9.0 * k);
    double c = 1.0 - a + z * sqrt(a);
    return k * c * c * c;
}

/* ---- Clocks for rd_render_opts.clock and rd_cmp_opts.clock -------------------------------
 * The timing tests keep and read time on these, not on the wall clock, so that what they check
 * does not depend on how loaded the machine is. */

/* A virtual clock: its k-th reading (k = 0, 1, ...) is k dt, whatever the time. A render's time
 * on it is the number of clock readings it made: one before every pixel it starts (the time
 * limit's check) and a few of its own (set-up, each pass's start and end, the report). Atomic:
 * the render's threads read it at once. dt a power of two keeps k dt exact. */
typedef struct {
    atomic_llong n; /* readings so far */
    double dt;
} rt_ticks;

static inline double rt_ticks_read(void *user)
{
    rt_ticks *t = user;
    return t->dt * (double)atomic_fetch_add(&t->n, 1);
}

/* CPU seconds of the calling thread. A render on one thread runs on its caller (OpenMP runs a
 * team of one on the calling thread), so on this clock its time limit counts its own work only:
 * the time the machine gives other processes does not count. */
static inline double rt_thread_cpu_seconds(void *user)
{
    (void)user;
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* ---- Child processes that the tests signal (test_cli.c, test_compare.c) ---------------- */

/* A child started by spawn_until: its pid and the files its stderr and stdout go to. */
typedef struct {
    pid_t pid;
    int efd, ofd;
    char path[256], opath[256];
} child;

/* The child's stderr so far, into errbuf. */
static inline void child_stderr(const child *c, char *errbuf, size_t errlen)
{
    ssize_t n = pread(c->efd, errbuf, errlen - 1, 0);
    errbuf[n > 0 ? n : 0] = 0;
}

/* Start argv with stderr in a file and wait until that file contains `marker` (the event the
 * caller waits for). Fails the test if the child ends or 60 s pass without the marker (a safety
 * net, not the synchronisation). */
static inline child spawn_until(char *const argv[], const char *marker, char *errbuf, size_t errlen)
{
    child c;
    snprintf(c.path, sizeof c.path, "%s/sig.XXXXXX", rt_tmpdir());
    snprintf(c.opath, sizeof c.opath, "%s/sigo.XXXXXX", rt_tmpdir());
    c.efd = mkstemp(c.path);
    c.ofd = mkstemp(c.opath);
    cr_assert(c.efd >= 0 && c.ofd >= 0);
    c.pid = fork();
    cr_assert(c.pid >= 0);
    if (c.pid == 0) {
        dup2(c.efd, 2);
        dup2(c.ofd, 1);
        int nul = open("/dev/null", O_RDWR);
        dup2(nul, 0);
        execv(argv[0], argv);
        _exit(127);
    }
    struct timespec t0, now, nap = {0, 5 * 1000 * 1000};
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (;;) {
        child_stderr(&c, errbuf, errlen);
        if (strstr(errbuf, marker)) return c;
        int status;
        cr_assert(waitpid(c.pid, &status, WNOHANG) == 0, "the child ended before printing \"%s\": %s", marker, errbuf);
        clock_gettime(CLOCK_MONOTONIC, &now);
        cr_assert(now.tv_sec - t0.tv_sec <= 60, "the child never printed \"%s\": %s", marker, errbuf);
        nanosleep(&nap, NULL);
    }
}

/* Wait for the child to end; its exit status, or 1000 + signal when it died of one. Its stdout
 * goes to out when out != NULL. */
static inline int child_wait(child *c, char *errbuf, size_t errlen, char *out, size_t outlen)
{
    int status = 0;
    cr_assert(waitpid(c->pid, &status, 0) == c->pid);
    child_stderr(c, errbuf, errlen);
    if (out) {
        ssize_t n = pread(c->ofd, out, outlen - 1, 0);
        out[n > 0 ? n : 0] = 0;
    }
    close(c->efd), close(c->ofd);
    unlink(c->path), unlink(c->opath);
    return WIFSIGNALED(status) ? 1000 + WTERMSIG(status) : WEXITSTATUS(status);
}

/* Start argv, wait until its stderr contains `marker`, send `sig`; the exit status as child_wait. */
static inline int run_signal_on(char *const argv[], const char *marker, int sig, char *errbuf, size_t errlen,
                                char *out, size_t outlen)
{
    child c = spawn_until(argv, marker, errbuf, errlen);
    kill(c.pid, sig);
    return child_wait(&c, errbuf, errlen, out, outlen);
}

/* ---- Comparing two renders of one scene (tests of estimators against each other) ----------
 * z-scores of the image mean and of 8x8-pixel region means of luminance, with standard errors
 * from the films' per-pixel standard errors (pixels are independent). Under equal expectations
 * each z is standard normal; rt_expect_same bounds the image z by 5 and every region's by 4.5
 * (with at most a few dozen regions, a false alarm per comparison below 1e-4). */
typedef struct {
    double z_image, z_max;
    int regions;
} rt_cmp;

/* The luminance of b's image (the sum over its pixels). */
static inline double rt_image_light(const rd_render_result *b)
{
    double sum = 0.0;
    for (size_t i = 0; i < (size_t)b->image.w * b->image.h; i++)
        sum += v3_lum(v3(b->image.rgb[3 * i], b->image.rgb[3 * i + 1], b->image.rgb[3 * i + 2]));
    return sum;
}

/* z-scores between two renders of the same scene (luminance of 8x8 regions and the image), the
 * regions' only over those whose light in b is at least `lit` times an even share of b's light
 * (0: every region). */
static inline rt_cmp rt_compare_lit(const rd_render_result *a, const rd_render_result *b, double lit)
{
    rt_cmp c = {0, 0, 0};
    int w = a->image.w, h = a->image.h;
    double img[2] = {0, 0}, img_v[2] = {0, 0};
    const double even = rt_image_light(b) / (double)(((w + 7) / 8) * ((h + 7) / 8));
    for (int ry = 0; ry < h; ry += 8)
        for (int rx = 0; rx < w; rx += 8) {
            double m[2] = {0, 0}, v[2] = {0, 0};
            for (int y = ry; y < ry + 8 && y < h; y++)
                for (int x = rx; x < rx + 8 && x < w; x++)
                    for (int k = 0; k < 2; k++) {
                        const rd_render_result *r = k ? b : a;
                        const float *p = &r->image.rgb[3 * ((size_t)y * w + x)];
                        const float *e = &r->stderr_img.rgb[3 * ((size_t)y * w + x)];
                        m[k] += v3_lum(v3(p[0], p[1], p[2]));
                        /* channels taken as fully correlated (same paths): an upper bound */
                        double se = v3_lum(v3(e[0], e[1], e[2]));
                        v[k] += se * se;
                    }
            for (int k = 0; k < 2; k++) {
                img[k] += m[k];
                img_v[k] += v[k];
            }
            if (v[0] + v[1] <= 0.0 || m[1] < lit * even) continue;
            double z = (m[0] - m[1]) / sqrt(v[0] + v[1]);
            if (fabs(z) > fabs(c.z_max)) c.z_max = z;
            c.regions++;
        }
    c.z_image = (img[0] - img[1]) / sqrt(img_v[0] + img_v[1]);
    return c;
}

/* rt_compare_lit over every region. */
static inline rt_cmp rt_compare_images(const rd_render_result *a, const rd_render_result *b)
{
    return rt_compare_lit(a, b, 0.0);
}

/* Mean over the pixels of the luminance's squared standard error: the image's variance. */
static inline double rt_mean_pixel_var(const rd_render_result *r)
{
    double v = 0.0;
    size_t n = (size_t)r->image.w * r->image.h;
    for (size_t i = 0; i < n; i++) {
        const float *e = &r->stderr_img.rgb[3 * i];
        double se = v3_lum(v3(e[0], e[1], e[2]));
        v += se * se;
    }
    return v / (double)n;
}

static inline rd_render_result rt_render(const rd_scene *s, const char *method, int spp, uint64_t seed,
                               const rd_baked *baked)
{
    rd_render_opts o = {.method = method, .spp = spp, .seed = seed, .threads = 2, .baked = baked};
    rd_render_result r;
    char err[RD_ERRLEN];
    cr_assert(rd_render(s, &o, &r, err, sizeof err) == RD_OK, "%s: %s", method, err);
    for (size_t i = 0; i < (size_t)r.image.w * r.image.h * 3; i++)
        cr_assert(isfinite(r.image.rgb[i]), "%s: non-finite pixel", method);
    return r;
}

static inline void rt_expect_same(const rd_render_result *a, const rd_render_result *b, const char *what)
{
    rt_cmp c = rt_compare_images(a, b);
    cr_assert(c.regions >= 4, "%s: too few lit regions (%d)", what, c.regions);
    cr_expect(fabs(c.z_image) < 5.0, "%s: image means differ, z = %.2f", what, c.z_image);
    cr_expect(fabs(c.z_max) < 4.5, "%s: a region differs, z = %.2f (of %d)", what, c.z_max, c.regions);
    cr_log_info("%s: z image %.2f, worst region %.2f of %d", what, c.z_image, c.z_max, c.regions);
}

#endif
