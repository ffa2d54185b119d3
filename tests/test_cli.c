/* The command line as a user meets it: the malformed-scene catalogue (every case a clear
 * one-line error naming the file and the field, exit code 2, never a crash, also under the
 * sanitizer build), a good render writing EXR + PNG + JSON atomically, Ctrl-C writing what it
 * has, and option errors. The binaries come from PHOTONMARCH_BIN and PHOTONMARCH_ASAN_BIN
 * (set by `make test`). */
#include "support/rd_test.h"

#include <cJSON.h>
#include <dirent.h>
#include <signal.h>
#include <time.h>

#include "sh.h"

/* The render report at `path`, parsed (the caller frees it with cJSON_Delete). */
static cJSON *read_report(const char *path)
{
    FILE *f = fopen(path, "r");
    cr_assert(f != NULL, "no report at %s", path);
    static char buf[1 << 16];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    buf[n] = 0;
    fclose(f);
    cJSON *j = cJSON_Parse(buf);
    cr_assert(j != NULL, "the report is not JSON: %s", buf);
    return j;
}

static double report_num(const cJSON *j, const char *key)
{
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(j, key);
    cr_assert(cJSON_IsNumber(v), "report: no number \"%s\"", key);
    return v->valuedouble;
}

/* The last non-empty line of a captured stream. */
static const char *last_line(const char *text)
{
    const char *end = text + strlen(text);
    while (end > text && end[-1] == '\n') end--;
    const char *p = end;
    while (p > text && p[-1] != '\n') p--;
    return p;
}

typedef struct { const char *file, *expect; } bad_case;

/* tests/data/bad/<file>: the message must contain `expect`. */
static const bad_case catalogue[] = {
    {"truncated.json", "line 1, column 38: invalid JSON"},
    {"empty.json", "invalid JSON"},
    {"top_array.json", "(top level): expected an object"},
    {"nan_value.json", "invalid JSON"},
    {"huge_number.json", "media[0].sigma_t: must be finite"},
    {"missing_camera.json", "camera: missing"},
    {"unknown_top_key.json", "lightz: unknown key"},
    {"unknown_medium_key.json", "media[0].densty: unknown key"},
    {"zero_resolution.json", "camera.resolution: expected [width, height]"},
    {"absurd_resolution.json", "camera.resolution: expected [width, height]"},
    {"fov_string.json", "camera.fov: expected a number, found a string"},
    {"negative_sigma.json", "media[0].sigma_t: must be in [0"},
    {"albedo_two_numbers.json", "media[0].albedo: expected a number or 3 numbers in [0, 1]"},
    {"albedo_above_one.json", "media[0].albedo: expected a number or 3 numbers in [0, 1], found 1.5"},
    {"g_equals_one.json", "media[0].g: must be in (-1, 1)"},
    {"missing_vdb.json", "media[0].density.file: tests/data/bad/no_such.vdb: No such file"},
    {"corrupt_vdb.json", "media[0].density.file: tests/data/bad/corrupt.vdb:"},
    {"raw_wrong_size.json", "media[0].density.file: tests/data/bad/short.raw: size 10 bytes, expected 256"},
    {"spot_angle_zero.json", "lights[0].angle: must be in (0, 180]"},
    {"spot_angle_200.json", "lights[0].angle: must be in (0, 180]"},
    {"unknown_light_type.json", "lights[0].type: unknown value \"laser\""},
    {"overlapping_media.json", "media[1].bounds: overlaps media[0]"},
    {"bounds_inverted.json", "media[0].bounds: min must be smaller than max"},
    {"camera_up_parallel.json", "camera.up: must not be parallel"},
    {"spp_zero.json", "settings.spp: must be in [1, 16777216], found 0"},
    {"media_not_array.json", "media: expected an array, found an object"},
    {"negative_intensity.json", "lights[0].intensity: expected a number or 3 numbers"},
    {"unknown_method.json", "settings.method: unknown method \"magic\""},
    {"ppm_alpha_one.json", "photons.alpha: must be in (0, 1), found 1"},
    {"ppm_pass_spp_zero.json", "photons.pass_spp: must be in [1, 1048576], found 0"},
    {"majorant_unknown_type.json", "media[0].majorant.type: unknown value \"kdtree\" (expected one of: auto, none, grid, octree)"},
    {"majorant_unknown_key.json", "media[0].majorant.resoluton: unknown key (allowed: type, resolution, bound, fail, max_level"},
    {"majorant_resolution_not_grid.json", "media[0].majorant.resolution: only with \"type\": \"grid\""},
    {"majorant_resolution_zero.json", "media[0].majorant.resolution: must be in [1, 256], found 0"},
    {"tracker_unknown.json", "settings.tracker: unknown value \"teleport\""},
    {"tracker_b_without_weighted.json", "settings.b: only with \"tracker\": \"weighted\" or \"decomposition\""},
    {"tracker_b_negative.json", "settings.b: must be in (0, 100], found -1"},
    {"transmittance_unknown.json", "settings.transmittance: unknown value \"guess\""},
    {"equiangular_unknown.json", "settings.equiangular: expected true, false, \"camera\", \"auto\" or \"tiles\", found \"always\""},
    {"adaptive_number.json", "settings.adaptive: expected true, false, \"auto\", \"pilot\" or \"epochs\", found a number"},
    {"adaptive_word.json", "settings.adaptive: expected true, false, \"auto\", \"pilot\" or \"epochs\", found \"sometimes\""},
    {"guide_equiangular_tiles.json", "guide.equiangular: expected true, false, \"camera\" or \"auto\", found \"tiles\""},
    {"thin_bias_above_one.json", "settings.thin_bias: expected false or a number in (0, 1), found 1.5"},
    {"thin_bias_weighted.json", "settings.thin_bias: only with \"tracker\": \"auto\", \"supervoxel\" or \"woodcock\""},
    {"too_thick.json", "media[0].sigma_t: majorant optical depth across the bounds is 3.46e+12"},
    {"shape_outside_wrong.json", "shapes[0].outside: \"fog\" but the shape lies in \"room\""},
};

/* Every case through `render` and `info`: exit 2, one line naming the file and the field, no
 * output, and refused at load: each run costs at most cpu_max CPU seconds (the program's start-up,
 * about 0.2 s in the release build, and the scene's parsing). CPU time, not wall time: how long the
 * 88 runs take on the clock depends on the machine's load, which is not what is tested. */
static void run_catalogue(const char *bin, double cpu_max)
{
    int n = sizeof catalogue / sizeof catalogue[0];
    cr_assert(n >= 15);
    double cpu_total = 0, cpu_worst = 0;
    for (int i = 0; i < n; i++) {
        char scene[256], out[4096], err[8192], outexr[256];
        snprintf(scene, sizeof scene, "tests/data/bad/%s", catalogue[i].file);
        snprintf(outexr, sizeof outexr, "%s/bad%d.exr", rt_tmpdir(), i);
        const char *cmds[2] = {"render", "info"};
        for (int c = 0; c < 2; c++) {
            char *argv[] = {(char *)bin, (char *)cmds[c], scene, "-o", outexr, "-q", NULL};
            if (c == 1) argv[3] = NULL;
            double cpu = 0;
            int code = rt_run(argv, out, sizeof out, err, sizeof err, &cpu);
            cr_expect(code == 2, "%s %s %s: exit %d (expected 2); stderr: %s", bin, cmds[c], scene, code, err);
            cr_expect(cpu <= cpu_max, "%s %s %s: %.2f CPU s to refuse a bad scene (at most %.1f)", bin, cmds[c], scene,
                      cpu, cpu_max);
            cpu_total += cpu;
            cpu_worst = fmax(cpu_worst, cpu);
            /* One line, beginning with the file's name, containing the expected words. */
            size_t len = strlen(err);
            cr_expect(len > 0 && err[len - 1] == '\n' && strchr(err, '\n') == err + len - 1,
                      "%s: stderr is not exactly one line: [%s]", scene, err);
            cr_expect(strncmp(err, scene, strlen(scene)) == 0, "%s: message does not start with the file: %s", scene, err);
            cr_expect(strstr(err, catalogue[i].expect) != NULL, "%s: expected \"%s\" in: %s", scene, catalogue[i].expect, err);
            cr_expect(access(outexr, F_OK) != 0, "%s: an output was written for a bad scene", scene);
        }
    }
    cr_log_info("%s: %d runs, %.1f CPU s, the longest %.2f s", bin, 2 * n, cpu_total, cpu_worst);
}

/* The timeouts below only guard against a run that blocks for ever (one that spins is ended by
 * RT_CHILD_CPU_LIMIT): the runs' cost is checked in CPU seconds, case by case. */
Test(cli, malformed_scene_catalogue, .timeout = 1800)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL, "PHOTONMARCH_BIN is not set (run through make test)");
    run_catalogue(bin, 2.0);
}

/* The sanitizer build starts more slowly (its runtime maps its shadow memory, the libraries'
 * start-up is instrumented too). */
Test(cli, malformed_scene_catalogue_under_sanitizers, .timeout = 1800)
{
    const char *bin = getenv("PHOTONMARCH_ASAN_BIN");
    if (!bin) cr_skip_test("PHOTONMARCH_ASAN_BIN is not set (make test sets it)");
    run_catalogue(bin, 5.0);
}

static const char *tiny_scene(void)
{
    static char path[256];
    snprintf(path, sizeof path, "%s/tiny.json", rt_tmpdir());
    const char *json =
        "{\"camera\":{\"position\":[0,0,4],\"look_at\":[0,0,0],\"resolution\":[24,16]},"
        "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"density\":{\"type\":\"noise\",\"octaves\":2},"
        "\"sigma_t\":2,\"albedo\":0.9,\"g\":0.4}],"
        "\"lights\":[{\"type\":\"point\",\"position\":[1,2,1],\"intensity\":5}],"
        "\"settings\":{\"spp\":4}}";
    rt_write_file(path, json, strlen(json));
    return path;
}

Test(cli, render_writes_exr_png_and_report, .timeout = 120)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char exr[256], png[256], js[256], out[4096], err[4096];
    snprintf(exr, sizeof exr, "%s/img/a.exr", rt_tmpdir());
    snprintf(png, sizeof png, "%s/img/a.png", rt_tmpdir());
    snprintf(js, sizeof js, "%s/img/a.json", rt_tmpdir());
    char *argv[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", exr, "--spp", "3", "--threads", "2", NULL};
    int code = rt_run(argv, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 0, "exit %d: %s", code, err);
    cr_expect(strstr(out, exr) && strstr(out, png) && strstr(out, js), "stdout names the outputs: %s", out);
    rd_image img;
    char msg[RD_ERRLEN];
    cr_assert(rd_image_read(exr, &img, msg, sizeof msg) == RD_OK, "%s", msg);
    cr_expect(img.w == 24 && img.h == 16);
    double sum = 0;
    for (int i = 0; i < img.w * img.h * 3; i++) {
        cr_expect(isfinite(img.rgb[i]) && img.rgb[i] >= 0.0f);
        sum += img.rgb[i];
    }
    cr_expect(sum > 0.0);
    rd_image_free_pixels(&img);
    cr_expect(rd_image_read(png, &img, msg, sizeof msg) == RD_OK, "%s", msg);
    rd_image_free_pixels(&img);
    cJSON *rep = read_report(js);
    cr_expect(report_num(rep, "spp") == 3, "report: spp %g", report_num(rep, "spp"));
    /* (the default method, delta, with its default "tiles" on this point light: the epochs'
     * shares of the samples, since session 72) */
    cr_expect(cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(rep, "shares")), "report: \"shares\" not true");
    /* The per-pixel standard error beside the image: same size, finite, non-negative, and
     * non-zero somewhere (3 samples of a lit medium are not all equal). */
    char se[300];
    snprintf(se, sizeof se, "%s/img/a-stderr.exr", rt_tmpdir());
    cr_assert(rd_image_read(se, &img, msg, sizeof msg) == RD_OK, "%s", msg);
    cr_expect(img.w == 24 && img.h == 16);
    double se_sum = 0, se2_sum = 0;
    for (int i = 0; i < img.w * img.h * 3; i++) {
        cr_expect(isfinite(img.rgb[i]) && img.rgb[i] >= 0.0f);
        se_sum += img.rgb[i];
        se2_sum += (double)img.rgb[i] * img.rgb[i];
    }
    cr_expect(se_sum > 0.0);
    /* The report's variance per sample is that file's squared errors, averaged over pixels and
     * channels, times the 3 samples each pixel took (the EXR stores floats, as the report's sum
     * read them: agreement to float rounding). */
    double vps = se2_sum / (img.w * img.h * 3) * 3.0, rep_vps = report_num(rep, "variance_per_sample");
    cr_expect(vps > 0.0 && fabs(rep_vps - vps) <= 1e-5 * vps, "variance_per_sample %g, from the file %g", rep_vps, vps);
    cJSON_Delete(rep);
    rd_image_free_pixels(&img);
    /* No temporary files are left beside the outputs. */
    char cmd[512];
    snprintf(cmd, sizeof cmd, "ls -a %s/img | grep -c tmp", rt_tmpdir());
    FILE *p = popen(cmd, "r");
    int tmpfiles = -1;
    cr_assert(fscanf(p, "%d", &tmpfiles) == 1);
    pclose(p);
    cr_expect(tmpfiles == 0, "temporary files left behind");
}

/* The image module (core/image_plugin.h) is loaded when a command first reads or writes an
 * image; a copy of the program without the module beside it must refuse a render before the
 * render, not after it: one line naming the output, a non-zero exit, no output written, and
 * little CPU time for a render of 24x16 pixels at 2^20 samples (minutes of work). `info` on a
 * good scene, which reads no image, succeeds there; and the program does not name OpenImageIO
 * among the libraries it needs (readelf), or every start would load it again. */
Test(cli, a_program_without_its_image_module_refuses_before_rendering, .timeout = 120)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char dir[256], lone[300], exr[300], out[4096], err[4096], cmd[700];
    snprintf(dir, sizeof dir, "%s/lone", rt_tmpdir());
    snprintf(lone, sizeof lone, "%s/photonmarch", dir);
    snprintf(exr, sizeof exr, "%s/x.exr", dir);
    snprintf(cmd, sizeof cmd, "mkdir -p '%s' && cp '%s' '%s'", dir, bin, lone);
    cr_assert(system(cmd) == 0, "%s", cmd);
    cr_assert(system("command -v readelf > /dev/null") == 0, "readelf (binutils) is not installed");
    snprintf(cmd, sizeof cmd, "readelf -d '%s' | grep -q 'NEEDED.*OpenImageIO'", bin);
    cr_expect(system(cmd) != 0, "%s is linked against OpenImageIO: every start loads it", bin);
    char *info[] = {lone, "info", (char *)tiny_scene(), NULL};
    int code = rt_run(info, out, sizeof out, err, sizeof err, NULL);
    cr_expect(code == 0, "info without the image module: exit %d: %s", code, err);
    char *argv[] = {lone, "render", (char *)tiny_scene(), "-o", exr, "--spp", "1048576", "-q", NULL};
    double cpu = 0;
    code = rt_run(argv, out, sizeof out, err, sizeof err, &cpu);
    cr_expect(code == 3, "a render without the image module: exit %d (expected 3, an output cannot be written)", code);
    size_t len = strlen(err);
    cr_expect(len > 0 && strchr(err, '\n') == err + len - 1, "stderr is not one line: [%s]", err);
    cr_expect(strncmp(err, exr, strlen(exr)) == 0 && strstr(err, "cannot load the image module"),
              "the message does not name the output and the module: %s", err);
    cr_expect(cpu <= 2.0, "%.2f CPU s before refusing: the render ran first", cpu);
    cr_expect(access(exr, F_OK) != 0, "an output was written");
}

/* Bit for bit the same contents. */
static int same_bytes(const char *a, const char *b)
{
    char cmd[700];
    snprintf(cmd, sizeof cmd, "cmp -s '%s' '%s'", a, b);
    return system(cmd) == 0;
}

static void copy_file(const char *from, const char *to)
{
    char cmd[700];
    snprintf(cmd, sizeof cmd, "cp '%s' '%s'", from, to);
    cr_assert(system(cmd) == 0, "%s", cmd);
}

Test(cli, info_names_the_light_only_photons_find, .timeout = 120)
{
    /* scenes/glass-fog.json: a spot above a glass ball of fog; most of the fog's light comes
     * through the glass (rd_hidden_light, tests/test_photons.c checks the share), and info says
     * so; scenes/default.json has no glass and no such line. render notes it for delta, which
     * cannot render that light, and for guided with nee+paths; not for guided as it comes
     * (march.ls defaults to nee+beams on such a scene: load/load.c). */
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char out[8192], err[4096];
    char *glass[] = {(char *)bin, "info", "scenes/glass-fog.json", NULL};
    cr_assert(rt_run(glass, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    cr_expect(strstr(out, "\nhidden ") != NULL && strstr(out, "by way of glass first") != NULL, "%s", out);
    cr_expect(strstr(out, "\ncaustic ") == NULL, "a spot light's caustic is hidden light, said once: %s", out);
    char *plain[] = {(char *)bin, "info", "scenes/default.json", NULL};
    cr_assert(rt_run(plain, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    cr_expect(strstr(out, "\nhidden ") == NULL && strstr(out, "\ncaustic ") == NULL, "%s", out);
    /* scenes/hard-lens-caustic.json: a sphere light above a ball lens: nothing hidden (a path can
     * hit the light), but 4% of the haze's light comes through the glass (the caustic line) */
    char *lens[] = {(char *)bin, "info", "scenes/hard-lens-caustic.json", NULL};
    cr_assert(rt_run(lens, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    cr_expect(strstr(out, "\nhidden ") == NULL && strstr(out, "\ncaustic ") != NULL &&
                  strstr(out, "leaves a sphere or environment light by way of glass first") != NULL,
              "%s", out);
    char exr[256];
    snprintf(exr, sizeof exr, "%s/hidden/a.exr", rt_tmpdir());
    char *blind[] = {(char *)bin, "render", "scenes/glass-fog.json", "--method", "delta", "--spp", "1",
                     "--set", "camera.resolution=[16,12]", "-o", exr, NULL};
    cr_assert(rt_run(blind, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    cr_expect(strstr(err, "note: ") != NULL && strstr(err, "delta cannot render it") != NULL, "%s", err);
    char *paths[] = {(char *)bin, "render", "scenes/glass-fog.json", "--method", "guided", "--spp", "1",
                     "--set", "camera.resolution=[16,12]", "--set", "march.ls=nee+paths", "--no-cache", "-o", exr, NULL};
    cr_assert(rt_run(paths, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    cr_expect(strstr(err, "guided cannot render it") != NULL, "%s", err);
    char *sees[] = {(char *)bin, "render", "scenes/glass-fog.json", "--method", "guided", "--spp", "1",
                    "--set", "camera.resolution=[16,12]", "--no-cache", "-o", exr, NULL};
    cr_assert(rt_run(sees, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    cr_expect(strstr(err, "note: ") == NULL, "%s", err);
}

Test(cli, failed_run_keeps_the_previous_image, .timeout = 120)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char exr[256], copy[300], out[4096], err[4096];
    snprintf(exr, sizeof exr, "%s/keep.exr", rt_tmpdir());
    snprintf(copy, sizeof copy, "%s/keep.copy", rt_tmpdir());
    char *good[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", exr, "-q", NULL};
    cr_assert(rt_run(good, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    char cmd[700];
    snprintf(cmd, sizeof cmd, "cp '%s' '%s'", exr, copy);
    cr_assert(system(cmd) == 0);
    /* An invalid scene: refused, the image untouched byte for byte. */
    char *bad[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", exr, "--set", "media[0].g=2", NULL};
    int code = rt_run(bad, out, sizeof out, err, sizeof err, NULL);
    cr_expect(code == 2, "exit %d", code);
    cr_expect(strstr(err, "media[0].g: must be in (-1, 1), found 2") != NULL, "%s", err);
    cr_expect(same_bytes(exr, copy), "a refused run changed the image");
}

Test(cli, failed_write_leaves_no_partial_file, .timeout = 120)
{
    /* The output path is a folder: writing fails at the rename, exit 3, the folder is intact
     * and no temporary file is left beside it. */
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char dir[200], exr[256], out[4096], err[4096], probe[300];
    snprintf(dir, sizeof dir, "%s/wf", rt_tmpdir());
    cr_assert(mkdir(dir, 0777) == 0);
    snprintf(exr, sizeof exr, "%s/img.exr", dir);
    cr_assert(mkdir(exr, 0777) == 0);
    snprintf(probe, sizeof probe, "%s/inside", exr);
    rt_write_file(probe, "x", 1);
    char *argv[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", exr, "--spp", "1", NULL};
    int code = rt_run(argv, out, sizeof out, err, sizeof err, NULL);
    cr_expect(code == 3, "exit %d (expected 3): %s", code, err);
    cr_expect(strncmp(last_line(err), exr, strlen(exr)) == 0, "message names the output: %s", err);
    cr_expect(access(probe, F_OK) == 0, "the folder in the way was damaged");
    char cmd[400];
    snprintf(cmd, sizeof cmd, "ls -a '%s' | grep -c tmp", dir);
    FILE *p = popen(cmd, "r");
    int n = -1;
    cr_assert(fscanf(p, "%d", &n) == 1);
    pclose(p);
    cr_expect(n == 0, "temporary files left behind");
}

/* A render far longer than the test waits for, stopped by `sig` once it has reported its first
 * pass (the progress line written to a non-terminal stderr): exit 128 + sig, the image so far and
 * a report marked interrupted. */
static void signal_writes_what_it_has(int sig, const char *name)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char exr[256], js[256], err[4096];
    snprintf(exr, sizeof exr, "%s/%s.exr", rt_tmpdir(), name);
    snprintf(js, sizeof js, "%s/%s.json", rt_tmpdir(), name);
    char *argv[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", exr, "--spp", "10000000",
                    "--set", "camera.resolution=[64,64]", NULL};
    int code = run_signal_on(argv, " spp ", sig, err, sizeof err, NULL, 0);
    cr_expect(code == 128 + sig, "%s: exit %d (expected %d): %s", name, code, 128 + sig, err);
    cr_expect(access(exr, F_OK) == 0, "%s: the partial image was not written", name);
    cJSON *rep = read_report(js);
    cr_expect(cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(rep, "interrupted")), "%s: not marked interrupted", name);
    cr_expect(report_num(rep, "spp") >= 1, "%s: the first pass was reported done, so spp >= 1", name);
    cJSON_Delete(rep);
}

Test(cli, ctrl_c_writes_what_it_has, .timeout = 120)
{
    signal_writes_what_it_has(SIGINT, "int");
}

/* What batch schedulers and `timeout` send: the same treatment, exit 143. */
Test(cli, sigterm_writes_what_it_has, .timeout = 120)
{
    signal_writes_what_it_has(SIGTERM, "term");
}

/* Entries of folder `dir` whose name contains `part`. */
static int count_entries(const char *dir, const char *part)
{
    DIR *d = opendir(dir);
    cr_assert(d != NULL, "%s", dir);
    int n = 0;
    for (struct dirent *e; (e = readdir(d)) != NULL;) n += strstr(e->d_name, part) != NULL;
    closedir(d);
    return n;
}

/* A second signal ends the process at once, before it writes anything, so the previous outputs
 * stay as they were. The two signals are made pending together while the child is stopped, so
 * they arrive at the same moment: one thread's handler blocks the other signal (sa_mask) until it
 * has restored the default action, and when two threads take one each, the handler's atomic
 * first-signal check makes the later one a second signal. Either way the second one kills, with
 * no race against the child's progress. */
Test(cli, second_signal_ends_at_once_keeping_the_previous_output, .timeout = 120)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char exr[256], js[256], exr0[300], js0[300], dir[200], out[4096], err[4096];
    snprintf(dir, sizeof dir, "%s/twice", rt_tmpdir());
    snprintf(exr, sizeof exr, "%s/t.exr", dir);
    snprintf(js, sizeof js, "%s/t.json", dir);
    snprintf(exr0, sizeof exr0, "%s/previous.exr", rt_tmpdir());
    snprintf(js0, sizeof js0, "%s/previous.json", rt_tmpdir());
    char *first[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", exr, "--spp", "1", "-q", NULL};
    cr_assert(rt_run(first, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    copy_file(exr, exr0);
    copy_file(js, js0);
    char *argv[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", exr, "--spp", "10000000", "--threads", "2",
                    "--set", "camera.resolution=[64,64]", NULL};
    child c = spawn_until(argv, " spp ", err, sizeof err);
    int status;
    kill(c.pid, SIGSTOP);
    cr_assert(waitpid(c.pid, &status, WUNTRACED) == c.pid && WIFSTOPPED(status));
    kill(c.pid, SIGTERM);
    kill(c.pid, SIGINT);
    kill(c.pid, SIGCONT);
    int code = child_wait(&c, err, sizeof err, NULL, 0);
    cr_expect(code == 1000 + SIGTERM || code == 1000 + SIGINT, "exit %d: expected death by the second signal: %s", code, err);
    /* (The first signal's message is not checked: when two threads take the signals at once,
     * the second can end the process before the first handler has written it.) */
    cr_expect(same_bytes(exr, exr0) && same_bytes(js, js0), "the previous output was changed");
    cr_expect(count_entries(dir, ".tmp") == 0, "a temporary was left although nothing was being written");
}

/* SIGKILL while the outputs are being written (the event: a temporary file appears beside
 * them). The output is never damaged: each file is the previous one or a complete new one; what
 * is left is only hidden temporaries (".t.tmp<pid>.exr"), and the next run removes them. */
Test(cli, sigkill_mid_write_leaves_only_hidden_temporaries, .timeout = 180)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char dir[200], exr[256], exr0[300], out[4096], err[4096];
    snprintf(dir, sizeof dir, "%s/kill", rt_tmpdir());
    snprintf(exr, sizeof exr, "%s/k.exr", dir);
    snprintf(exr0, sizeof exr0, "%s/k-previous.exr", rt_tmpdir());
    /* A large image, so that writing it takes a while (the medium covers few pixels: the render
     * itself is quick). */
    char *argv[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", exr, "--spp", "1", "-q",
                    "--set", "camera.resolution=[1500,1500]", "--set", "camera.position=[0,0,40]", NULL};
    cr_assert(rt_run(argv, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    copy_file(exr, exr0);
    int ofd = open("/dev/null", O_RDWR);
    pid_t pid = fork();
    cr_assert(pid >= 0);
    if (pid == 0) {
        dup2(ofd, 1);
        dup2(ofd, 2);
        execv(argv[0], argv);
        _exit(127);
    }
    struct timespec t0, now, nap = {0, 1000 * 1000};
    clock_gettime(CLOCK_MONOTONIC, &t0);
    int status = 0, ended = 0;
    while (count_entries(dir, ".tmp") == 0) {
        if (waitpid(pid, &status, WNOHANG) == pid) { ended = 1; break; }
        clock_gettime(CLOCK_MONOTONIC, &now);
        cr_assert(now.tv_sec - t0.tv_sec <= 120, "no temporary file appeared");
        nanosleep(&nap, NULL);
    }
    cr_assert(!ended, "the run ended before a temporary file was seen (exit %d)", WEXITSTATUS(status));
    kill(pid, SIGKILL);
    cr_assert(waitpid(pid, &status, 0) == pid && WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL);
    close(ofd);
    /* The image: the previous one, or a complete new one (if the kill came after its rename). */
    rd_image img;
    char msg[RD_ERRLEN];
    cr_expect(same_bytes(exr, exr0) || rd_image_read(exr, &img, msg, sizeof msg) == RD_OK, "a damaged image: %s", msg);
    /* Every temporary left is hidden. */
    DIR *d = opendir(dir);
    cr_assert(d != NULL);
    int left = 0;
    for (struct dirent *e; (e = readdir(d)) != NULL;) {
        if (!strstr(e->d_name, ".tmp")) continue;
        left++;
        cr_expect(e->d_name[0] == '.', "a temporary that is not hidden: %s", e->d_name);
    }
    closedir(d);
    cr_log_info("SIGKILL mid-write left %d hidden temporaries", left);
    /* The next run writing the same output clears them. */
    cr_assert(rt_run(argv, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    cr_expect(count_entries(dir, ".tmp") == 0, "the next run left the temporaries of the killed one");
}

/* The pid of a process that has ended (forked, exited, reaped). */
static pid_t dead_pid(void)
{
    pid_t pid = fork();
    cr_assert(pid >= 0);
    if (pid == 0) _exit(0);
    cr_assert(waitpid(pid, NULL, 0) == pid);
    return pid;
}

/* The clean-up is precise: temporaries of this output whose process has ended go; those of a
 * running process (a concurrent run writing the same output) and of other outputs stay. */
Test(cli, stale_temporaries_of_the_output_are_removed, .timeout = 120)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char dir[200], path[400], out[4096], err[4096];
    snprintf(dir, sizeof dir, "%s/stale", rt_tmpdir());
    cr_assert(mkdir(dir, 0777) == 0);
    long dead = (long)dead_pid(), live = (long)getpid();
    const char *gone[] = {".c.tmp%ld.exr", ".c-stderr.tmp%ld.exr", ".c.tmp%ld.png", ".c.tmp%ld.json"};
    const char *kept[] = {".d.tmp%ld.exr", ".c.tmp%ld.exr.x"};
    for (int i = 0; i < 4; i++) {
        int n = snprintf(path, sizeof path, "%s/", dir);
        snprintf(path + n, sizeof path - n, gone[i], dead);
        rt_write_file(path, "x", 1);
    }
    for (int i = 0; i < 2; i++) {
        int n = snprintf(path, sizeof path, "%s/", dir);
        snprintf(path + n, sizeof path - n, kept[i], dead);
        rt_write_file(path, "x", 1);
    }
    snprintf(path, sizeof path, "%s/.c.tmp%ld.exr", dir, live);
    rt_write_file(path, "x", 1);
    char exr[300];
    snprintf(exr, sizeof exr, "%s/c.exr", dir);
    char *argv[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", exr, "--spp", "1", "-q", NULL};
    cr_assert(rt_run(argv, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    for (int i = 0; i < 4; i++) {
        int n = snprintf(path, sizeof path, "%s/", dir);
        snprintf(path + n, sizeof path - n, gone[i], dead);
        cr_expect(access(path, F_OK) != 0, "%s: a stale temporary was not removed", path);
    }
    for (int i = 0; i < 2; i++) {
        int n = snprintf(path, sizeof path, "%s/", dir);
        snprintf(path + n, sizeof path - n, kept[i], dead);
        cr_expect(access(path, F_OK) == 0, "%s: not a temporary of this output, but removed", path);
    }
    snprintf(path, sizeof path, "%s/.c.tmp%ld.exr", dir, live);
    cr_expect(access(path, F_OK) == 0, "the temporary of a running process was removed");
}

/* Wait until process `pid` catches SIGTERM (bit 15 of SigCgt in /proc/PID/status): the event
 * that its handler is installed. Fails after 60 s (a safety net). */
static void wait_until_catching_sigterm(pid_t pid)
{
    char path[64], line[256];
    snprintf(path, sizeof path, "/proc/%ld/status", (long)pid);
    struct timespec t0, now, nap = {0, 1000 * 1000};
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (;;) {
        FILE *f = fopen(path, "r");
        cr_assert(f != NULL, "%s", path);
        unsigned long long mask = 0;
        while (fgets(line, sizeof line, f))
            if (sscanf(line, "SigCgt: %llx", &mask) == 1) break;
        fclose(f);
        if (mask & (1ULL << (SIGTERM - 1))) return;
        clock_gettime(CLOCK_MONOTONIC, &now);
        cr_assert(now.tv_sec - t0.tv_sec <= 60, "the process never installed its SIGTERM handler");
        nanosleep(&nap, NULL);
    }
}

/* SIGTERM during a bake (tracing and baking cannot stop part-way, and there is nothing yet to
 * save): exit 143 at once, a message, nothing written. */
Test(cli, sigterm_during_bake_ends_it_with_nothing_written, .timeout = 120)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char prefix[256], pmap[300], fe[256], err[4096];
    snprintf(prefix, sizeof prefix, "%s/bt/b", rt_tmpdir());
    snprintf(pmap, sizeof pmap, "%s.pmap", prefix);
    snprintf(fe, sizeof fe, "%s/bake-stderr.XXXXXX", rt_tmpdir());
    int efd = mkstemp(fe);
    cr_assert(efd >= 0);
    char *argv[] = {(char *)bin, "bake", (char *)tiny_scene(), "-o", prefix, "--photons", "1000000000", NULL};
    pid_t pid = fork();
    cr_assert(pid >= 0);
    if (pid == 0) {
        dup2(efd, 2);
        execv(argv[0], argv);
        _exit(127);
    }
    wait_until_catching_sigterm(pid);
    kill(pid, SIGTERM);
    int status;
    cr_assert(waitpid(pid, &status, 0) == pid);
    ssize_t n = pread(efd, err, sizeof err - 1, 0);
    err[n > 0 ? n : 0] = 0;
    close(efd);
    cr_expect(WIFEXITED(status) && WEXITSTATUS(status) == 143, "status %#x (expected exit 143): %s", status, err);
    cr_expect(strstr(err, "nothing written") != NULL, "%s", err);
    cr_expect(access(pmap, F_OK) != 0, "a photon map was written");
}

/* The output named as a symbolic link: the link is replaced by the new file (the rename of the
 * temporary), and the file it pointed to is left as it was (docs/cli.md, "Output paths"). */
Test(cli, symlink_output_is_replaced_not_written_through, .timeout = 120)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char target[256], link[256], out[4096], err[4096];
    snprintf(target, sizeof target, "%s/target.exr", rt_tmpdir());
    snprintf(link, sizeof link, "%s/link.exr", rt_tmpdir());
    rt_write_file(target, "keep", 4);
    cr_assert(symlink(target, link) == 0);
    char *argv[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", link, "--spp", "1", "-q", NULL};
    cr_assert(rt_run(argv, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    struct stat st;
    cr_assert(lstat(link, &st) == 0);
    cr_expect(S_ISREG(st.st_mode), "the output is still a link");
    char buf[16] = {0};
    FILE *f = fopen(target, "rb");
    cr_assert(f != NULL);
    size_t got = fread(buf, 1, sizeof buf, f);
    fclose(f);
    cr_expect(got == 4 && !memcmp(buf, "keep", 4), "the link's target was written through");
}

/* The input scene named as an output (render's report OUT.json, any of bake's files, explain's
 * PREFIX.json) is
 * refused with exit 1 and a message, and the scene is untouched. */
/* An output folder that cannot be made is one line naming it and exit 3 (an output error), also under the
 * sanitizers: `render` once jumped to its clean-up before its bake pointer was set and freed
 * an uninitialised pointer (found by clang's -Wsometimes-uninitialized; UBSan reported a
 * misaligned load in rd_baked_free). */
Test(cli, unmakeable_output_folder_is_one_line, .timeout = 300)
{
    const char *bins[2] = {getenv("PHOTONMARCH_BIN"), getenv("PHOTONMARCH_ASAN_BIN")};
    cr_assert(bins[0] != NULL, "PHOTONMARCH_BIN is not set (run through make test)");
    const char *scene = tiny_scene();
    char out[4096], err[4096];
    for (int i = 0; i < 2; i++) {
        if (!bins[i]) continue;
        char *argv[] = {(char *)bins[i], "render", (char *)scene, "-o", "/proc/photonmarch-none/x.exr",
                        "--spp", "1", "-q", NULL};
        int code = rt_run(argv, out, sizeof out, err, sizeof err, NULL);
        size_t len = strlen(err);
        cr_expect(code == 3, "%s: exit %d (expected 3): %s", bins[i], code, err);
        cr_expect(len > 0 && strchr(err, '\n') == err + len - 1, "%s: not one line: [%s]", bins[i], err);
        cr_expect(strstr(err, "/proc/photonmarch-none") != NULL, "%s: does not name the folder: %s", bins[i], err);
    }
}

Test(cli, scene_as_output_is_refused, .timeout = 120)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char exr[256], copy[256], guide[256], prefix[256], out[4096], err[4096];
    const char *scene = tiny_scene();
    snprintf(exr, sizeof exr, "%s/tiny.exr", rt_tmpdir()); /* its report would be tiny.json */
    snprintf(copy, sizeof copy, "%s/tiny-copy.json", rt_tmpdir());
    copy_file(scene, copy);
    char *a1[] = {(char *)bin, "render", (char *)scene, "-o", exr, "--spp", "1", NULL};
    cr_expect(rt_run(a1, out, sizeof out, err, sizeof err, NULL) == 1, "%s", err);
    cr_expect(strstr(err, "is the input scene") != NULL, "%s", err);
    cr_expect(same_bytes(scene, copy), "the scene was overwritten");
    cr_expect(access(exr, F_OK) != 0, "an image was written");
    /* bake: a scene file named like one of its outputs */
    snprintf(guide, sizeof guide, "%s/s.guide", rt_tmpdir());
    snprintf(prefix, sizeof prefix, "%s/s", rt_tmpdir());
    copy_file(scene, guide);
    char *a2[] = {(char *)bin, "bake", guide, "-o", prefix, "--photons", "1000", NULL};
    cr_expect(rt_run(a2, out, sizeof out, err, sizeof err, NULL) == 1, "%s", err);
    cr_expect(strstr(err, "is the input scene") != NULL, "%s", err);
    cr_expect(same_bytes(guide, copy), "the scene was overwritten by bake");
    /* explain: -o PREFIX whose PREFIX.json is the scene */
    char ex[256], exp_prefix[256];
    snprintf(ex, sizeof ex, "%s/ex.json", rt_tmpdir());
    snprintf(exp_prefix, sizeof exp_prefix, "%s/ex", rt_tmpdir());
    copy_file(scene, ex);
    char *a3[] = {(char *)bin, "explain", ex, "--pixel", "1,1", "-o", exp_prefix, NULL};
    cr_expect(rt_run(a3, out, sizeof out, err, sizeof err, NULL) == 1, "%s", err);
    cr_expect(strstr(err, "is the input scene") != NULL, "%s", err);
    cr_expect(same_bytes(ex, copy), "the scene was overwritten by explain");
}

Test(cli, usage_errors_exit_1)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char out[4096], err[4096];
    char *a1[] = {(char *)bin, "render", (char *)tiny_scene(), "--spp", "zero", NULL};
    cr_expect(rt_run(a1, out, sizeof out, err, sizeof err, NULL) == 1);
    cr_expect(strstr(err, "--spp: expected an integer") != NULL, "%s", err);
    char *a2[] = {(char *)bin, "frobnicate", NULL};
    cr_expect(rt_run(a2, out, sizeof out, err, sizeof err, NULL) == 1);
    char *a3[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", "x.png", NULL};
    cr_expect(rt_run(a3, out, sizeof out, err, sizeof err, NULL) == 1);
    cr_expect(strstr(err, "expected a path ending in .exr") != NULL, "%s", err);
    char *a4[] = {(char *)bin, "render", (char *)tiny_scene(), "--set", "nosuch[3].x=1", NULL};
    cr_expect(rt_run(a4, out, sizeof out, err, sizeof err, NULL) == 1, "%s", err);
    char *a5[] = {(char *)bin, "render", "--help", NULL};
    cr_expect(rt_run(a5, out, sizeof out, err, sizeof err, NULL) == 0);
    cr_expect(strstr(out, "--spp N") && strstr(out, "--set KEY=VALUE"), "%s", out);
    char *a6[] = {(char *)bin, "render", "/nonexistent/scene.json", NULL};
    cr_expect(rt_run(a6, out, sizeof out, err, sizeof err, NULL) == 2);
    cr_expect(strstr(err, "/nonexistent/scene.json: No such file") != NULL, "%s", err);
    /* explain's pixel outside the image: refused before the bake (no folder, no cache made) */
    char prefix[320], dir[300];
    snprintf(dir, sizeof dir, "%.250s/explain-outside", rt_tmpdir());
    snprintf(prefix, sizeof prefix, "%s/x", dir);
    char *a7[] = {(char *)bin, "explain", (char *)tiny_scene(), "--pixel", "100000,0", "-o", prefix, NULL};
    cr_expect(rt_run(a7, out, sizeof out, err, sizeof err, NULL) == 1, "%s", err);
    cr_expect(strstr(err, "--pixel 100000,0: outside the") != NULL, "%s", err);
    cr_expect(access(dir, F_OK) != 0, "explain made %s before refusing the pixel", dir);
}

Test(cli, bake_writes_map_guide_and_pictures_and_reuses_the_map, .timeout = 120)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char prefix[256], out[8192], err[4096], path[300];
    snprintf(prefix, sizeof prefix, "%s/bk/a", rt_tmpdir());
    char *argv[] = {(char *)bin, "bake", (char *)tiny_scene(), "-o", prefix, "--photons", "20000", "--stats",
                    "--slice", "y", "--slice", "z=0.25", NULL};
    int code = rt_run(argv, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 0, "exit %d: %s", code, err);
    cr_expect(strstr(out, "photons    emitted 20000") != NULL, "%s", out);
    cr_expect(strstr(out, "photons/s emitted") && strstr(out, "kd-tree built in") && strstr(out, "bytes per photon"), "%s", out);
    cr_expect(strstr(out, "uniform grid, k-NN bake, 8 bands") != NULL, "%s", out);
    const char *files[] = {".pmap", ".guide", "-photons.exr", "-photons.png", "-slice-y.png", "-slice-z.exr", "-cells-z.png"};
    for (int i = 0; i < 7; i++) {
        snprintf(path, sizeof path, "%s%s", prefix, files[i]);
        cr_expect(access(path, F_OK) == 0, "%s missing", path);
    }
    /* Baking again from the saved map gives the same guide, byte for byte. */
    char pmap[300], prefix2[256], g1[300], g2[300];
    snprintf(pmap, sizeof pmap, "%s.pmap", prefix);
    snprintf(prefix2, sizeof prefix2, "%s/bk/b", rt_tmpdir());
    char *again[] = {(char *)bin, "bake", (char *)tiny_scene(), "-o", prefix2, "--load-photons", pmap, "-q", NULL};
    code = rt_run(again, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 0, "exit %d: %s", code, err);
    snprintf(g1, sizeof g1, "%s.guide", prefix);
    snprintf(g2, sizeof g2, "%s.guide", prefix2);
    /* (the files differ in the stored bake time; compare the cells) */
    sh_guide *ga = NULL, *gb = NULL;
    char msg[256];
    cr_assert(sh_guide_load(&ga, g1, msg, sizeof msg) == SH_OK, "%s", msg);
    cr_assert(sh_guide_load(&gb, g2, msg, sizeof msg) == SH_OK, "%s", msg);
    cr_assert(sh_guide_cell_count(ga) == sh_guide_cell_count(gb) && sh_guide_cell_count(ga) > 0);
    size_t ncoef = 3 * (size_t)sh_guide_bands(ga) * sh_guide_bands(ga);
    for (size_t c = 0; c < sh_guide_cell_count(ga); c++) {
        cr_expect(memcmp(sh_guide_cell_coeffs(ga, c), sh_guide_cell_coeffs(gb, c), ncoef * sizeof(float)) == 0,
                  "cell %zu differs after reloading the photon map", c);
        cr_expect(sh_guide_cell_sigma_t(ga, c) == sh_guide_cell_sigma_t(gb, c));
    }
    sh_guide_free(ga);
    sh_guide_free(gb);
    /* A corrupt photon map is refused with a message naming it, exit 2. */
    FILE *f = fopen(pmap, "r+b");
    cr_assert(f != NULL);
    fseek(f, 100, SEEK_SET);
    fputc(0x5a, f);
    fclose(f);
    code = rt_run(again, out, sizeof out, err, sizeof err, NULL);
    cr_expect(code == 2, "exit %d for a corrupt photon map", code);
    cr_expect(strncmp(err, pmap, strlen(pmap)) == 0, "%s", err);
}

Test(cli, bake_track_length_adaptive, .timeout = 120)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char prefix[256], out[8192], err[4096];
    snprintf(prefix, sizeof prefix, "%s/bk/t", rt_tmpdir());
    char *argv[] = {(char *)bin, "bake", (char *)tiny_scene(), "-o", prefix, "--photons", "20000",
                    "--set", "guide={\"grid\":\"adaptive\",\"bake\":\"track\"}", NULL};
    int code = rt_run(argv, out, sizeof out, err, sizeof err, NULL);
    cr_assert(code == 0, "exit %d: %s", code, err);
    cr_expect(strstr(out, "adaptive grid, track-length bake") != NULL, "%s", out);
}

/* The pixels of two image files are the same bit for bit (the files differ in their date). */
static int same_pixels(const char *a, const char *b)
{
    rd_image ia, ib;
    char msg[RD_ERRLEN];
    cr_assert(rd_image_read(a, &ia, msg, sizeof msg) == RD_OK, "%s", msg);
    cr_assert(rd_image_read(b, &ib, msg, sizeof msg) == RD_OK, "%s", msg);
    int same = ia.w == ib.w && ia.h == ib.h && !memcmp(ia.rgb, ib.rgb, (size_t)ia.w * ia.h * 3 * sizeof(float));
    rd_image_free_pixels(&ia);
    rd_image_free_pixels(&ib);
    return same;
}

/* A method that needs a photon map bakes it once and reuses it from the cache beside the
 * output: the second run says so and gives the same image bit for bit (same seed, same maps);
 * a damaged cache file is baked anew, not trusted. */
Test(cli, bake_cache_is_reused_and_checked, .timeout = 120)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char a[256], b[256], out[4096], err[4096], copy[300];
    snprintf(a, sizeof a, "%s/cache/a.exr", rt_tmpdir());
    snprintf(b, sizeof b, "%s/cache/b.exr", rt_tmpdir());
    snprintf(copy, sizeof copy, "%s/cache/a-copy.exr", rt_tmpdir());
    char *argv_a[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", a, "--method", "uniform", "--spp", "2",
                      "--set", "photons.count=2000", "--set", "march.ls=\"photons\"", NULL};
    cr_assert(rt_run(argv_a, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    cr_expect(strstr(err, "baked the photon map") != NULL, "%s", err);
    char cmd[700];
    snprintf(cmd, sizeof cmd, "cp '%s' '%s'", a, copy);
    cr_assert(system(cmd) == 0);
    cr_assert(rt_run(argv_a, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    cr_expect(strstr(err, "reused the cached") != NULL, "%s", err);
    cr_expect(same_pixels(a, copy), "the cached bake gave another image");
    /* Damage every cached photon map: the next run must bake again. */
    snprintf(cmd, sizeof cmd, "for f in '%s'/cache/.photonmarch-cache/*.pmap; do printf 'XXXX' | dd of=\"$f\" bs=1 seek=20 conv=notrunc 2>/dev/null; done", rt_tmpdir());
    cr_assert(system(cmd) == 0);
    char *argv_b[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", b, "--method", "uniform", "--spp", "2",
                      "--set", "photons.count=2000", "--set", "march.ls=\"photons\"", NULL};
    cr_assert(rt_run(argv_b, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    cr_expect(strstr(err, "baked the photon map") != NULL, "a damaged cache was trusted: %s", err);
    cr_expect(same_pixels(b, copy), "the rebaked photon map gave another image");
    /* A render setting (spp) does not change the key; a photon setting does. */
    char *argv_c[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", b, "--method", "uniform", "--spp", "1",
                      "--set", "photons.count=2001", "--set", "march.ls=\"photons\"", NULL};
    cr_assert(rt_run(argv_c, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    cr_expect(strstr(err, "baked the photon map") != NULL, "a changed photon count reused the cache: %s", err);
}

/* `bake` killed (SIGKILL) while it writes its photon map or its guide (the event: a temporary
 * whose name holds `kind` appears in the output folder): every temporary left is hidden
 * (".b.tmp<pid>.pmap", as render's), and no visible file was created. A large map (1e6
 * photons, written with fsync) and a large guide (96^3 cells, 4 bands) keep the write going
 * long enough to be seen. */
static void bake_killed_while_writing(const char *kind)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char dir[200], prefix[256];
    snprintf(dir, sizeof dir, "%s/bk-%s", rt_tmpdir(), kind);
    snprintf(prefix, sizeof prefix, "%s/b", dir);
    cr_assert(mkdir(dir, 0777) == 0);
    char *argv[] = {(char *)bin, "bake", (char *)tiny_scene(), "-o", prefix, "--photons", "1000000", "-q",
                    "--set", "guide={\"resolution\":[96,96,96],\"bands\":4,\"k\":4}", NULL};
    int nul = open("/dev/null", O_RDWR);
    pid_t pid = fork();
    cr_assert(pid >= 0);
    if (pid == 0) {
        dup2(nul, 1);
        dup2(nul, 2);
        execv(argv[0], argv);
        _exit(127);
    }
    close(nul);
    struct timespec t0, now, nap = {0, 200 * 1000};
    clock_gettime(CLOCK_MONOTONIC, &t0);
    int status = 0, seen = 0;
    while (!seen) {
        DIR *d = opendir(dir);
        cr_assert(d != NULL);
        for (struct dirent *e; (e = readdir(d)) != NULL;)
            seen |= strstr(e->d_name, ".tmp") && strstr(e->d_name, kind);
        closedir(d);
        if (seen) break;
        cr_assert(waitpid(pid, &status, WNOHANG) == 0, "the bake ended before a %s temporary was seen", kind);
        clock_gettime(CLOCK_MONOTONIC, &now);
        cr_assert(now.tv_sec - t0.tv_sec <= 150, "no %s temporary appeared", kind);
        nanosleep(&nap, NULL);
    }
    kill(pid, SIGKILL);
    cr_assert(waitpid(pid, &status, 0) == pid && WIFSIGNALED(status));
    DIR *d = opendir(dir);
    cr_assert(d != NULL);
    for (struct dirent *e; (e = readdir(d)) != NULL;) {
        if (!strstr(e->d_name, ".tmp")) continue;
        cr_expect(e->d_name[0] == '.', "a temporary that is not hidden: %s", e->d_name);
        cr_expect(strstr(e->d_name, ".tmp.") == NULL, "not the .NAME.tmp<pid>.ext scheme: %s", e->d_name);
    }
    closedir(d);
    cr_assert(count_entries(dir, ".tmp") > 0, "the kill left no temporary: nothing to clear below");
    /* The next bake writing the same outputs (a small one) clears the killed one's temporaries. */
    char out[4096], err[4096];
    char *again[] = {(char *)bin, "bake", (char *)tiny_scene(), "-o", prefix, "--photons", "20000", "-q", NULL};
    cr_assert(rt_run(again, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    cr_expect(count_entries(dir, ".tmp") == 0, "the next bake left the killed one's %s temporary", kind);
}

Test(cli, bake_killed_writing_the_photon_map_leaves_only_hidden_temporaries, .timeout = 180)
{
    bake_killed_while_writing("pmap");
}

Test(cli, bake_killed_writing_the_guide_leaves_only_hidden_temporaries, .timeout = 180)
{
    bake_killed_while_writing("guide");
}

/* Wait for child c (spawn_until) like child_wait, and also return the CPU seconds it used. */
static int child_wait_cpu(child *c, char *errbuf, size_t errlen, double *cpu)
{
    int status = 0;
    struct rusage ru;
    cr_assert(wait4(c->pid, &status, 0, &ru) == c->pid);
    *cpu = ru.ru_utime.tv_sec + 1e-6 * ru.ru_utime.tv_usec + ru.ru_stime.tv_sec + 1e-6 * ru.ru_stime.tv_usec;
    child_stderr(c, errbuf, errlen);
    close(c->efd), close(c->ofd);
    unlink(c->path), unlink(c->opath);
    return WIFSIGNALED(status) ? 1000 + WTERMSIG(status) : WEXITSTATUS(status);
}

/* The lines of `text` after the one containing `marker`. */
static int lines_after(const char *text, const char *marker)
{
    const char *p = strstr(text, marker);
    if (!p) return -1;
    p = strchr(p, '\n');
    int n = 0;
    for (; p && p[1]; p = strchr(p + 1, '\n')) n++;
    return n;
}

/* A billion photons of one collision each, none stored (so memory stays flat): about ten CPU
 * minutes of tracing, which a prompt cancel cuts to a fraction of a second. */
#define LONG_TRACE "--set", "photons.max_depth=1", "--set", "photons.store_direct=false"

/* The line a command prints once its cancelling handler is in place, before a bake. */
#define CANCEL_READY "Ctrl-C stops and writes nothing"

/* Start `argv` (a long bake), wait for its CANCEL_READY line (the event), send it `sig` and wait
 * for it. Checks what every cancelled bake owes: exit 128 + sig; a prompt stop (the child's CPU
 * time, not the clock's, so the machine's load does not matter); one line after the ready line,
 * the last, starting with `last`. The child's stderr is left in err. */
static void cancel_bake(char *const argv[], int sig, const char *last, char *err, size_t errlen)
{
    child c = spawn_until(argv, CANCEL_READY, err, errlen);
    kill(c.pid, sig);
    double cpu = 0;
    int code = child_wait_cpu(&c, err, errlen, &cpu);
    cr_expect(code == 128 + sig, "signal %d: exit %d (expected %d): %s", sig, code, 128 + sig, err);
    cr_expect(cpu < 30.0, "signal %d: the bake went on for %.1f CPU s after it", sig, cpu);
    cr_expect(strstr(last_line(err), last) == last_line(err), "signal %d: the last line is not the cancel's: %s", sig,
              err);
    cr_expect(lines_after(err, CANCEL_READY) == 1, "signal %d: not one line: %s", sig, err);
}

/* Nothing was written into the bake cache `cache` (it may not even exist). */
static void expect_cache_untouched(const char *cache)
{
    cr_expect(access(cache, F_OK) != 0 || (count_entries(cache, ".pmap") == 0 && count_entries(cache, ".guide") == 0 &&
                                            count_entries(cache, ".tmp") == 0),
              "the cancelled bake wrote into the cache %s", cache);
}

/* Ctrl-C or SIGTERM while `bake` traces: it stops promptly (cancel_bake), one line says nothing
 * was written, the previous bake's files are as they were and no temporary is left. */
Test(cli, bake_signal_while_tracing_stops_and_writes_nothing, .timeout = 240)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char dir[200], prefix[256], pmap[300], guide[300], pmap0[300], guide0[300], out[4096], err[8192];
    snprintf(dir, sizeof dir, "%s/bcancel", rt_tmpdir());
    snprintf(prefix, sizeof prefix, "%s/b", dir);
    snprintf(pmap, sizeof pmap, "%s.pmap", prefix);
    snprintf(guide, sizeof guide, "%s.guide", prefix);
    snprintf(pmap0, sizeof pmap0, "%s/previous.pmap", rt_tmpdir());
    snprintf(guide0, sizeof guide0, "%s/previous.guide", rt_tmpdir());
    char *first[] = {(char *)bin, "bake", (char *)tiny_scene(), "-o", prefix, "--photons", "20000", "-q", NULL};
    cr_assert(rt_run(first, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    copy_file(pmap, pmap0);
    copy_file(guide, guide0);
    const int sigs[2] = {SIGINT, SIGTERM};
    for (int i = 0; i < 2; i++) {
        char *argv[] = {(char *)bin, "bake", (char *)tiny_scene(), "-o", prefix, "--photons", "1000000000",
                        "--threads", "2", LONG_TRACE, NULL};
        cancel_bake(argv, sigs[i], "photonmarch bake: interrupted while baking; nothing written", err, sizeof err);
        cr_expect(same_bytes(pmap, pmap0) && same_bytes(guide, guide0), "signal %d: the previous bake was changed", sigs[i]);
        cr_expect(count_entries(dir, ".tmp") == 0, "signal %d: a temporary was left", sigs[i]);
    }
}

/* The same during `compare`'s bake of a guided method (the event: its signal handler installed,
 * which it does just before the comparison starts; with --reference given, the bake is the first
 * thing it does): the bake stops promptly and, no run having finished, nothing is written. */
Test(cli, compare_signal_while_baking_stops_promptly, .timeout = 240)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char ref[256], dir[256], err[8192], msg[RD_ERRLEN];
    snprintf(ref, sizeof ref, "%s/cmp-ref.exr", rt_tmpdir());
    snprintf(dir, sizeof dir, "%s/cmp-cancel", rt_tmpdir());
    static float px[24 * 16 * 3];
    rd_image im = {24, 16, px, 0};
    cr_assert(rd_image_write_exr(ref, &im, msg, sizeof msg) == RD_OK, "%s", msg);
    char *argv[] = {(char *)bin, "compare", (char *)tiny_scene(), "--methods", "guided,delta", "--reference", ref,
                    "--budget", "1", "--runs", "1", "--threads", "2", "-o", dir, "-q",
                    "--set", "photons.count=1000000000", LONG_TRACE, NULL};
    child c = spawn_until(argv, "", err, sizeof err); /* started; the event is below (-q: no ready line) */
    wait_until_catching_sigterm(c.pid);
    kill(c.pid, SIGTERM);
    double cpu = 0;
    int code = child_wait_cpu(&c, err, sizeof err, &cpu);
    cr_expect(code == 128 + SIGTERM, "exit %d (expected %d): %s", code, 128 + SIGTERM, err);
    cr_expect(cpu < 30.0, "the bake went on for %.1f CPU s after SIGTERM", cpu);
    cr_expect(strstr(err, "interrupted before any run finished; nothing written") != NULL, "%s", err);
    cr_expect(access(dir, F_OK) != 0, "a report was written");
}

/* The same during `explain`'s bake (through the bake cache beside its outputs): it stops
 * promptly, says so in one line, and writes neither its report nor into the cache. */
Test(cli, explain_signal_while_baking_stops_and_writes_nothing, .timeout = 240)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char dir[200], prefix[256], report[300], cache[300], err[8192];
    snprintf(dir, sizeof dir, "%s/xcancel", rt_tmpdir());
    snprintf(prefix, sizeof prefix, "%s/x", dir);
    snprintf(report, sizeof report, "%s.json", prefix);
    snprintf(cache, sizeof cache, "%s/.photonmarch-cache", dir);
    char *argv[] = {(char *)bin, "explain", (char *)tiny_scene(), "--pixel", "4,4", "-o", prefix, "--threads", "2",
                    "--set", "photons.count=1000000000", LONG_TRACE, NULL};
    cancel_bake(argv, SIGINT, "photonmarch explain: interrupted while baking", err, sizeof err);
    cr_expect(access(report, F_OK) != 0, "a report was written");
    expect_cache_untouched(cache);
}

/* The same during `render`'s bake (a guided method, through the bake cache beside the output):
 * it stops promptly, says so in one line, leaves the previous image and writes nothing into the
 * cache. */
Test(cli, render_signal_while_baking_stops_and_writes_nothing, .timeout = 240)
{
    const char *bin = getenv("PHOTONMARCH_BIN");
    cr_assert(bin != NULL);
    char dir[200], exr[256], exr0[300], cache[300], out[4096], err[8192];
    snprintf(dir, sizeof dir, "%s/rcancel", rt_tmpdir());
    snprintf(exr, sizeof exr, "%s/r.exr", dir);
    snprintf(exr0, sizeof exr0, "%s/previous-r.exr", rt_tmpdir());
    snprintf(cache, sizeof cache, "%s/.photonmarch-cache", dir);
    char *first[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", exr, "--spp", "1", "-q", NULL};
    cr_assert(rt_run(first, out, sizeof out, err, sizeof err, NULL) == 0, "%s", err);
    copy_file(exr, exr0);
    char *argv[] = {(char *)bin, "render", (char *)tiny_scene(), "-o", exr, "--method", "guided", "--spp", "1",
                    "--threads", "2", "--set", "photons.count=1000000000", LONG_TRACE, NULL};
    cancel_bake(argv, SIGTERM, "photonmarch render: interrupted while baking", err, sizeof err);
    cr_expect(same_bytes(exr, exr0), "the previous image was changed");
    cr_expect(count_entries(dir, ".tmp") == 0, "a temporary was left beside the image");
    expect_cache_untouched(cache);
}
