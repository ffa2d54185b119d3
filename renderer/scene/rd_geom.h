/* rd_geom.h: surfaces (issue 14): triangle meshes loaded through assimp, their materials, and
 * one Embree scene that answers "what does this ray hit first" for every shape and sphere
 * light. Internal to renderer/ (tests include it too); the transport (integrators, photon
 * tracing, free-path engine per medium interval) is wired to it in a later step:
 * docs/surfaces.md has the design note.
 *
 * Units: lengths in scene units (metres), angles in degrees where the scene gives them.
 * Directions are unit vectors. Conventions of this header:
 *   - A surface's FRONT side is the side its geometric normal points to. Triangles are
 *     counter-clockwise seen from the front; for a closed mesh the front is the OUTSIDE (the
 *     loader reverses a closed mesh whose winding points inward).
 *   - Paths are described by their direction of TRAVEL: `d` arrives at the surface, the
 *     sampled direction leaves it (pbrt's wo/wi point away from the surface; here both follow
 *     the path, as the phase-function code does, rd_hg_sample).
 * Errors: status + a one-line message in the caller's buffer (see each function). */
#ifndef RD_GEOM_H
#define RD_GEOM_H

#include "scene/rd_scene.h"

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- Transforms ---------------------------------------------------------------------------- *
 * A shape's placement (scene key shapes[i].transform): scale, then rotate about an axis
 * through the origin, then translate:
 *     p' = translate + R(axis, angle) (scale * p)      (scale per axis, each > 0)
 * R is the right-handed rotation by `angle_deg` degrees about the unit `axis` (Rodrigues'
 * formula): counter-clockwise when the axis points at the viewer. */
typedef struct {
    vec3 scale;       /* > 0 on every axis (a mirroring scale would turn meshes inside out) */
    vec3 axis;        /* unit rotation axis */
    double angle_deg; /* rotation angle in degrees */
    vec3 translate;
} rd_transform;

/* The identity transform. */
rd_transform rd_transform_identity(void);
/* p' = translate + R (scale * p). */
vec3 rd_transform_point(const rd_transform *xf, vec3 p);
/* A normal transformed by the inverse transpose, R (n / scale), renormalised. */
vec3 rd_transform_normal(const rd_transform *xf, vec3 n);

/* ---- Meshes -------------------------------------------------------------------------------- */
typedef struct {
    size_t n_vertices, n_triangles;
    float *positions;   /* 3 n_vertices, world space (transform applied); owned */
    float *normals;     /* 3 n_vertices unit shading normals from the file, or NULL; owned */
    uint32_t *indices;  /* 3 n_triangles vertex indices, counter-clockwise seen from the
                         * front; owned */
    int closed;         /* 1: every edge (vertices welded by position) is shared by exactly two
                         * triangles that traverse it in opposite directions: a closed,
                         * consistently oriented surface with an inside */
    size_t open_edges;  /* edges that break that rule (0 when closed) */
    int flipped;        /* 1: the file's winding pointed inward (negative signed volume) and was
                         * reversed at load so the front is the outside */
    double volume;      /* enclosed volume (divergence theorem; meaningful when closed) */
    vec3 bmin, bmax;    /* bounds of the positions */
} rd_mesh;

/* Load an OBJ or PLY file (any format assimp reads) into `m` and place it with `xf` (NULL:
 * identity). assimp post-processing: triangulate, join identical vertices, flatten the node
 * hierarchy (node transforms applied), sort out points and lines (ignored). Every mesh of the
 * file goes into one triangle list; degenerate triangles (two equal welded corners) are
 * dropped. Closedness and orientation are computed on vertices welded by exact position (a
 * seam where the file splits a vertex for its normals or texture coordinates is not a hole).
 * Errors (message in err, no file prefix of the scene; the caller adds the JSON path):
 *   RD_ERR_IO     "PATH: no such file" (or the system's reason)
 *   RD_ERR_FORMAT "PATH: not a mesh assimp can read (...)", "PATH: no triangles",
 *                 "PATH: non-finite vertex", "PATH: more than 2^31 vertices"
 *   RD_ERR_NOMEM
 * On error `m` is left empty (rd_mesh_free-safe). */
rd_status rd_mesh_load(const char *path, const rd_transform *xf, rd_mesh *m, char *err,
                       size_t errlen);
/* Build a mesh from arrays (copied; positions in world space, no transform) and compute
 * closedness, orientation (reversing an inward closed mesh), volume and bounds, as
 * rd_mesh_load does. `normals` may be NULL. RD_ERR_FORMAT "no triangles" / an index out of
 * range; RD_ERR_NOMEM. For tests and generated geometry. */
rd_status rd_mesh_from_arrays(const float *positions, size_t n_vertices, const float *normals,
                              const uint32_t *indices, size_t n_triangles, rd_mesh *m, char *err,
                              size_t errlen);
/* Free what the mesh owns and zero it; safe on a zeroed mesh. */
void rd_mesh_free(rd_mesh *m);

/* ---- Materials ----------------------------------------------------------------------------- */
typedef enum {
    RD_MAT_INTERFACE,  /* no scattering: the path goes straight on and only its medium changes
                        * (an index-matched boundary) */
    RD_MAT_DIELECTRIC, /* smooth dielectric: Fresnel reflection or refraction */
    RD_MAT_DIFFUSE     /* Lambertian reflector (opaque: no transmission) */
} rd_material_kind;

typedef struct {
    rd_material_kind kind;
    double ior;   /* dielectric: relative index of refraction n_inside / n_outside, in [0.25, 4]
                   * (the media carry no index of their own); 1 is invisible */
    vec3 albedo;  /* diffuse: reflectance per channel, in [0, 1] */
} rd_material;

/* Which quantity a path carries (Veach 1997, ch. 5; pbrt-v4 TransportMode). A camera path
 * carries RADIANCE weights: refraction from index n_i into n_t multiplies them by
 * (n_i / n_t)^2, because radiance divided by n^2 is what is conserved along a refracted beam
 * (Veach eq. 5.13; the BTDF is not symmetric, Veach §5.2: f_t(wi->wo) / n_o^2 =
 * f_t(wo->wi) / n_i^2). A photon carries IMPORTANCE-mode weights, i.e. flux: the beam's power
 * is only split between reflection and refraction, so refraction scales it by (1 - F) alone
 * and the sampled weight is 1 (the adjoint BTDF has no 1/eta^2, Veach eq. 5.14). The two
 * agree: a photon map inside glass estimates flux per solid angle and area there, which is the
 * radiance inside (n^2 times larger), and a camera path that enters the glass scales what it
 * finds there by (1/n)^2. */
typedef enum { RD_TRANSPORT_RADIANCE, RD_TRANSPORT_IMPORTANCE } rd_transport;

/* One sampled scattering event at a surface. */
typedef struct {
    vec3 d;        /* the new direction of travel, unit */
    vec3 weight;   /* f(d_in, d) |cos(n, d)| / pdf, times the mode's factor above: the factor
                    * the path's throughput is multiplied by. Dielectric: 1 for a reflection,
                    * 1 (IMPORTANCE) or (n_i / n_t)^2 (RADIANCE) for a refraction, because the
                    * event is chosen with its Fresnel probability; interface: 1; diffuse:
                    * the albedo (f = albedo/pi, pdf = cos/pi) */
    double pdf;    /* diffuse: solid-angle pdf cos/pi of d; specular events: the discrete
                    * probability of the chosen event (F, 1 - F or 1) */
    int specular;  /* 1: a delta distribution (dielectric, interface): no light sampling
                    * (next-event estimation) can produce d, so no MIS */
    int crossed;   /* 1: the path went through to the other side (refraction, interface):
                    * its medium changes from the side it came from to the other */
} rd_surface_sample;

/* Fresnel reflectance of a smooth dielectric boundary for unpolarised light (Born & Wolf
 * §1.5.3; pbrt-v4 FrDielectric): cos_i = cosine of the angle of incidence, in [0, 1], and
 * eta = n_t / n_i (the index of the side the light goes into over the side it comes from).
 *     sin_t = sin_i / eta (Snell); F = 1 when sin_t >= 1 (total internal reflection), else
 *     r_par  = (eta cos_i - cos_t) / (eta cos_i + cos_t),
 *     r_perp = (cos_i - eta cos_t) / (cos_i + eta cos_t),   F = (r_par^2 + r_perp^2) / 2.
 * F(1, eta) = ((eta - 1)/(eta + 1))^2; 1 - F is the transmittance (no absorption). */
double rd_fresnel_dielectric(double cos_i, double eta);

/* Snell refraction of the travel direction d (unit) at a surface with unit normal n (either
 * orientation) into a side of relative index eta = n_t / n_i. Returns 0 on total internal
 * reflection, else 1 with *t the unit refracted direction of travel (on the far side of the
 * surface from d's origin, in the plane of d and n, sin_t = sin_i / eta). */
int rd_refract(vec3 d, vec3 n, double eta, vec3 *t);

/* Mirror reflection of the travel direction d about the surface with unit normal n. */
vec3 rd_reflect(vec3 d, vec3 n);

/* Sample the scattering of a path travelling along d (unit) that meets a surface of material
 * m with geometric normal ng (unit, pointing to the front = outside) and shading normal ns
 * (unit; pass ng for flat shading). `u_event` chooses the event (dielectric: reflect when
 * u_event < F), (u1, u2) the diffuse direction; all three uniform in [0, 1).
 * The side the path comes from is decided by ng (front when dot(d, ng) < 0); the dielectric's
 * relative index is eta = ior arriving from the front, 1/ior from the back, and the Fresnel
 * term and the directions use ns turned to ng's side. Diffuse reflects into the hemisphere
 * of ng the path came from (cosine-weighted around it; the geometric normal only).
 * Returns 0 when nothing leaves (a shading normal that sends the sampled direction to the
 * wrong side of ng: the path ends rather than leak through the surface; d parallel to the
 * surface), else 1 and *s as documented at rd_surface_sample. */
int rd_material_sample(const rd_material *m, vec3 d, vec3 ng, vec3 ns, rd_transport mode,
                       double u_event, double u1, double u2, rd_surface_sample *s);

/* BSDF value f(d_in -> d_out) for the non-specular part (diffuse: albedo/pi when d_out leaves
 * on the side d_in came from, else 0; interface and dielectric: 0, they are pure deltas), and
 * the solid-angle pdf rd_material_sample gives d_out (cos/pi on that side, else 0). For
 * next-event estimation at a diffuse surface. */
vec3 rd_material_eval(const rd_material *m, vec3 d_in, vec3 d_out, vec3 ng, double *pdf);

/* ---- Shapes in a scene --------------------------------------------------------------------- */
/* A shape (scene key shapes[i]): a mesh, its material, and the media on its two sides
 * (pbrt-v4's MediumInterface): `inside` behind the front (the enclosed volume of a closed
 * mesh), `outside` in front of it. -1 means no medium (vacuum). */
typedef struct rd_shape {
    char name[64];
    char file[2048];      /* the mesh file as resolved (relative to the scene's folder) */
    rd_mesh mesh;
    rd_material material;
    int inside, outside;  /* medium indices into rd_scene.media, or -1 */
} rd_shape;

/* Whether media[i] is bound to surfaces: named by some shape's inside/outside or by the
 * scene-wide "medium". A bound medium exists only where the surfaces say (the path tracks it
 * across boundaries); its bounds still bound its density (0 outside them). A medium that is
 * not bound is a box medium as before: it fills its bounds. */
int rd_scene_medium_bound(const rd_scene *s, int i);

/* ---- Ray queries: one Embree scene for all shapes and sphere lights -------------------------- */
typedef struct rd_geom rd_geom; /* opaque */

/* What a ray met. Exactly one of shape / light is >= 0 after a hit. */
struct rd_hit {
    double t;            /* distance along the (unit-direction) ray, in double precision:
                          * recomputed from the float geometry Embree found (below) */
    vec3 p;              /* the hit point o + t d */
    int shape;           /* index into rd_scene.shapes, or -1 */
    int light;           /* index into rd_scene.lights (a sphere light), or -1 */
    uint32_t prim;       /* triangle index within the shape's mesh */
    double b1, b2;       /* barycentric coordinates of the hit (weights of corners 1 and 2) */
    vec3 ng;             /* unit geometric normal: the triangle's front (outside); for a sphere
                          * light the outward normal */
    vec3 ns;             /* unit shading normal (interpolated vertex normals, turned to ng's
                          * side; ng when the mesh has none) */
    int front;           /* 1: the ray arrived on the front side (dot(d, ng) < 0) */
    int medium_from;     /* medium on the side the ray arrived from (index or -1) */
    int medium_to;       /* medium on the other side (index or -1); equal for lights */
    double eps;          /* the spawn offset for this hit (rd_hit_spawn) */
};

/* Build the Embree scene of s's shapes (one triangle geometry each) and sphere lights (one
 * user geometry each, intersected in double precision by rd_light_hit, so lights are hit
 * exactly as rd_scene_hit_light finds them). Returns NULL with a message on failure (Embree
 * device error, out of memory). The geometry holds copies; s must outlive it only for
 * rd_geom_intersect's medium and light lookups. */
rd_geom *rd_geom_build(const rd_scene *s, char *err, size_t errlen);
void rd_geom_free(rd_geom *g);

/* The nearest surface r (r.d unit) meets with t in (tmin, tmax): returns 1 and fills *h, or 0.
 * `from` (may be NULL) is the hit the ray leaves from (it was spawned by rd_hit_spawn): its
 * triangle is ignored, which is exact (a ray leaving a flat triangle cannot meet it again) and
 * removes the self-intersection that float round-off would otherwise cause; a sphere light is
 * never hit from its inside. Thread-safe: any number of threads may query one rd_geom at
 * once (Embree's rtcIntersect1 on a committed scene, a context on each caller's stack). */
int rd_geom_intersect(const rd_geom *g, ray3 r, double tmin, double tmax, const rd_hit *from,
                      rd_hit *h);
/* 1 when some surface lies on r with t in (tmin, tmax) (`from` as above). Thread-safe. */
int rd_geom_occluded(const rd_geom *g, ray3 r, double tmin, double tmax, const rd_hit *from);

/* The ray leaving hit h in direction d (unit): its origin is h->p moved by h->eps along ng to
 * d's side of the surface. Embree intersects in float: the spawn point rounded to float lies
 * up to 2^-24 |p| (per coordinate) off the double point, and the triangle's float plane test
 * errs by a few ulps of the coordinates. h->eps = 2^-16 max(1, |p|_inf, |o|_inf, t) (the
 * origin o of the arriving ray), i.e. 2^8 float ulps of the largest coordinate involved, far
 * above both errors and far below any feature a scene in metres has (1e-5 m at 1 m), so the
 * next ray starts strictly on d's side of every triangle meeting at h->p: it does not re-hit
 * the neighbours of the triangle it leaves (which `from` cannot skip). */
ray3 rd_hit_spawn(const rd_hit *h, vec3 d);

/* Embree's build statistics for info and tests. */
size_t rd_geom_triangles(const rd_geom *g);

#ifdef __cplusplus
}
#endif
#endif /* RD_GEOM_H */
