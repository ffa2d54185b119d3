/* compare_scene.h: the small scene of the compare tests (test_compare.c, test_compare_rule.c):
 * 24x16 pixels, a few thousand photons, a coarse guide, so that a bake and a run take a
 * fraction of a second and delta renders hundreds of samples per pixel in well under one (the
 * whole comparison must stay small: the suite also runs under ASan). */
#ifndef RT_COMPARE_SCENE_H
#define RT_COMPARE_SCENE_H

static const char *const small_scene_json =
    "{\"camera\":{\"position\":[0,0,4],\"look_at\":[0,0,0],\"resolution\":[24,16]},"
    "\"media\":[{\"bounds\":{\"min\":[-1,-1,-1],\"max\":[1,1,1]},\"density\":{\"type\":\"noise\",\"octaves\":2},"
    "\"sigma_t\":2,\"albedo\":0.9,\"g\":0.4}],"
    "\"lights\":[{\"type\":\"point\",\"position\":[1,2,1],\"intensity\":[5,4,3]}],"
    "\"photons\":{\"count\":3000},\"guide\":{\"resolution\":[6,6,6]},"
    "\"settings\":{\"spp\":4, \"seed\":5}}";

#endif
