/* media.c: one entry of the scene's "media": its bounds, its density (constant, a VDB or raw
 * voxel file, or procedural noise), sigma_t, albedo and g, and its majorant structure, built
 * here once the density is known (rd_freepath.h; seed 000's cost model). */
#include "load/rd_load.h"
#include "media/rd_freepath.h"

#include <cJSON.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

/* ---- media --------------------------------------------------------------------------------- */
static rd_status parse_bounds(ld_ctx *c, const cJSON *m, const char *path, int required, rd_medium *med,
                              int *present)
{
    char p[300];
    ld_join(p, sizeof p, path, "bounds");
    const cJSON *b = cJSON_GetObjectItemCaseSensitive(m, "bounds");
    *present = b != NULL;
    if (!b) {
        if (required) return ld_fail(c, p, "missing (required: {\"min\": [x,y,z], \"max\": [x,y,z]})");
        return RD_OK;
    }
    LD_TRY(ld_need_object(c, b, p));
    static const char *const keys[] = {"min", "max", NULL};
    LD_TRY(ld_check_keys(c, b, p, keys));
    LD_TRY(ld_get_vec3(c, b, p, "min", 1, v3(0, 0, 0), 0, -1e9, 1e9, &med->bmin));
    LD_TRY(ld_get_vec3(c, b, p, "max", 1, v3(0, 0, 0), 0, -1e9, 1e9, &med->bmax));
    if (!(med->bmin.x < med->bmax.x && med->bmin.y < med->bmax.y && med->bmin.z < med->bmax.z))
        return ld_fail(c, p, "min must be smaller than max on every axis");
    return RD_OK;
}


static rd_status parse_density(ld_ctx *c, const cJSON *m, const char *mpath, rd_medium *med,
                               int has_bounds)
{
    char path[300];
    ld_join(path, sizeof path, mpath, "density");
    const cJSON *d = cJSON_GetObjectItemCaseSensitive(m, "density");
    if (!d) return ld_fail(c, path, "missing (required)");
    if (cJSON_IsNumber(d)) { /* shorthand: "density": 0.5 */
        if (!isfinite(d->valuedouble) || d->valuedouble < 0)
            return ld_fail(c, path, "must be a finite number >= 0");
        med->kind = RD_DENSITY_CONSTANT;
        med->constant = d->valuedouble;
        if (!has_bounds) return ld_fail(c, mpath[0] ? mpath : "media", "bounds: missing (required)");
        return RD_OK;
    }
    LD_TRY(ld_need_object(c, d, path));
    static const char *const kinds[] = {"constant", "vdb", "raw", "noise", NULL};
    int kind;
    LD_TRY(ld_get_enum(c, d, path, "type", 1, kinds, 0, &kind));
    if (kind != 1 && !has_bounds && kind != 3) {
        char p[300];
        ld_join(p, sizeof p, mpath, "bounds");
        return ld_fail(c, p, "missing (required for a %s density)", kinds[kind]);
    }
    char full[2048];
    if (kind == 0) {
        static const char *const keys[] = {"type", "value", NULL};
        LD_TRY(ld_check_keys(c, d, path, keys));
        med->kind = RD_DENSITY_CONSTANT;
        LD_TRY(ld_get_num(c, d, path, "value", 1, 0, 0, 0, 1e12, 0, &med->constant));
    } else if (kind == 1) {
        static const char *const keys[] = {"type", "file", "grid", "made_by", NULL};
        LD_TRY(ld_check_keys(c, d, path, keys));
        if (has_bounds) {
            char p[300];
            ld_join(p, sizeof p, mpath, "bounds");
            return ld_fail(c, p, "not allowed with a vdb density (the bounds come from the grid and its transform)");
        }
        const char *file, *grid, *made_by;
        LD_TRY(ld_get_str(c, d, path, "file", 1, NULL, &file));
        LD_TRY(ld_get_str(c, d, path, "grid", 0, "density", &grid));
        LD_TRY(ld_get_str(c, d, path, "made_by", 0, NULL, &made_by));
        ld_resolve_path(c, file, full, sizeof full);
        med->kind = RD_DENSITY_GRID;
        char msg[RD_ERRLEN];
        rd_status st = rd_vdb_load(full, grid, &med->grid, &med->bmin, &med->bmax, msg, sizeof msg);
        if (st) {
            char p[300];
            ld_join(p, sizeof p, path, "file");
            char hint[300];
            ld_fail(c, p, "%s%s", msg, ld_missing_hint(full, made_by, hint, sizeof hint));
            return st;
        }
    } else if (kind == 2) {
        static const char *const keys[] = {"type", "file", "dims", "made_by", NULL};
        LD_TRY(ld_check_keys(c, d, path, keys));
        const char *file, *made_by;
        LD_TRY(ld_get_str(c, d, path, "file", 1, NULL, &file));
        LD_TRY(ld_get_str(c, d, path, "made_by", 0, NULL, &made_by));
        char p[300];
        ld_join(p, sizeof p, path, "dims");
        const cJSON *dims = cJSON_GetObjectItemCaseSensitive(d, "dims");
        if (!dims) return ld_fail(c, p, "missing (required: [nx, ny, nz])");
        int n[3];
        if (!cJSON_IsArray(dims) || cJSON_GetArraySize(dims) != 3)
            return ld_fail(c, p, "expected 3 integers in [1, 4096]");
        for (int i = 0; i < 3; i++) {
            const cJSON *e = cJSON_GetArrayItem(dims, i);
            if (!cJSON_IsNumber(e) || e->valuedouble != floor(e->valuedouble) || e->valuedouble < 1 ||
                e->valuedouble > 4096)
                return ld_fail(c, p, "expected 3 integers in [1, 4096]");
            n[i] = e->valueint;
        }
        ld_resolve_path(c, file, full, sizeof full);
        med->kind = RD_DENSITY_GRID;
        char msg[RD_ERRLEN];
        rd_status st = rd_raw_load(full, n[0], n[1], n[2], &med->grid, msg, sizeof msg);
        if (st) {
            ld_join(p, sizeof p, path, "file");
            char hint[300];
            ld_fail(c, p, "%s%s", msg, ld_missing_hint(full, made_by, hint, sizeof hint));
            return st;
        }
        /* The voxels fill the medium bounds: u = n (x - bmin) / (bmax - bmin). */
        memset(med->grid.w2g, 0, sizeof med->grid.w2g);
        for (int a = 0; a < 3; a++) {
            double lo = v3_get(med->bmin, a), hi = v3_get(med->bmax, a);
            med->grid.w2g[a][a] = n[a] / (hi - lo);
            med->grid.w2g[a][3] = -lo * n[a] / (hi - lo);
        }
    } else {
        static const char *const keys[] = {"type", "octaves", "frequency", "gain", "lacunarity",
                                           "amplitude", "seed", "shape", "edge", NULL};
        LD_TRY(ld_check_keys(c, d, path, keys));
        rd_noise *nz = &med->noise;
        long long oct, seed;
        LD_TRY(ld_get_int(c, d, path, "octaves", 0, 5, 1, 16, &oct));
        LD_TRY(ld_get_num(c, d, path, "frequency", 0, 2.0, 0, 1, 1e6, 0, &nz->frequency));
        LD_TRY(ld_get_num(c, d, path, "gain", 0, 0.5, 0, 0, 1, 0, &nz->gain));
        LD_TRY(ld_get_num(c, d, path, "lacunarity", 0, 2.0, 1, 0, 8, 0, &nz->lacunarity));
        LD_TRY(ld_get_num(c, d, path, "amplitude", 0, 1.0, 0, 0, 100, 0, &nz->amplitude));
        LD_TRY(ld_get_int(c, d, path, "seed", 0, 1, 0, UINT32_MAX, &seed));
        LD_TRY(ld_get_num(c, d, path, "edge", 0, 0.4, 0, 1, 1, 0, &nz->edge));
        static const char *const shapes[] = {"none", "ellipsoid", NULL};
        int shape;
        LD_TRY(ld_get_enum(c, d, path, "shape", 0, shapes, 1, &shape));
        nz->octaves = (int)oct;
        nz->seed = (uint32_t)seed;
        /* The finest octave must stay a sane number of lattice cells per unit (its lattice
         * coordinates are converted to integers). */
        double finest = nz->frequency * pow(nz->lacunarity, nz->octaves - 1);
        if (!(finest <= 1e6))
            return ld_fail(c, path, "the finest octave's frequency, frequency x lacunarity^(octaves-1) = %.3g, exceeds 1e6", finest);
        nz->shape = shape == 0 ? RD_SHAPE_NONE : RD_SHAPE_ELLIPSOID;
        if (!has_bounds) {
            char p[300];
            ld_join(p, sizeof p, mpath, "bounds");
            return ld_fail(c, p, "missing (required: the noise fills, and its ellipsoid is inscribed in, the bounds)");
        }
        nz->center = v3_scale(v3_add(med->bmin, med->bmax), 0.5);
        nz->radii = v3_scale(v3_sub(med->bmax, med->bmin), 0.5);
        rd_noise_init_perm(nz);
        med->kind = RD_DENSITY_NOISE;
    }
    return RD_OK;
}

rd_status ld_parse_medium(ld_ctx *c, const cJSON *m, int idx, rd_medium *med, rd_majorant_opts *mo_out)
{
    char path[64];
    snprintf(path, sizeof path, "media[%d]", idx);
    LD_TRY(ld_need_object(c, m, path));
    static const char *const keys[] = {"name", "bounds", "density", "sigma_t", "albedo", "g", "majorant", NULL};
    LD_TRY(ld_check_keys(c, m, path, keys));
    const char *name;
    char defname[32];
    snprintf(defname, sizeof defname, "medium%d", idx);
    LD_TRY(ld_get_str(c, m, path, "name", 0, defname, &name));
    snprintf(med->name, sizeof med->name, "%s", name);
    int has_bounds;
    LD_TRY(parse_bounds(c, m, path, 0, med, &has_bounds));
    LD_TRY(parse_density(c, m, path, med, has_bounds));
    LD_TRY(ld_get_num(c, m, path, "sigma_t", 1, 1.0, 0, 0, 1e9, 0, &med->sigma_t_scale));
    LD_TRY(ld_get_vec3(c, m, path, "albedo", 0, v3(1, 1, 1), 1, 0, 1, &med->albedo));
    LD_TRY(ld_get_num(c, m, path, "g", 0, 0.0, -1, 1, 1, 1, &med->g));
    switch (med->kind) {
    case RD_DENSITY_CONSTANT: med->density_max = med->constant; break;
    case RD_DENSITY_GRID: med->density_max = fmax(0.0, med->grid.vmax); break;
    case RD_DENSITY_NOISE: /* shape <= 1, so density <= 1 + amplitude * bound(|fbm|) */
        med->density_max = 1.0 + med->noise.amplitude * rd_noise_fbm_bound(&med->noise);
        break;
    }
    med->sigma_maj = med->density_max * med->sigma_t_scale;
    med->density_min = med->kind == RD_DENSITY_CONSTANT ? med->constant : 0.0;
    /* A medium so thick that one ray needs more than ~1e7 tentative collisions would make a
     * render that never finishes: refuse it (before building anything for it) rather than hang. */
    double tau = med->sigma_maj * v3_len(v3_sub(med->bmax, med->bmin));
    if (!(tau <= 1e7)) {
        char p[300];
        ld_join(p, sizeof p, path, "sigma_t");
        return ld_fail(c, p, "majorant optical depth across the bounds is %.3g, more than 1e7: the medium is too thick to render (lower sigma_t or the density)", tau);
    }

    /* Majorant structure (rd_freepath.h): {"type": "auto"|"none"|"grid"|"octree",
     * "resolution": N (grid), "bound": "constant"|"trilinear" (grid), "fail": F (octree)}. */
    rd_majorant_opts mo = {RD_MAJ_AUTO, 0, RD_BOUND_CONSTANT, 2, 0, 0.0};
    const cJSON *mj = cJSON_GetObjectItemCaseSensitive(m, "majorant");
    char mpath[300];
    ld_join(mpath, sizeof mpath, path, "majorant");
    if (mj) {
        LD_TRY(ld_need_object(c, mj, mpath));
        static const char *const mkeys[] = {"type", "resolution", "bound", "fail", "max_level", "rewind_cost", NULL};
        LD_TRY(ld_check_keys(c, mj, mpath, mkeys));
        static const char *const mtypes[] = {"auto", "none", "grid", "octree", NULL};
        static const char *const bounds[] = {"constant", "trilinear", NULL};
        int type, bound;
        long long v;
        LD_TRY(ld_get_enum(c, mj, mpath, "type", 0, mtypes, 0, &type));
        mo.kind = (rd_maj_kind)type;
        LD_TRY(ld_get_enum(c, mj, mpath, "bound", 0, bounds, 0, &bound));
        mo.bound = (rd_bound_kind)bound;
        /* 256^3 super-voxels (16.7 M cells, 128 MiB of bounds) is past any gain (seed 003:
         * 16^3 is best for 512^3 data); larger grids would only cost memory and build time. */
        LD_TRY(ld_get_int(c, mj, mpath, "resolution", 0, 0, 1, 256, &v));
        mo.resolution = (int)v;
        LD_TRY(ld_get_int(c, mj, mpath, "fail", 0, 2, 0, 8, &v));
        mo.fail_limit = (int)v;
        LD_TRY(ld_get_int(c, mj, mpath, "max_level", 0, 0, 1, 8, &v));
        mo.max_level = (int)v;
        LD_TRY(ld_get_num(c, mj, mpath, "rewind_cost", 0, 0.0, 0, 1, 10, 0, &mo.rewind_cost));
        char p[300];
        if (cJSON_GetObjectItemCaseSensitive(mj, "resolution") && mo.kind != RD_MAJ_GRID) {
            ld_join(p, sizeof p, mpath, "resolution");
            return ld_fail(c, p, "only with \"type\": \"grid\"");
        }
        if (cJSON_GetObjectItemCaseSensitive(mj, "fail") && mo.kind != RD_MAJ_OCTREE) {
            ld_join(p, sizeof p, mpath, "fail");
            return ld_fail(c, p, "only with \"type\": \"octree\"");
        }
        if (mo.bound == RD_BOUND_TRILINEAR && mo.kind != RD_MAJ_GRID && mo.kind != RD_MAJ_AUTO) {
            ld_join(p, sizeof p, mpath, "bound");
            return ld_fail(c, p, "\"trilinear\" needs \"type\": \"grid\" or \"auto\"");
        }
    }
    /* Seed 000 eq. 15: a rewind (one DDA step) against an iteration, which costs a density
     * lookup: a trilinear fetch for grids, one Perlin evaluation per octave for noise. The
     * ratios 0.1 (grids) and 0.8 / octaves (noise) were calibrated by bench_freepath
     * --calibrate on media that are not in its benchmark (docs/benchmarks.md), so the
     * benchmark that judges them did not choose them. Fixed per density kind, so the structure,
     * and the image, never depend on timing. */
    if (mo.rewind_cost == 0.0)
        mo.rewind_cost = med->kind == RD_DENSITY_GRID ? 0.1 : med->kind == RD_DENSITY_NOISE ? 0.8 / med->noise.octaves : 1.0;
    /* A constant medium gains nothing from a partition (eq. 14 >= eq. 17): skip the levels. */
    if (mo.kind == RD_MAJ_AUTO && med->kind == RD_DENSITY_CONSTANT) mo.kind = RD_MAJ_NONE;
    if (mo.max_level == 0) {
        /* Finest level of the cost-model search: no finer than the voxels, at most 128 cells
         * per axis for grids and 64 for procedural noise (bounding cost grows with the cells). */
        int lim = med->kind == RD_DENSITY_NOISE ? 64 : 128;
        if (med->kind == RD_DENSITY_GRID) {
            int nmax = med->grid.nx > med->grid.ny ? med->grid.nx : med->grid.ny;
            if (med->grid.nz > nmax) nmax = med->grid.nz;
            if (nmax < lim) lim = nmax;
        }
        mo.max_level = 1;
        while ((2 << mo.max_level) <= lim && mo.max_level < 8) mo.max_level++;
    }
    *mo_out = mo;
    return RD_OK;
}

rd_status ld_build_majorant(ld_ctx *c, int idx, rd_medium *med, const rd_majorant_opts *mo)
{
    char mpath[64], msg[RD_ERRLEN];
    snprintf(mpath, sizeof mpath, "media[%d].majorant", idx);
    med->majorant = rd_majorant_build(med->bmin, med->bmax, med->sigma_t_scale, med->sigma_maj,
                                      rd_medium_box_bound, med, mo, msg, sizeof msg);
    if (!med->majorant) {
        ld_fail(c, mpath, "%s", msg);
        return RD_ERR_NOMEM;
    }
    if (med->kind != RD_DENSITY_CONSTANT) med->density_min = med->majorant->dmin_root;
    /* The oracle's bound over the whole box can be tighter than the global formula (noise). */
    if (med->majorant->dmax_root < med->density_max && med->kind == RD_DENSITY_NOISE) {
        med->density_max = med->majorant->dmax_root * (1.0 + 1e-6);
        med->sigma_maj = med->density_max * med->sigma_t_scale;
    }
    return RD_OK;
}
