/* harness.c: the loaders as fuzz targets (harness.h). */
#define _DEFAULT_SOURCE /* mkstemps */
#include "harness.h"

#include "photonmap.h"
#include "core/rd_core.h"
#include "transport/rd_path.h"
#include "sh.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Write `n` bytes to a fresh file $TMPDIR/pmfuzz-XXXXXX<suffix>; its path in `path`. 0 on
 * failure (then the input is skipped). */
static int temp_file(const void *data, size_t n, const char *suffix, char *path, size_t len)
{
    const char *dir = getenv("TMPDIR");
    snprintf(path, len, "%s/pmfuzz-XXXXXX%s", dir && dir[0] ? dir : "/tmp", suffix);
    int fd = mkstemps(path, (int)strlen(suffix));
    if (fd < 0) return 0;
    const char *p = data;
    size_t left = n;
    while (left > 0) {
        ssize_t w = write(fd, p, left);
        if (w <= 0) break;
        p += w;
        left -= (size_t)w;
    }
    close(fd);
    if (left) unlink(path);
    return left == 0;
}

/* FNV-1a 64 (Fowler, Noll, Vo), the checksum ending .pmap and .guide files. */
static uint64_t fnv1a(const uint8_t *p, size_t n)
{
    uint64_t h = 0xcbf29ce484222325ull;
    for (size_t i = 0; i < n; i++) {
        h ^= p[i];
        h *= 0x100000001b3ull;
    }
    return h;
}

/* A copy of the input with its last 8 bytes set to the little-endian checksum of the others. */
static uint8_t *with_checksum(const uint8_t *data, size_t n)
{
    uint8_t *c = malloc(n ? n : 1);
    if (!c) return NULL;
    memcpy(c, data, n);
    if (n >= 8) {
        uint64_t h = fnv1a(c, n - 8);
        for (int i = 0; i < 8; i++) c[n - 8 + i] = (uint8_t)(h >> (8 * i));
    }
    return c;
}

int fz_scene(const uint8_t *data, size_t n)
{
    /* Split at NUL: scene, then overrides. */
    char *buf = malloc(n + 1);
    if (!buf) return 0;
    memcpy(buf, data, n);
    buf[n] = 0;
    rd_override ov[8];
    int nov = 0;
    size_t scene_len = strlen(buf);
    for (size_t at = scene_len + 1; at < n && nov < 8;) {
        char *part = buf + at;
        at += strlen(part) + 1;
        char *eq = strchr(part, '=');
        if (!eq || eq == part) continue;
        *eq = 0;
        ov[nov].key = part;
        ov[nov].value = eq + 1;
        nov++;
    }
    char path[512];
    if (temp_file(buf, scene_len, ".json", path, sizeof path)) {
        char err[RD_ERRLEN];
        rd_scene *s = NULL;
        if (rd_scene_load(&s, path, ov, nov, err, sizeof err) == RD_OK) {
            FILE *null = fopen("/dev/null", "w");
            if (null) {
                rd_scene_info(s, null);
                fclose(null);
            }
            rd_scene_free(s);
        }
        unlink(path);
    }
    free(buf);
    return 0;
}

int fz_pmap(const uint8_t *data, size_t n)
{
    uint8_t *c = with_checksum(data, n);
    char path[512];
    if (c && temp_file(c, n, ".pmap", path, sizeof path)) {
        char err[256];
        pm_map *m = NULL;
        if (pm_map_load(&m, path, err, sizeof err) == PM_OK) {
            /* Build the index and query it at the centre of the photons' bounds. */
            if (pm_map_build(m, err, sizeof err) == PM_OK && pm_map_photon_count(m) > 0) {
                float lo[3], hi[3], dens[3];
                pm_map_bounds(m, lo, hi);
                double x[3] = {0.5 * ((double)lo[0] + hi[0]), 0.5 * ((double)lo[1] + hi[1]),
                               0.5 * ((double)lo[2] + hi[2])};
                pm_map_density(m, x, 8, dens);
            }
            pm_map_free(m);
        }
        unlink(path);
    }
    free(c);
    return 0;
}

int fz_guide(const uint8_t *data, size_t n)
{
    uint8_t *c = with_checksum(data, n);
    char path[512];
    if (c && temp_file(c, n, ".guide", path, sizeof path)) {
        char err[256];
        sh_guide *g = NULL;
        if (sh_guide_load(&g, path, err, sizeof err) == SH_OK) {
            /* Evaluate at the box centre and walk one ray through the grid. */
            double lo[3], hi[3], w[3] = {0.0, 0.0, 1.0}, o[3], d[3] = {0.48, 0.6, 0.64};
            float out[3];
            sh_guide_box(g, lo, hi);
            for (int k = 0; k < 3; k++) {
                o[k] = lo[k] - 1.0;
                lo[k] = 0.5 * (lo[k] + hi[k]);
            }
            sh_guide_eval(g, lo, w, out);
            sh_guide_ray it;
            sh_guide_seg seg;
            sh_guide_ray_begin(g, o, d, 0.0, 1e30, &it);
            for (int steps = 0; steps < 100000 && sh_guide_ray_next(&it, &seg); steps++) {}
            sh_guide_free(g);
        }
        unlink(path);
    }
    free(c);
    return 0;
}

int fz_raw(const uint8_t *data, size_t n)
{
    if (n < 3) return 0;
    int dims[3] = {1 + data[0] % 16, 1 + data[1] % 16, 1 + data[2] % 16};
    char path[512];
    if (temp_file(data + 3, n - 3, ".raw", path, sizeof path)) {
        char err[RD_ERRLEN];
        rd_grid g = {0};
        if (rd_raw_load(path, dims[0], dims[1], dims[2], &g, err, sizeof err) == RD_OK) free(g.data);
        unlink(path);
    }
    return 0;
}

int fz_vdb(const uint8_t *data, size_t n)
{
    char path[512];
    if (temp_file(data, n, ".vdb", path, sizeof path)) {
        char err[RD_ERRLEN];
        rd_grid g = {0};
        vec3 lo, hi;
        if (rd_vdb_load(path, "density", &g, &lo, &hi, err, sizeof err) == RD_OK) rd_grid_free(&g); /* dense or sparse */
        unlink(path);
    }
    return 0;
}

int fz_image(const uint8_t *data, size_t n)
{
    if (n < 1) return 0;
    char path[512];
    if (temp_file(data + 1, n - 1, data[0] % 2 ? ".png" : ".exr", path, sizeof path)) {
        char err[RD_ERRLEN];
        rd_image img = {0};
        if (rd_image_read(path, &img, err, sizeof err) == RD_OK) {
            /* touch every pixel: a size the loader got wrong shows here under ASan */
            double sum = 0.0;
            for (size_t i = 0; i < (size_t)img.w * img.h * 3; i++) sum += img.rgb[i];
            (void)sum;
            rd_image_free_pixels(&img);
        }
        unlink(path);
    }
    return 0;
}
