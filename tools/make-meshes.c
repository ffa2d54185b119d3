/* make-meshes: writes the closed triangle meshes the surface scenes use (issue 14), as OBJ
 * with per-vertex normals, counter-clockwise seen from outside:
 *
 *   make-meshes icosphere LEVEL OUT.obj      unit-radius icosphere: the icosahedron's 20
 *                                            faces split in 4 LEVEL times (20 4^LEVEL triangles),
 *                                            new vertices pushed onto the sphere
 *   make-meshes displaced LEVEL OUT.obj      the icosphere with radius
 *                                            r(x) = 1 + 0.12 sin(3x) sin(4y + 1) sin(5z + 2)
 *                                            (a smooth lumpy blob, star-shaped so still closed
 *                                            and free of self-intersection)
 *   make-meshes knot RINGS SIDES OUT.obj     a (2,3) torus knot tube: centre line
 *                                            ((1 + 0.45 cos 3t) cos 2t, (1 + 0.45 cos 3t) sin 2t,
 *                                            0.45 sin 3t), tube radius 0.14, RINGS rings of SIDES
 *                                            vertices
 *   make-meshes box OUT.obj                  the cube [-1,1]^3, 12 flat triangles (no vertex
 *                                            normals): a floor or a block when scaled
 *   make-meshes wall X0 X1 Y0 Y1 OUT.obj     the slab [-1,1]^2 x [-1,1] (x, y, then z the
 *                                            thickness) with a rectangular hole through it,
 *                                            [X0,X1] x [Y0,Y1] strictly inside (-1,1)^2: a wall
 *                                            with a window, 32 flat triangles. Each face of the
 *                                            slab is a ring of 4 trapezoids between the outer
 *                                            and the hole's corners, so no edge has a T-junction
 *                                            and the mesh is closed (genus 1)
 *
 * Deterministic (no random numbers): the same arguments write the same bytes. Used by
 * scripts/make-meshes.sh; `make tools` builds it. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

typedef struct { double x, y, z; } v3;
static v3 mk(double x, double y, double z) { v3 r = {x, y, z}; return r; }
static v3 add(v3 a, v3 b) { return mk(a.x + b.x, a.y + b.y, a.z + b.z); }
static v3 sub(v3 a, v3 b) { return mk(a.x - b.x, a.y - b.y, a.z - b.z); }
static v3 scl(v3 a, double s) { return mk(a.x * s, a.y * s, a.z * s); }
static double dot(v3 a, v3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static v3 cross(v3 a, v3 b) { return mk(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x); }
static v3 norm(v3 a) { double l = sqrt(dot(a, a)); return l > 0 ? scl(a, 1.0 / l) : a; }

typedef struct {
    v3 *p, *n;
    int nv, capv;
    int *t; /* 3 per triangle */
    int nt, capt;
} mesh;

static void *grow(void *a, int *cap, int need, size_t size)
{
    if (need <= *cap) return a;
    int c = *cap ? *cap : 64;
    while (c < need) c *= 2;
    void *b = realloc(a, (size_t)c * size);
    if (!b) { fprintf(stderr, "make-meshes: out of memory\n"); exit(1); }
    *cap = c;
    return b;
}
static int vert(mesh *m, v3 p)
{
    int capn = m->capv;
    m->p = grow(m->p, &m->capv, m->nv + 1, sizeof *m->p);
    m->n = grow(m->n, &capn, m->nv + 1, sizeof *m->n);
    m->p[m->nv] = p;
    return m->nv++;
}
static void tri(mesh *m, int a, int b, int c)
{
    m->t = grow(m->t, &m->capt, 3 * (m->nt + 1), sizeof *m->t);
    m->t[3 * m->nt] = a, m->t[3 * m->nt + 1] = b, m->t[3 * m->nt + 2] = c;
    m->nt++;
}

/* The icosphere: the icosahedron, each face split into 4 `level` times; a midpoint shared by
 * two faces is made once (found through a table keyed by the edge). */
static int midpoint(mesh *m, int *table, int cap, int a, int b)
{
    int lo = a < b ? a : b, hi = a < b ? b : a;
    unsigned h = (unsigned)lo * 73856093u ^ (unsigned)hi * 19349663u;
    for (unsigned k = h % (unsigned)cap;; k = (k + 1) % (unsigned)cap) {
        int *e = table + 3 * k;
        if (e[0] < 0) {
            e[0] = lo, e[1] = hi;
            e[2] = vert(m, norm(scl(add(m->p[lo], m->p[hi]), 0.5)));
            return e[2];
        }
        if (e[0] == lo && e[1] == hi) return e[2];
    }
}

static void icosphere(mesh *m, int level)
{
    double f = (1.0 + sqrt(5.0)) / 2.0;
    const double P[12][3] = {{-1, f, 0}, {1, f, 0}, {-1, -f, 0}, {1, -f, 0}, {0, -1, f}, {0, 1, f},
                             {0, -1, -f}, {0, 1, -f}, {f, 0, -1}, {f, 0, 1}, {-f, 0, -1}, {-f, 0, 1}};
    const int F[20][3] = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                          {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                          {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    for (int i = 0; i < 12; i++) vert(m, norm(mk(P[i][0], P[i][1], P[i][2])));
    for (int i = 0; i < 20; i++) tri(m, F[i][0], F[i][1], F[i][2]);
    for (int l = 0; l < level; l++) {
        int cap = 6 * m->nt + 1;
        int *table = malloc((size_t)cap * 3 * sizeof *table);
        int *old = malloc((size_t)m->nt * 3 * sizeof *old), n = m->nt;
        if (!table || !old) { fprintf(stderr, "make-meshes: out of memory\n"); exit(1); }
        for (int i = 0; i < 3 * cap; i++) table[i] = -1;
        memcpy(old, m->t, (size_t)n * 3 * sizeof *old);
        m->nt = 0;
        for (int i = 0; i < n; i++) {
            int a = old[3 * i], b = old[3 * i + 1], c = old[3 * i + 2];
            int ab = midpoint(m, table, cap, a, b), bc = midpoint(m, table, cap, b, c), ca = midpoint(m, table, cap, c, a);
            tri(m, a, ab, ca), tri(m, b, bc, ab), tri(m, c, ca, bc), tri(m, ab, bc, ca);
        }
        free(table);
        free(old);
    }
}

/* Area-weighted vertex normals (the face normals' sum, normalised). */
static void vertex_normals(mesh *m)
{
    for (int i = 0; i < m->nv; i++) m->n[i] = mk(0, 0, 0);
    for (int i = 0; i < m->nt; i++) {
        int *t = m->t + 3 * i;
        v3 fn = cross(sub(m->p[t[1]], m->p[t[0]]), sub(m->p[t[2]], m->p[t[0]]));
        for (int k = 0; k < 3; k++) m->n[t[k]] = add(m->n[t[k]], fn);
    }
    for (int i = 0; i < m->nv; i++) m->n[i] = norm(m->n[i]);
}

/* The (2,3) torus knot's centre line and its derivative. */
static v3 knot(double t)
{
    double r = 1.0 + 0.45 * cos(3 * t);
    return mk(r * cos(2 * t), r * sin(2 * t), 0.45 * sin(3 * t));
}

static void knot_tube(mesh *m, int rings, int sides)
{
    const double tube = 0.14;
    for (int i = 0; i < rings; i++) {
        double t = 2.0 * M_PI * i / rings, h = 1e-5;
        v3 c = knot(t), T = norm(sub(knot(t + h), knot(t - h)));
        /* Frame: N from the offset of the centre line from the torus' core circle (never
         * parallel to T: it lies in the meridian plane, and T has an azimuthal part), so the
         * frame is a periodic function of t and the tube closes on itself. */
        v3 core = mk(cos(2 * t), sin(2 * t), 0);
        v3 off = sub(c, core);
        v3 N = norm(sub(off, scl(T, dot(off, T)))), B = cross(T, N);
        for (int j = 0; j < sides; j++) {
            double a = 2.0 * M_PI * j / sides;
            v3 dir = add(scl(N, cos(a)), scl(B, sin(a)));
            int v = vert(m, add(c, scl(dir, tube)));
            m->n[v] = dir;
        }
    }
    for (int i = 0; i < rings; i++)
        for (int j = 0; j < sides; j++) {
            int i1 = (i + 1) % rings, j1 = (j + 1) % sides;
            int a = i * sides + j, b = i1 * sides + j, c = i1 * sides + j1, d = i * sides + j1;
            /* Counter-clockwise seen from outside: (T, dir_j, dir_j1) is right-handed. */
            tri(m, a, d, c), tri(m, a, c, b);
        }
}

/* A flat quad a-b-c-d (a convex polygon in that order) as two triangles, wound so that its
 * normal points along `out` (the solid's outside). */
static void quad(mesh *m, int a, int b, int c, int d, v3 out)
{
    v3 n = cross(sub(m->p[b], m->p[a]), sub(m->p[c], m->p[a]));
    if (dot(n, out) > 0)
        tri(m, a, b, c), tri(m, a, c, d);
    else
        tri(m, a, c, b), tri(m, a, d, c);
}

static void box(mesh *m)
{
    for (int i = 0; i < 8; i++) vert(m, mk(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1));
    /* Faces x = -1, +1; y = -1, +1; z = -1, +1: corners in order around each face. */
    quad(m, 0, 2, 6, 4, mk(-1, 0, 0)), quad(m, 1, 3, 7, 5, mk(1, 0, 0));
    quad(m, 0, 1, 5, 4, mk(0, -1, 0)), quad(m, 2, 3, 7, 6, mk(0, 1, 0));
    quad(m, 0, 1, 3, 2, mk(0, 0, -1)), quad(m, 4, 5, 7, 6, mk(0, 0, 1));
}

static void wall(mesh *m, double x0, double x1, double y0, double y1)
{
    /* Outer corners O_i and hole corners H_i, counter-clockwise seen from +z, on both faces
     * (f = 0: z = +1, f = 1: z = -1). */
    const double ox[4] = {-1, 1, 1, -1}, oy[4] = {-1, -1, 1, 1};
    const double hx[4] = {x0, x1, x1, x0}, hy[4] = {y0, y0, y1, y1};
    int O[2][4], H[2][4];
    for (int f = 0; f < 2; f++)
        for (int i = 0; i < 4; i++) {
            double z = f ? -1 : 1;
            O[f][i] = vert(m, mk(ox[i], oy[i], z));
            H[f][i] = vert(m, mk(hx[i], hy[i], z));
        }
    v3 hc = mk(0.5 * (x0 + x1), 0.5 * (y0 + y1), 0);
    for (int i = 0; i < 4; i++) {
        int j = (i + 1) % 4;
        /* The two faces: trapezoid O_i O_j H_j H_i, outward +z and -z. */
        quad(m, O[0][i], O[0][j], H[0][j], H[0][i], mk(0, 0, 1));
        quad(m, O[1][i], O[1][j], H[1][j], H[1][i], mk(0, 0, -1));
        /* Outer side i: outward away from the slab's centre. */
        v3 mid = scl(add(m->p[O[0][i]], m->p[O[0][j]]), 0.5);
        quad(m, O[0][i], O[0][j], O[1][j], O[1][i], mk(mid.x, mid.y, 0));
        /* Hole side i: outward (away from the solid) is toward the hole's centre. */
        v3 hm = scl(add(m->p[H[0][i]], m->p[H[0][j]]), 0.5);
        quad(m, H[0][i], H[0][j], H[1][j], H[1][i], sub(hc, mk(hm.x, hm.y, 0)));
    }
}

static int write_obj(const mesh *m, const char *path, const char *what, int flat)
{
    FILE *f = fopen(path, "w");
    if (!f) { perror(path); return 1; }
    fprintf(f, "# %s, written by tools/make-meshes.c (scripts/make-meshes.sh)\n", what);
    fprintf(f, "# %d vertices, %d triangles, counter-clockwise seen from outside\n", m->nv, m->nt);
    for (int i = 0; i < m->nv; i++) fprintf(f, "v %.7g %.7g %.7g\n", m->p[i].x, m->p[i].y, m->p[i].z);
    if (flat) /* no vertex normals: the renderer shades with the faces' own */
        for (int i = 0; i < m->nt; i++) fprintf(f, "f %d %d %d\n", m->t[3 * i] + 1, m->t[3 * i + 1] + 1, m->t[3 * i + 2] + 1);
    else {
        for (int i = 0; i < m->nv; i++) fprintf(f, "vn %.6f %.6f %.6f\n", m->n[i].x, m->n[i].y, m->n[i].z);
        for (int i = 0; i < m->nt; i++) {
            int a = m->t[3 * i] + 1, b = m->t[3 * i + 1] + 1, c = m->t[3 * i + 2] + 1;
            fprintf(f, "f %d//%d %d//%d %d//%d\n", a, a, b, b, c, c);
        }
    }
    if (fclose(f) != 0) { perror(path); return 1; }
    return 0;
}

static int usage(void)
{
    fprintf(stderr, "usage: make-meshes icosphere LEVEL OUT.obj | displaced LEVEL OUT.obj | knot RINGS SIDES OUT.obj\n"
                    "       | box OUT.obj | wall X0 X1 Y0 Y1 OUT.obj\n"
                    "  LEVEL in [0, 7]; RINGS in [3, 4096], SIDES in [3, 256]; -1 < X0 < X1 < 1, -1 < Y0 < Y1 < 1\n");
    return 2;
}

int main(int argc, char **argv)
{
    mesh m;
    memset(&m, 0, sizeof m);
    char what[128];
    if (argc == 4 && (strcmp(argv[1], "icosphere") == 0 || strcmp(argv[1], "displaced") == 0)) {
        int level = atoi(argv[2]);
        if (level < 0 || level > 7) return usage();
        icosphere(&m, level);
        if (argv[1][0] == 'd') {
            for (int i = 0; i < m.nv; i++) {
                v3 p = m.p[i];
                double r = 1.0 + 0.12 * sin(3 * p.x) * sin(4 * p.y + 1) * sin(5 * p.z + 2);
                m.p[i] = scl(p, r);
            }
            vertex_normals(&m);
            snprintf(what, sizeof what, "displaced icosphere, level %d", level);
        } else {
            for (int i = 0; i < m.nv; i++) m.n[i] = m.p[i];
            snprintf(what, sizeof what, "unit icosphere, level %d", level);
        }
        return write_obj(&m, argv[3], what, 0);
    }
    if (argc == 5 && strcmp(argv[1], "knot") == 0) {
        int rings = atoi(argv[2]), sides = atoi(argv[3]);
        if (rings < 3 || rings > 4096 || sides < 3 || sides > 256) return usage();
        knot_tube(&m, rings, sides);
        snprintf(what, sizeof what, "(2,3) torus knot tube, %d rings of %d", rings, sides);
        return write_obj(&m, argv[4], what, 0);
    }
    if (argc == 3 && strcmp(argv[1], "box") == 0) {
        box(&m);
        return write_obj(&m, argv[2], "cube [-1,1]^3, flat", 1);
    }
    if (argc == 7 && strcmp(argv[1], "wall") == 0) {
        double x0 = atof(argv[2]), x1 = atof(argv[3]), y0 = atof(argv[4]), y1 = atof(argv[5]);
        if (!(-1 < x0 && x0 < x1 && x1 < 1 && -1 < y0 && y0 < y1 && y1 < 1)) return usage();
        wall(&m, x0, x1, y0, y1);
        snprintf(what, sizeof what, "slab [-1,1]^3 with the hole [%g,%g] x [%g,%g] through z, flat", x0, x1, y0, y1);
        return write_obj(&m, argv[6], what, 1);
    }
    return usage();
}
