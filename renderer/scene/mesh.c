/* mesh.c: triangle meshes from OBJ and PLY files through assimp's C API (assimp/cimport.h),
 * placed by a shape's transform; closedness and orientation for media bounded by meshes
 * (rd_geom.h). */
#include "scene/rd_geom.h"

#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* ---- transforms -------------------------------------------------------------------------- */
rd_transform rd_transform_identity(void)
{
    rd_transform xf = {v3(1, 1, 1), v3(0, 0, 1), 0.0, v3(0, 0, 0)};
    return xf;
}

/* Rodrigues' rotation formula: R v = v cos a + (k x v) sin a + k (k . v)(1 - cos a). */
static vec3 rotate(const rd_transform *xf, vec3 v)
{
    if (xf->angle_deg == 0.0) return v;
    double a = xf->angle_deg * M_PI / 180.0, c = cos(a), s = sin(a);
    vec3 k = xf->axis;
    return v3_add(v3_add(v3_scale(v, c), v3_scale(v3_cross(k, v), s)), v3_scale(k, v3_dot(k, v) * (1.0 - c)));
}

vec3 rd_transform_point(const rd_transform *xf, vec3 p)
{
    return v3_add(xf->translate, rotate(xf, v3_mul(xf->scale, p)));
}

vec3 rd_transform_normal(const rd_transform *xf, vec3 n)
{
    /* (R S)^-T = R S^-1 for a rotation R and a diagonal S. */
    return v3_norm(rotate(xf, v3(n.x / xf->scale.x, n.y / xf->scale.y, n.z / xf->scale.z)));
}

void rd_mesh_free(rd_mesh *m)
{
    if (!m) return;
    free(m->positions);
    free(m->normals);
    free(m->indices);
    memset(m, 0, sizeof *m);
}

/* ---- topology: weld by position, drop degenerate triangles, closedness, orientation ------- */
/* A vertex's position and index, sorted by position to weld (no qsort context needed). */
typedef struct { float p[3]; uint32_t i; } keyed_vertex;
static int cmp_pos(const void *a, const void *b)
{
    const keyed_vertex *u = a, *w = b;
    for (int k = 0; k < 3; k++)
        if (u->p[k] != w->p[k]) return u->p[k] < w->p[k] ? -1 : 1;
    return 0;
}

typedef struct { uint32_t lo, hi; int dir; } edge;
static int cmp_edge(const void *a, const void *b)
{
    const edge *e = a, *f = b;
    if (e->lo != f->lo) return e->lo < f->lo ? -1 : 1;
    if (e->hi != f->hi) return e->hi < f->hi ? -1 : 1;
    return e->dir - f->dir;
}

static rd_status finish_mesh(rd_mesh *m, const char *what, char *err, size_t errlen)
{
    size_t nv = m->n_vertices;
    for (size_t i = 0; i < 3 * nv; i++)
        if (!isfinite(m->positions[i])) {
            snprintf(err, errlen, "%s: non-finite vertex", what);
            return RD_ERR_FORMAT;
        }
    /* Weld: weld[i] = the smallest index of a vertex at exactly the same position. */
    keyed_vertex *order = malloc((nv ? nv : 1) * sizeof *order);
    uint32_t *weld = malloc((nv ? nv : 1) * sizeof *weld);
    if (!order || !weld) {
        free(order), free(weld);
        return RD_ERR_NOMEM;
    }
    for (size_t i = 0; i < nv; i++) {
        memcpy(order[i].p, m->positions + 3 * i, sizeof order[i].p);
        order[i].i = (uint32_t)i;
    }
    qsort(order, nv, sizeof *order, cmp_pos);
    for (size_t i = 0; i < nv;) {
        size_t j = i;
        uint32_t rep = order[i].i;
        while (j < nv && cmp_pos(&order[i], &order[j]) == 0) {
            if (order[j].i < rep) rep = order[j].i;
            j++;
        }
        for (size_t k = i; k < j; k++) weld[order[k].i] = rep;
        i = j;
    }
    free(order);
    /* Drop triangles with two equal welded corners (no area, no edges of their own). */
    size_t nt = 0;
    for (size_t t = 0; t < m->n_triangles; t++) {
        uint32_t *v = m->indices + 3 * t;
        uint32_t a = weld[v[0]], b = weld[v[1]], c = weld[v[2]];
        if (a == b || b == c || a == c) continue;
        memmove(m->indices + 3 * nt, v, 3 * sizeof *v);
        nt++;
    }
    m->n_triangles = nt;
    if (nt == 0) {
        free(weld);
        snprintf(err, errlen, "%s: no triangles", what);
        return RD_ERR_FORMAT;
    }
    /* Closed and consistently oriented: every undirected edge appears exactly twice, once in
     * each direction (a 2-manifold without boundary whose triangles agree on the winding). */
    edge *e = malloc(3 * nt * sizeof *e);
    if (!e) {
        free(weld);
        return RD_ERR_NOMEM;
    }
    for (size_t t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t a = weld[m->indices[3 * t + k]], b = weld[m->indices[3 * t + (k + 1) % 3]];
            edge x = {a < b ? a : b, a < b ? b : a, a < b ? 0 : 1};
            e[3 * t + k] = x;
        }
    free(weld);
    qsort(e, 3 * nt, sizeof *e, cmp_edge);
    size_t bad = 0;
    for (size_t i = 0; i < 3 * nt;) {
        size_t j = i;
        while (j < 3 * nt && e[j].lo == e[i].lo && e[j].hi == e[i].hi) j++;
        if (!(j - i == 2 && e[i].dir != e[i + 1].dir)) bad++;
        i = j;
    }
    free(e);
    m->open_edges = bad;
    m->closed = bad == 0;
    /* Enclosed volume by the divergence theorem: V = sum over triangles p0 . (p1 x p2) / 6
     * (exact for a closed surface, any origin). */
    double vol = 0.0;
    m->bmin = v3(INFINITY, INFINITY, INFINITY);
    m->bmax = v3(-INFINITY, -INFINITY, -INFINITY);
    for (size_t t = 0; t < nt; t++) {
        vec3 p[3];
        for (int k = 0; k < 3; k++) {
            const float *q = m->positions + 3 * (size_t)m->indices[3 * t + k];
            p[k] = v3(q[0], q[1], q[2]);
        }
        vol += v3_dot(p[0], v3_cross(p[1], p[2])) / 6.0;
    }
    for (size_t i = 0; i < nv; i++) {
        const float *q = m->positions + 3 * i;
        m->bmin = v3(fmin(m->bmin.x, q[0]), fmin(m->bmin.y, q[1]), fmin(m->bmin.z, q[2]));
        m->bmax = v3(fmax(m->bmax.x, q[0]), fmax(m->bmax.y, q[1]), fmax(m->bmax.z, q[2]));
    }
    /* A closed mesh wound inward (negative volume) is reversed so that its front, where the
     * geometric normals point, is the outside. */
    m->flipped = 0;
    if (m->closed && vol < 0.0) {
        for (size_t t = 0; t < nt; t++) {
            uint32_t tmp = m->indices[3 * t + 1];
            m->indices[3 * t + 1] = m->indices[3 * t + 2];
            m->indices[3 * t + 2] = tmp;
        }
        vol = -vol;
        m->flipped = 1;
    }
    m->volume = vol;
    return RD_OK;
}

rd_status rd_mesh_from_arrays(const float *positions, size_t n_vertices, const float *normals,
                              const uint32_t *indices, size_t n_triangles, rd_mesh *m, char *err,
                              size_t errlen)
{
    char dummy[8];
    if (!err) err = dummy, errlen = sizeof dummy;
    memset(m, 0, sizeof *m);
    if (n_triangles == 0 || n_vertices == 0) {
        snprintf(err, errlen, "no triangles");
        return RD_ERR_FORMAT;
    }
    if (n_vertices > 0x7fffffffu) {
        snprintf(err, errlen, "more than 2^31 vertices");
        return RD_ERR_FORMAT;
    }
    for (size_t i = 0; i < 3 * n_triangles; i++)
        if (indices[i] >= n_vertices) {
            snprintf(err, errlen, "triangle %zu: vertex index %u out of range (%zu vertices)", i / 3, indices[i], n_vertices);
            return RD_ERR_FORMAT;
        }
    m->positions = malloc(3 * n_vertices * sizeof *m->positions);
    m->indices = malloc(3 * n_triangles * sizeof *m->indices);
    if (normals) m->normals = malloc(3 * n_vertices * sizeof *m->normals);
    if (!m->positions || !m->indices || (normals && !m->normals)) {
        rd_mesh_free(m);
        return RD_ERR_NOMEM;
    }
    memcpy(m->positions, positions, 3 * n_vertices * sizeof *m->positions);
    memcpy(m->indices, indices, 3 * n_triangles * sizeof *m->indices);
    if (normals) memcpy(m->normals, normals, 3 * n_vertices * sizeof *m->normals);
    m->n_vertices = n_vertices;
    m->n_triangles = n_triangles;
    rd_status st = finish_mesh(m, "mesh", err, errlen);
    if (st) rd_mesh_free(m);
    return st;
}

rd_status rd_mesh_load(const char *path, const rd_transform *xf, rd_mesh *m, char *err,
                       size_t errlen)
{
    char dummy[8];
    if (!err) err = dummy, errlen = sizeof dummy;
    memset(m, 0, sizeof *m);
    rd_transform id = rd_transform_identity();
    if (!xf) xf = &id;
    struct stat sb;
    if (stat(path, &sb) != 0) {
        snprintf(err, errlen, "%s: %s", path, errno == ENOENT ? "no such file" : strerror(errno));
        return RD_ERR_IO;
    }
    if (!S_ISREG(sb.st_mode)) {
        snprintf(err, errlen, "%s: not a regular file", path);
        return RD_ERR_IO;
    }
    /* Triangulate polygons; join identical vertices (an indexed mesh); PreTransformVertices
     * applies the node hierarchy's transforms and merges the nodes' meshes; SortByPType puts
     * points and lines in meshes of their own (skipped below); ValidateDataStructure rejects
     * corrupt imports (out-of-range indices). */
    const unsigned flags = aiProcess_Triangulate | aiProcess_JoinIdenticalVertices | aiProcess_PreTransformVertices |
                           aiProcess_SortByPType | aiProcess_ValidateDataStructure;
    const struct aiScene *sc = aiImportFile(path, flags);
    if (!sc) {
        snprintf(err, errlen, "%s: not a mesh assimp can read (%s)", path, aiGetErrorString());
        return RD_ERR_FORMAT;
    }
    size_t nv = 0, nt = 0;
    int all_normals = 1;
    for (unsigned i = 0; i < sc->mNumMeshes; i++) {
        const struct aiMesh *am = sc->mMeshes[i];
        if (!(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
        nv += am->mNumVertices;
        nt += am->mNumFaces;
        if (!am->mNormals) all_normals = 0;
    }
    if (nt == 0 || nv == 0) {
        aiReleaseImport(sc);
        snprintf(err, errlen, "%s: no triangles", path);
        return RD_ERR_FORMAT;
    }
    if (nv > 0x7fffffffu) {
        aiReleaseImport(sc);
        snprintf(err, errlen, "%s: more than 2^31 vertices", path);
        return RD_ERR_FORMAT;
    }
    m->positions = malloc(3 * nv * sizeof *m->positions);
    m->indices = malloc(3 * nt * sizeof *m->indices);
    if (all_normals) m->normals = malloc(3 * nv * sizeof *m->normals);
    if (!m->positions || !m->indices || (all_normals && !m->normals)) {
        aiReleaseImport(sc);
        rd_mesh_free(m);
        return RD_ERR_NOMEM;
    }
    size_t v0 = 0, t = 0;
    for (unsigned i = 0; i < sc->mNumMeshes; i++) {
        const struct aiMesh *am = sc->mMeshes[i];
        if (!(am->mPrimitiveTypes & aiPrimitiveType_TRIANGLE)) continue;
        for (unsigned k = 0; k < am->mNumVertices; k++) {
            vec3 p = rd_transform_point(xf, v3(am->mVertices[k].x, am->mVertices[k].y, am->mVertices[k].z));
            float *q = m->positions + 3 * (v0 + k);
            q[0] = (float)p.x, q[1] = (float)p.y, q[2] = (float)p.z;
            if (m->normals) {
                vec3 n = rd_transform_normal(xf, v3(am->mNormals[k].x, am->mNormals[k].y, am->mNormals[k].z));
                float *r = m->normals + 3 * (v0 + k);
                r[0] = (float)n.x, r[1] = (float)n.y, r[2] = (float)n.z;
            }
        }
        for (unsigned f = 0; f < am->mNumFaces; f++) {
            const struct aiFace *fc = &am->mFaces[f];
            if (fc->mNumIndices != 3) continue; /* SortByPType: only triangles here */
            for (int k = 0; k < 3; k++) m->indices[3 * t + k] = (uint32_t)(v0 + fc->mIndices[k]);
            t++;
        }
        v0 += am->mNumVertices;
    }
    aiReleaseImport(sc);
    m->n_vertices = nv;
    m->n_triangles = t;
    /* A normal of zero length (a file's placeholder) cannot shade: drop them all. */
    for (size_t i = 0; m->normals && i < nv; i++) {
        const float *r = m->normals + 3 * i;
        if (!(isfinite(r[0]) && isfinite(r[1]) && isfinite(r[2])) || r[0] * r[0] + r[1] * r[1] + r[2] * r[2] < 0.5f) {
            free(m->normals);
            m->normals = NULL;
        }
    }
    rd_status st = finish_mesh(m, path, err, errlen);
    if (st) rd_mesh_free(m);
    return st;
}
