/* main.c: the photonmarch command line (docs/cli.md). A thin layer over renderer.h: it parses
 * options, reports errors as one line on stderr, and decides the exit code (cli.h lists them).
 * This file is the dispatch: the top-level help and version, and the table of subcommands, each
 * in its own cmd_<name>.c. */
#include "cli.h"

#include <stdio.h>
#include <string.h>

static const char *const usage_main =
    "photonmarch: a renderer for participating media (volume photon map guided ray marching\n"
    "and unbiased delta tracking).\n"
    "\n"
    "usage: photonmarch COMMAND [options]\n"
    "\n"
    "commands:\n"
    "  render SCENE   render a scene to a linear EXR, an sRGB PNG preview and a JSON report\n"
    "  info SCENE     describe media, bounds, density range, lights, majorants and memory\n"
    "  voxelize SCENE sample a medium's density into an OpenVDB (.vdb) or raw (.raw) grid\n"
    "  bake SCENE     trace the volume photon map and bake its SH guide grid; save both and\n"
    "                 write pictures of where the light went and of guide slices\n"
    "  compare SCENE  render with several methods at equal time or samples, K runs each, and\n"
    "                 write a report (HTML page, metrics.json, error maps, convergence plot)\n"
    "  explain SCENE --pixel X,Y\n"
    "                 lay one camera ray open: the integrand along it, where guided,\n"
    "                 transmittance and uniform marching put their samples, their variances\n"
    "\n"
    "  photonmarch COMMAND --help   shows the options of a command\n"
    "  photonmarch --version        prints the version\n"
    "\n"
    "exit codes: 0 success, 1 usage error, 2 invalid input (scene or data file),\n"
    "            3 output not written, 4 internal error, 130 / 143 interrupted by SIGINT (Ctrl-C)\n"
    "            / SIGTERM (the image so far written)\n"
    "\n"
    "several processes: mpirun -n K photonmarch render|bake|compare ... (docs/cluster.md)\n"
    "\n"
    "docs: docs/cli.md (this reference), docs/scene-format.md (the scene file)\n";

static int run(int argc, char **argv);

/* The subcommands; each gets the arguments after its name. */
static const struct {
    const char *name;
    int (*run)(int argc, char **argv);
} commands[] = {
    {"render", cli_cmd_render},     {"info", cli_cmd_info},       {"bake", cli_cmd_bake},
    {"voxelize", cli_cmd_voxelize}, {"explain", cli_cmd_explain}, {"compare", cli_cmd_compare},
};

/* The command under an MPI launcher (rd_dist.h): render, bake and compare share their work
 * between the ranks; the others do not yet, and refuse to run on several ranks (each would do the whole
 * job). One rank runs every command as a plain process would. */
static int run_on_ranks(int argc, char **argv, rd_dist *d)
{
    if (argc < 2) return run(argc, argv);
    if (!strcmp(argv[1], "render")) return cli_cmd_render_on(argc - 2, argv + 2, d);
    if (!strcmp(argv[1], "bake")) return cli_cmd_bake_on(argc - 2, argv + 2, d);
    if (!strcmp(argv[1], "compare")) return cli_cmd_compare_on(argc - 2, argv + 2, d);
    if (rd_dist_size(d) > 1) {
        for (size_t k = 0; k < sizeof commands / sizeof commands[0]; k++)
            if (!strcmp(argv[1], commands[k].name)) {
                if (rd_dist_rank(d) == 0)
                    fprintf(stderr, "photonmarch %s: runs on one process only (mpirun -n 1, or without mpirun); "
                                    "only render, bake and compare are shared between ranks (docs/cluster.md)\n", argv[1]);
                return CLI_EXIT_USAGE;
            }
    }
    return run(argc, argv);
}

int main(int argc, char **argv)
{
    rd_steady_allocation(); /* (compare renders several times in one process) */
    /* MPI only when an MPI launcher started this process; a plain run never touches it. */
    rd_dist *d = NULL;
    char err[RD_ERRLEN];
    if (rd_dist_start(&argc, &argv, &d, err, sizeof err) != RD_OK) {
        fprintf(stderr, "photonmarch: %s\n", err);
        return CLI_EXIT_INTERNAL;
    }
    int code = d ? run_on_ranks(argc, argv, d) : run(argc, argv);
    rd_dist_finish(d);
    return code;
}

static int run(int argc, char **argv)
{
    if (argc < 2 || !strcmp(argv[1], "-h") || !strcmp(argv[1], "--help") || !strcmp(argv[1], "help")) {
        fputs(usage_main, argc < 2 ? stderr : stdout);
        return argc < 2 ? CLI_EXIT_USAGE : 0;
    }
    if (!strcmp(argv[1], "--version")) {
        printf("photonmarch 0.1.0\n");
        return 0;
    }
    for (size_t k = 0; k < sizeof commands / sizeof commands[0]; k++)
        if (!strcmp(argv[1], commands[k].name)) return commands[k].run(argc - 2, argv + 2);
    fprintf(stderr, "photonmarch: %s: unknown command (see photonmarch --help)\n", argv[1]);
    return CLI_EXIT_USAGE;
}
