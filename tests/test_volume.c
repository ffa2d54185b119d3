/* Volume data: OpenVDB grids are read with their transform honoured, broken .vdb files are
 * rejected with a message, and the procedural noise respects the bound its majorant uses. */
#include "support/rd_test.h"

Test(volume, vdb_roundtrip_honours_the_transform, .timeout = 60)
{
    /* 6x5x4 voxels, voxel size 0.25, voxel (0,0,0) centred at (1, 2, 3). */
    enum { NX = 6, NY = 5, NZ = 4 };
    float v[NX * NY * NZ];
    for (int i = 0; i < NX * NY * NZ; i++) v[i] = 0.1f * (float)(i % 17) + 0.05f;
    char path[256], err[RD_ERRLEN];
    snprintf(path, sizeof path, "%s/g.vdb", rt_tmpdir());
    const double origin[3] = {1, 2, 3};
    cr_assert(rd_vdb_save_dense(path, "density", v, NX, NY, NZ, 0.25, origin, err, sizeof err) == RD_OK, "%s", err);
    rd_scene *s = rt_scene("vdb.json",
                           "{\"camera\":{\"position\":[0,0,9],\"look_at\":[1,2,3],\"resolution\":[4,4]},"
                           "\"media\":[{\"density\":{\"type\":\"vdb\",\"file\":\"g.vdb\",\"grid\":\"density\"},\"sigma_t\":1}]}");
    const rd_medium *m = &s->media[0];
    cr_expect(m->grid.nx == NX && m->grid.ny == NY && m->grid.nz == NZ);
    /* World bounds: voxel centres from origin to origin + 0.25 (n-1), grown by one voxel. */
    cr_expect(fabs(m->bmin.x - 0.75) < 1e-9 && fabs(m->bmin.y - 1.75) < 1e-9 && fabs(m->bmin.z - 2.75) < 1e-9,
              "bmin (%g %g %g)", m->bmin.x, m->bmin.y, m->bmin.z);
    cr_expect(fabs(m->bmax.x - (1 + 0.25 * NX)) < 1e-9 && fabs(m->bmax.z - (3 + 0.25 * NZ)) < 1e-9,
              "bmax (%g %g %g)", m->bmax.x, m->bmax.y, m->bmax.z);
    /* At every voxel centre the density is that voxel's value. */
    for (int k = 0; k < NZ; k++)
        for (int j = 0; j < NY; j++)
            for (int i = 0; i < NX; i++) {
                double d = rd_medium_density(m, v3(1 + 0.25 * i, 2 + 0.25 * j, 3 + 0.25 * k));
                cr_expect(fabs(d - v[(k * NY + j) * NX + i]) < 1e-6, "voxel (%d %d %d): %g", i, j, k, d);
            }
    cr_expect(fabs(m->density_max - 0.1 * 16 - 0.05) < 1e-6);
    rd_scene_free(s);
}

Test(volume, truncated_and_wrong_vdb_files_are_rejected, .timeout = 60)
{
    float v[8] = {1, 1, 1, 1, 1, 1, 1, 1};
    char path[256], cut[256], err[RD_ERRLEN];
    snprintf(path, sizeof path, "%s/ok.vdb", rt_tmpdir());
    snprintf(cut, sizeof cut, "%s/cut.vdb", rt_tmpdir());
    const double origin[3] = {0, 0, 0};
    cr_assert(rd_vdb_save_dense(path, "density", v, 2, 2, 2, 1.0, origin, err, sizeof err) == RD_OK, "%s", err);
    FILE *f = fopen(path, "rb");
    char buf[65536];
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    rd_grid g;
    vec3 lo, hi;
    for (size_t len = 0; len < n; len += n / 7 + 1) {
        rt_write_file(cut, buf, len);
        memset(&g, 0, sizeof g);
        rd_status st = rd_vdb_load(cut, "density", &g, &lo, &hi, err, sizeof err);
        cr_expect(st != RD_OK, "a file cut at %zu of %zu bytes was accepted", len, n);
        cr_expect(strncmp(err, cut, strlen(cut)) == 0, "message names the file: %s", err);
        cr_expect(g.data == NULL);
    }
    cr_expect(rd_vdb_load(path, "temperature", &g, &lo, &hi, err, sizeof err) == RD_ERR_FORMAT);
    cr_expect(strstr(err, "no grid named \"temperature\" (grids: density)") != NULL, "%s", err);
    cr_expect(rd_vdb_load(path, "density", &g, &lo, &hi, err, sizeof err) == RD_OK, "%s", err);
    free(g.data);
}

Test(volume, noise_stays_within_its_majorant_bound)
{
    /* rd_noise_fbm_bound uses |noise| <= 1.04 per octave (see medium.c). Check the envelope
     * E(f) = sum_c w_c (largest two |f - c|) on 200000 random points, and the noise itself
     * (several seeds) on 200000 points; a bound that a single sample beats is wrong. */
    pcg32 rng = pcg32_seed(8, 8, 8);
    double emax = 0, nmax = 0;
    for (int i = 0; i < 200000; i++) {
        double f[3] = {pcg32_uniform(&rng), pcg32_uniform(&rng), pcg32_uniform(&rng)}, w[3], e = 0;
        for (int a = 0; a < 3; a++) w[a] = f[a] * f[a] * f[a] * (f[a] * (f[a] * 6 - 15) + 10);
        for (int c = 0; c < 8; c++) {
            double wc = 1, d[3];
            for (int a = 0; a < 3; a++) {
                int bit = (c >> a) & 1;
                wc *= bit ? w[a] : 1 - w[a];
                d[a] = fabs(f[a] - bit);
            }
            double mn = fmin(d[0], fmin(d[1], d[2]));
            e += wc * (d[0] + d[1] + d[2] - mn);
        }
        emax = fmax(emax, e);
    }
    cr_expect(emax < 1.04 && emax > 1.0, "envelope maximum %.5f", emax);
    for (uint32_t seed = 1; seed <= 4; seed++) {
        rd_noise n = {.octaves = 1, .frequency = 1, .gain = 0.5, .lacunarity = 2, .seed = seed};
        rd_noise_init_perm(&n);
        for (int i = 0; i < 50000; i++) {
            vec3 x = v3(40 * pcg32_uniform(&rng), 40 * pcg32_uniform(&rng), 40 * pcg32_uniform(&rng));
            nmax = fmax(nmax, fabs(rd_noise_eval(&n, x)));
        }
    }
    cr_expect(nmax <= 1.04 && nmax > 0.5, "noise maximum %.5f", nmax);
    rd_noise n5 = {.octaves = 5, .gain = 0.5};
    cr_expect(fabs(rd_noise_fbm_bound(&n5) - 1.04 * (1 + 0.5 + 0.25 + 0.125 + 0.0625)) < 1e-12);
}
