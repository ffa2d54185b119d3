/* cmd_info.c: photonmarch info, load and validate a scene and describe it (rd_scene_info). */
#include "cli.h"

#include <stdio.h>
#include <string.h>

static const char *const usage_info =
    "usage: photonmarch info SCENE [--set KEY=VALUE ...]\n"
    "\n"
    "Loads and validates SCENE and describes it: camera, media (kind, bounds, density range,\n"
    "sigma_t scale, albedo, g, majorant), lights (kind, parameters, power), settings, memory,\n"
    "and the share of the media's light that leaves a point, spot or directional light through\n"
    "glass first (which delta cannot render), when there is any.\n";

int cli_cmd_info(int argc, char **argv)
{
    cli_scene_args a = {0};
    for (int i = 0; i < argc; i++) {
        int t = cli_take_set(&a, argc, argv, &i);
        if (t < 0) return CLI_EXIT_USAGE;
        if (t) continue;
        if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) { fputs(usage_info, stdout); return 0; }
        if (cli_take_positional(&a, "info", argv[i])) return CLI_EXIT_USAGE;
    }
    if (cli_need_scene(&a, "info")) return CLI_EXIT_USAGE;
    char err[RD_ERRLEN];
    rd_scene *scene;
    rd_status st = rd_scene_load(&scene, a.scene, a.ov, a.nov, err, sizeof err);
    if (st) return cli_report_error(st, err);
    rd_scene_info(scene, stdout);
    /* Light delta cannot render (rd_hidden_light, measured at load; docs/compare.md). */
    double share = rd_scene_hidden_light(scene);
    if (share > RD_HIDDEN_SHARE)
        printf("hidden     %.3g%% of the light scattered in the media leaves a point, spot or directional light "
               "by way of glass first: delta and guided-unbiased cannot render it, nor a marcher without photons "
               "(march.ls %s here, its default on such a scene nee+beams with progressive passes; compare "
               "renders its reference with photons)\n",
               100.0 * share, rd_scene_march_uses_photons(scene) ? "takes photons" : "takes no photons");
    rd_scene_free(scene);
    return 0;
}
