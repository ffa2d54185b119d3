/* pm-inspect: dump a photon map (.pmap) or a slice of an SH guide grid (.guide) as CSV, for
 * plotting (scripts/make-how-it-works.sh, docs/how-it-works.md). Reads the files through the
 * project's public headers only (photonmap.h, sh.h).
 *
 *   pm-inspect photons MAP.pmap [--every N]
 *       one line per stored photon: x,y,z (world, m), dx,dy,dz (propagation direction w'),
 *       r,g,b (scattered power dPhi, W; photonmap.h), every N-th photon only with --every.
 *   pm-inspect slice GUIDE.guide --axis x|y|z [--at C] [--res W,H] VALUE
 *       the plane x[axis] = C (default: the middle of the guide's box) on a W x H raster
 *       (default 200 x 150) of pixel centres spanning the box, one line per pixel: u,v,value,
 *       a blank line after each row (gnuplot's grid format; u, v the in-plane axes of
 *       sh_guide_slice: x -> (y,z), y -> (x,z), z -> (x,y)). VALUE is one of
 *         --dc            sqrt(4 pi) c_00 averaged over R, G, B: the integral of f(w) over the
 *                         sphere, the photon density estimate sigma_s * fluence [W m^-3]
 *                         (sh.h: f(w) = sum c_lm Y_lm(w), Y_00 = 1 / (2 sqrt(pi)))
 *         --eye X,Y,Z     the guide value sh_eval_guide toward that point (the camera): at x
 *                         the direction w = (eye - x) / |eye - x|, the radiance leaving x
 *                         toward the eye, sigma_s L_s(x, w) [W m^-3 sr^-1]; the histogram
 *                         height a camera ray reads (seed 001 eq. 16)
 *         --toward X,Y,Z  the same toward one fixed direction w
 *       Points outside the box, or in a cell with no photon, give 0.
 *   pm-inspect info FILE
 *       counts, bounds and grid resolution, one "key value" per line.
 *
 * Exit status: 0 done, 1 a file could not be read (the library's message), 2 bad usage. */
#include "photonmap.h"
#include "sh.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { ERRLEN = 512 };
static const double PI = 3.14159265358979323846;

static int usage(void)
{
    fputs("usage: pm-inspect photons MAP.pmap [--every N]\n"
          "       pm-inspect slice GUIDE.guide --axis x|y|z [--at C] [--res W,H]"
          " (--dc | --eye X,Y,Z | --toward X,Y,Z)\n"
          "       pm-inspect info MAP.pmap|GUIDE.guide\n",
          stderr);
    return 2;
}

/* Parse "a,b,c" (n numbers) into v; 1 on success. */
static int parse_vec(const char *s, double *v, int n)
{
    char *end;
    for (int i = 0; i < n; i++) {
        v[i] = strtod(s, &end);
        if (end == s || !isfinite(v[i])) return 0;
        if (i < n - 1) {
            if (*end != ',') return 0;
            s = end + 1;
        }
    }
    return *end == '\0';
}

static int has_suffix(const char *s, const char *suffix)
{
    size_t n = strlen(s), m = strlen(suffix);
    return n >= m && strcmp(s + n - m, suffix) == 0;
}

/* ---- photons ------------------------------------------------------------------------------ */

static int dump_photons(const char *path, long every)
{
    char err[ERRLEN];
    pm_map *map = NULL;
    if (pm_map_load(&map, path, err, sizeof err) != PM_OK) {
        fprintf(stderr, "pm-inspect: %s\n", err);
        return 1;
    }
    double o[3];
    pm_map_origin(map, o);
    const pm_photon *ph = pm_map_photons(map);
    size_t n = pm_map_photon_count(map);
    printf("# %s: %zu photons (one in %ld below); world position = origin + pos\n", path, n,
           every);
    puts("x,y,z,dx,dy,dz,r,g,b");
    for (size_t i = 0; i < n; i += (size_t)every) {
        const pm_photon *p = &ph[i];
        printf("%.6g,%.6g,%.6g,%.5g,%.5g,%.5g,%.6g,%.6g,%.6g\n", o[0] + p->pos[0],
               o[1] + p->pos[1], o[2] + p->pos[2], p->dir[0], p->dir[1], p->dir[2],
               p->power[0], p->power[1], p->power[2]);
    }
    pm_map_free(map);
    return 0;
}

/* ---- guide slices ------------------------------------------------------------------------- */

typedef enum { VALUE_DC, VALUE_EYE, VALUE_TOWARD } slice_value;

typedef struct {
    int axis;          /* 0, 1, 2: the plane x[axis] = at */
    double at;         /* NAN: the middle of the box */
    int width, height; /* raster */
    slice_value value;
    double vec[3];     /* the eye point or the direction */
} slice_opts;

/* The value of one point of the slice (see the header comment). */
static double slice_value_at(const sh_guide *g, const slice_opts *so, const double x[3])
{
    long cell = sh_guide_locate(g, x);
    if (cell < 0) return 0.0;
    const float *c = sh_guide_cell_coeffs(g, (size_t)cell);
    const int bands = sh_guide_bands(g);
    if (so->value == VALUE_DC) {
        /* integral over the sphere of f = sum c_lm Y_lm is 4 pi c_00 Y_00 = sqrt(4 pi) c_00 */
        const size_t stride = (size_t)bands * (size_t)bands;
        double sum = c[0] + c[stride] + c[2 * stride];
        return sqrt(4.0 * PI) * sum / 3.0;
    }
    double w[3];
    for (int i = 0; i < 3; i++) w[i] = so->value == VALUE_EYE ? so->vec[i] - x[i] : so->vec[i];
    float y[SH_MAX_COEFFS];
    sh_basis_evalf(sh_guide_basis(g), w, y); /* normalises w */
    return sh_eval_guide(bands, c, y);
}

static int dump_slice(const char *path, const slice_opts *so)
{
    char err[ERRLEN];
    sh_guide *g = NULL;
    if (sh_guide_load(&g, path, err, sizeof err) != SH_OK) {
        fprintf(stderr, "pm-inspect: %s\n", err);
        return 1;
    }
    double lo[3], hi[3];
    sh_guide_box(g, lo, hi);
    /* in-plane axes as sh_guide_slice: x -> (y, z), y -> (x, z), z -> (x, y) */
    const int ua = so->axis == 0 ? 1 : 0, va = so->axis == 2 ? 1 : 2;
    const double at = isnan(so->at) ? 0.5 * (lo[so->axis] + hi[so->axis]) : so->at;
    static const char *names = "xyz";
    printf("# %s: plane %c = %g of the box [%g,%g]x[%g,%g]x[%g,%g], %d bands, %zu cells\n",
           path, names[so->axis], at, lo[0], hi[0], lo[1], hi[1], lo[2], hi[2],
           sh_guide_bands(g), sh_guide_cell_count(g));
    printf("%c,%c,value\n", names[ua], names[va]);
    for (int j = 0; j < so->height; j++) {
        for (int i = 0; i < so->width; i++) {
            double x[3];
            x[so->axis] = at;
            x[ua] = lo[ua] + (i + 0.5) / so->width * (hi[ua] - lo[ua]);
            x[va] = lo[va] + (j + 0.5) / so->height * (hi[va] - lo[va]);
            printf("%.6g,%.6g,%.6g\n", x[ua], x[va], slice_value_at(g, so, x));
        }
        putchar('\n'); /* gnuplot: end of a scan line */
    }
    sh_guide_free(g);
    return 0;
}

/* ---- info --------------------------------------------------------------------------------- */

static int info(const char *path)
{
    char err[ERRLEN];
    if (has_suffix(path, ".pmap")) {
        pm_map *map = NULL;
        if (pm_map_load(&map, path, err, sizeof err) != PM_OK) {
            fprintf(stderr, "pm-inspect: %s\n", err);
            return 1;
        }
        float lo[3], hi[3];
        pm_map_bounds(map, lo, hi);
        printf("photons %zu\nsegments %zu\nlo %g %g %g\nhi %g %g %g\n",
               pm_map_photon_count(map), pm_map_segment_count(map), lo[0], lo[1], lo[2], hi[0],
               hi[1], hi[2]);
        pm_map_free(map);
        return 0;
    }
    sh_guide *g = NULL;
    if (sh_guide_load(&g, path, err, sizeof err) != SH_OK) {
        fprintf(stderr, "pm-inspect: %s\n", err);
        return 1;
    }
    sh_guide_stats st;
    sh_guide_stats_get(g, &st);
    double lo[3], hi[3];
    sh_guide_box(g, lo, hi);
    printf("kind %s\nbands %d\ncells %zu\nres %d %d %d\nlo %g %g %g\nhi %g %g %g\n",
           st.kind == SH_GRID_UNIFORM ? "uniform" : "adaptive", st.bands, st.cells, st.res[0],
           st.res[1], st.res[2], lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
    sh_guide_free(g);
    return 0;
}

/* ---- command line ------------------------------------------------------------------------- */

static int parse_slice(int argc, char **argv, slice_opts *so)
{
    *so = (slice_opts){.axis = -1, .at = NAN, .width = 200, .height = 150, .value = -1};
    for (int i = 3; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        double r[2];
        if (strcmp(a, "--dc") == 0) {
            so->value = VALUE_DC;
            continue;
        }
        if (!v) return 0;
        i++;
        if (strcmp(a, "--axis") == 0 && strlen(v) == 1 && strchr("xyz", v[0]))
            so->axis = v[0] - 'x';
        else if (strcmp(a, "--at") == 0 && parse_vec(v, &so->at, 1))
            ;
        else if (strcmp(a, "--res") == 0 && parse_vec(v, r, 2) && r[0] >= 1 && r[1] >= 1 &&
                 r[0] <= 4096 && r[1] <= 4096)
            so->width = (int)r[0], so->height = (int)r[1];
        else if (strcmp(a, "--eye") == 0 && parse_vec(v, so->vec, 3))
            so->value = VALUE_EYE;
        else if (strcmp(a, "--toward") == 0 && parse_vec(v, so->vec, 3))
            so->value = VALUE_TOWARD;
        else
            return 0;
    }
    return so->axis >= 0 && (int)so->value >= 0;
}

int main(int argc, char **argv)
{
    if (argc < 3) return usage();
    if (strcmp(argv[1], "photons") == 0) {
        long every = 1;
        char *end = NULL;
        if (argc == 5 && strcmp(argv[3], "--every") == 0) every = strtol(argv[4], &end, 10);
        else if (argc != 3) return usage();
        if (every < 1 || (end && *end)) return usage();
        return dump_photons(argv[2], every);
    }
    if (strcmp(argv[1], "slice") == 0) {
        slice_opts so;
        if (!parse_slice(argc, argv, &so)) return usage();
        return dump_slice(argv[2], &so);
    }
    if (strcmp(argv[1], "info") == 0 && argc == 3) return info(argv[2]);
    return usage();
}
