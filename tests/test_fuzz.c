/* Regression inputs found by fuzzing (docs/robustness.md): every file under
 * tests/data/fuzz/<target>/ is replayed through the same harness the libFuzzer target uses
 * (fuzz/harness.c), so a fixed loader bug stays fixed. Under `make test`'s sanitizer suite a
 * memory error or undefined behaviour in a replay fails the test; in the release suite a crash
 * does. The seed corpus (fuzz/seeds/) is replayed too: its valid files reach the deeper paths
 * (index build and queries, guide evaluation and ray walk, scene description). */
#include "support/rd_test.h"

#include <dirent.h>

#include "harness.h"

/* Replay every regular file of `dir` through `one`; returns how many. */
static int replay_dir(const char *dir, int (*one)(const uint8_t *, size_t))
{
    DIR *d = opendir(dir);
    if (!d) return 0; /* no regression inputs for this target (yet) */
    int count = 0;
    for (struct dirent *e; (e = readdir(d)) != NULL;) {
        if (e->d_name[0] == '.') continue;
        char path[512];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        FILE *f = fopen(path, "rb");
        cr_assert(f != NULL, "%s", path);
        static uint8_t buf[1 << 20];
        size_t n = fread(buf, 1, sizeof buf, f);
        fclose(f);
        cr_expect(one(buf, n) == 0, "%s", path);
        count++;
    }
    closedir(d);
    return count;
}

static void replay(const char *target, int (*one)(const uint8_t *, size_t))
{
    char dir[256];
    snprintf(dir, sizeof dir, "tests/data/fuzz/%s", target);
    int n = replay_dir(dir, one);
    snprintf(dir, sizeof dir, "fuzz/seeds/%s", target);
    int seeds = replay_dir(dir, one);
    cr_expect(seeds > 0, "no seeds in %s", dir);
    cr_log_info("%s: %d regression inputs, %d seeds replayed", target, n, seeds);
}

Test(fuzz_regress, scene, .timeout = 120) { replay("scene", fz_scene); }
Test(fuzz_regress, pmap, .timeout = 120) { replay("pmap", fz_pmap); }
Test(fuzz_regress, guide, .timeout = 120) { replay("guide", fz_guide); }
Test(fuzz_regress, raw, .timeout = 120) { replay("raw", fz_raw); }
Test(fuzz_regress, vdb, .timeout = 120) { replay("vdb", fz_vdb); }
Test(fuzz_regress, image, .timeout = 120) { replay("image", fz_image); }
