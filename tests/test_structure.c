/* test_structure.c: the code's house rules (docs/render-core.md, "The map"), checked on the
 * objects of this build by tests/check_structure.py: no file-level dependency cycle among the
 * libraries' objects, modules that depend one way, renderer/'s folders as layers that depend
 * downward only, and the size caps (library sources at most 1000 lines, internal headers at
 * most 300). The checker's own self-test runs first, so a checker that can no longer find a
 * planted cycle fails here rather than passing everything. */
#define _DEFAULT_SOURCE
#include <criterion/criterion.h>
#include <libgen.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

/* Run a shell command; its output goes into out (up to n bytes), its exit status is returned. */
static int run(const char *cmd, char *out, size_t n)
{
    FILE *p = popen(cmd, "r");
    cr_assert(p != NULL, "cannot run %s", cmd);
    size_t got = fread(out, 1, n - 1, p);
    out[got] = 0;
    int st = pclose(p);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

Test(structure, checker_finds_planted_cycles_and_upward_uses)
{
    char out[4096];
    int st = run("python3 tests/check_structure.py --self-test 2>&1", out, sizeof out);
    cr_assert_eq(st, 0, "check_structure.py --self-test failed:\n%s", out);
}

Test(structure, no_cycle_no_upward_use_no_oversized_file)
{
    /* The build folder is the one holding the binary under test (build/photonmarch). */
    const char *bin = getenv("PHOTONMARCH_BIN");
    char dir[1024], cmd[1200], out[16384];
    snprintf(dir, sizeof dir, "%s", bin ? bin : "build/photonmarch");
    snprintf(cmd, sizeof cmd, "python3 tests/check_structure.py '%s' 2>&1", dirname(dir));
    int st = run(cmd, out, sizeof out);
    cr_assert_eq(st, 0, "%s\n%s", cmd, out);
}
