/* camera.c: the pinhole (perspective) and orthographic cameras: the primary ray through a film
 * position, and its inverse, the film position of a point (for the photon picture of the bake).
 * The film plane has x to the right and y down, (0, 0) at the top-left corner; a perspective
 * camera's half-height at unit distance is tan(fov / 2). */
#include "scene/rd_scene.h"

ray3 rd_camera_ray(const rd_camera *cam, double px, double py)
{
    /* Film plane: x to the right, y down; sx, sy in [-1, 1] scaled by the aspect ratio. */
    double aspect = (double)cam->width / cam->height;
    double sx = (2.0 * px / cam->width - 1.0) * aspect;
    double sy = 1.0 - 2.0 * py / cam->height;
    ray3 r;
    if (cam->kind == RD_CAM_PERSPECTIVE) {
        double th = cam->tan_half_fov;
        r.o = cam->pos;
        r.d = v3_norm(v3_add(cam->forward, v3_add(v3_scale(cam->right, sx * th), v3_scale(cam->up, sy * th))));
    } else {
        double half = 0.5 * cam->ortho_width / aspect; /* half the view height */
        r.o = v3_add(cam->pos, v3_add(v3_scale(cam->right, sx * half), v3_scale(cam->up, sy * half)));
        r.d = cam->forward;
    }
    return r;
}

int rd_camera_project(const rd_camera *cam, vec3 p, double *px, double *py)
{
    /* The inverse of rd_camera_ray: film coordinates of the point p. */
    double aspect = (double)cam->width / cam->height, sx, sy;
    vec3 v = v3_sub(p, cam->pos);
    if (cam->kind == RD_CAM_PERSPECTIVE) {
        double z = v3_dot(v, cam->forward), th = cam->tan_half_fov;
        if (!(z > 0.0)) return 0;
        sx = v3_dot(v, cam->right) / (z * th);
        sy = v3_dot(v, cam->up) / (z * th);
    } else {
        double half = 0.5 * cam->ortho_width / aspect;
        sx = v3_dot(v, cam->right) / half;
        sy = v3_dot(v, cam->up) / half;
    }
    *px = (sx / aspect + 1.0) * 0.5 * cam->width;
    *py = (1.0 - sy) * 0.5 * cam->height;
    return isfinite(*px) && isfinite(*py);
}

