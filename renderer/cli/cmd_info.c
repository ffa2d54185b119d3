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
    "glass first (which delta cannot render), then the share that leaves a sphere or environment\n"
    "light through glass first, each when there is any (a trace of 50000 photons for the second).\n";

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
    /* Light by way of glass from a sphere or environment light (rd_hidden_light's caustic share,
     * less the hidden share above; a trace of its own: the loader measures the hidden share
     * alone). */
    double hidden, caustic;
    st = rd_hidden_light(scene, RD_HIDDEN_PHOTONS, 0, &hidden, &caustic, err, sizeof err);
    if (st) {
        rd_scene_free(scene);
        return cli_report_error(st, err);
    }
    if (caustic - hidden > RD_HIDDEN_SHARE)
        printf("caustic    %.3g%% of the light scattered in the media leaves a sphere or environment light by way of "
               "glass first: a path finds it only by hitting the light through the glass, next-event estimation "
               "never (the photon sources of march.ls, nee+beams among them, render it from photons: "
               "docs/guided-marching.md, \"Light through glass from a sphere light\")\n",
               100.0 * (caustic - hidden));
    rd_scene_free(scene);
    return 0;
}
