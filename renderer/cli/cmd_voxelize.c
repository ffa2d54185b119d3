/* cmd_voxelize.c: photonmarch voxelize, one medium's density sampled into a .vdb or .raw grid
 * (rd_voxelize). */
#include "cli.h"

#include <stdio.h>
#include <string.h>

static const char *const usage_voxelize =
    "usage: photonmarch voxelize SCENE -o OUT.vdb|OUT.raw [options]\n"
    "\n"
    "Samples the density of one medium at voxel centres over its bounds and writes it as an\n"
    "OpenVDB float grid named \"density\" (cubic voxels, the transform places it where the medium\n"
    "is) or as a raw float32 grid (docs/scene-format.md; the dims to use are printed).\n"
    "\n"
    "options:\n"
    "  -o, --output OUT   .vdb or .raw (required)\n"
    "  --medium I         which medium (default 0)\n"
    "  --res N            voxels along the longest axis (default 64, at most 1024)\n"
    "  --set KEY=VALUE    override a scene field (repeatable)\n";

int cli_cmd_voxelize(int argc, char **argv)
{
    cli_scene_args a = {0};
    const char *outpath = NULL;
    long medium = 0, res = 64;
    for (int i = 0; i < argc; i++) {
        const char *o = argv[i];
        int t = cli_take_set(&a, argc, argv, &i);
        if (t < 0) return CLI_EXIT_USAGE;
        if (t) continue;
        int has_val = i + 1 < argc;
        if (!strcmp(o, "-h") || !strcmp(o, "--help")) { fputs(usage_voxelize, stdout); return 0; }
        else if ((!strcmp(o, "-o") || !strcmp(o, "--output")) && has_val) outpath = argv[++i];
        else if (!strcmp(o, "--medium") && has_val) { if (!cli_parse_int(o, argv[++i], 0, 63, &medium)) return CLI_EXIT_USAGE; }
        else if (!strcmp(o, "--res") && has_val) { if (!cli_parse_int(o, argv[++i], 1, 1024, &res)) return CLI_EXIT_USAGE; }
        else if (cli_take_positional(&a, "voxelize", o)) return CLI_EXIT_USAGE;
    }
    size_t olen = outpath ? strlen(outpath) : 0;
    int vdb = olen > 4 && !strcmp(outpath + olen - 4, ".vdb"), raw = olen > 4 && !strcmp(outpath + olen - 4, ".raw");
    if (!a.scene || !(vdb || raw)) {
        fprintf(stderr, "photonmarch voxelize: need SCENE and -o OUT.vdb or OUT.raw (see photonmarch voxelize --help)\n");
        return CLI_EXIT_USAGE;
    }
    if (cli_refuse_input_as_output("voxelize", outpath, a.scene)) return CLI_EXIT_USAGE;
    char err[RD_ERRLEN];
    rd_scene *s;
    rd_status st = rd_scene_load(&s, a.scene, a.ov, a.nov, err, sizeof err);
    if (st) return cli_report_error(st, err);
    int dims[3];
    st = rd_voxelize(s, (int)medium, (int)res, outpath, dims, err, sizeof err);
    if (st == RD_ERR_ARG) fprintf(stderr, "photonmarch voxelize: %s\n", err);
    else if (st) fprintf(stderr, "%s\n", err);
    else
        printf("%s: %dx%dx%d voxels of %s%s\n", outpath, dims[0], dims[1], dims[2],
               raw ? "the bounds' size / dims" : "cubic size",
               raw ? " (use \"dims\" with these numbers and the same bounds)" : "");
    rd_scene_free(s);
    return cli_exit_for(st);
}
