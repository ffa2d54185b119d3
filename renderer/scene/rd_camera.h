/* rd_camera.h: the camera (scene key "camera"): perspective or orthographic, the primary ray
 * through a film position and its inverse (scene/camera.c). Internal to renderer/. */
#ifndef RD_CAMERA_H
#define RD_CAMERA_H

#include "core/rd_math.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum { RD_CAM_PERSPECTIVE, RD_CAM_ORTHOGRAPHIC } rd_camera_kind;

typedef struct {
    rd_camera_kind kind;
    int width, height;
    vec3 pos;
    vec3 forward, right, up; /* orthonormal, right-handed: right = forward x up */
    double fov_deg;          /* perspective: vertical field of view */
    double tan_half_fov;     /* perspective: tan(fov_deg / 2), the film's half-height at unit
                              * distance (set with fov_deg by the loader, not per ray) */
    double ortho_width;      /* orthographic: width of the view in scene units */
    double exposure;         /* PNG preview: value * 2^exposure */
    int jitter;              /* 1 (default): a random position inside the pixel per sample;
                              * 0: every sample through the pixel centre (for measurements that
                              * must hold the camera ray fixed, docs/guided-marching.md) */
} rd_camera;

/* Primary ray through the film position (px, py) in pixels (0,0 = top-left corner). */
ray3 rd_camera_ray(const rd_camera *cam, double px, double py);
/* The inverse: film position (px, py) of the point p; 0 when p is behind a perspective camera. */
int rd_camera_project(const rd_camera *cam, vec3 p, double *px, double *py);

#ifdef __cplusplus
}
#endif
#endif /* RD_CAMERA_H */
