/* pm_file.c: the photon map's .pmap file (docs/photonmap-format.md "The .pmap file"): write
 * (to a stream the caller opened; where it goes, and how it is put in place, is the caller's)
 * and load (header, counts against the
 * file size, records, FNV-1a 64 checksum, then the same value checks as pm_map_add_photons /
 * _add_segments). */
#include <errno.h>
#include <inttypes.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "pm_internal.h"

#define PM_FILE_VERSION 2u   /* 2 added the origin; 1 is still read, with origin 0 */
#define PM_HEADER_BYTES 24u  /* magic, version, photon count, segment count */
#define PM_ORIGIN_BYTES 24u  /* version 2: origin x, y, z as float64 */
#define PM_PHOTON_BYTES 36u  /* 9 float32 */
#define PM_SEGMENT_BYTES 40u /* 10 float32 */
#define PM_CHECKSUM_BYTES 8u /* FNV-1a 64 of everything before it */
#define FNV_OFFSET 0xcbf29ce484222325ULL
#define FNV_PRIME 0x100000001b3ULL

/* The records are written as their in-memory floats; that needs these exact layouts. */
_Static_assert(sizeof(float) == 4, "float must be IEEE-754 binary32");
_Static_assert(sizeof(double) == 8, "double must be IEEE-754 binary64");
_Static_assert(sizeof(pm_photon) == PM_PHOTON_BYTES, "pm_photon must be 9 packed floats");
_Static_assert(sizeof(pm_segment) == PM_SEGMENT_BYTES, "pm_segment must be 10 packed floats");

/* FNV-1a 64 (Fowler, Noll, Vo): h = (h XOR byte) * prime, per byte. */
static uint64_t fnv1a(uint64_t h, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++) {
        h ^= p[i];
        h *= FNV_PRIME;
    }
    return h;
}

static int host_little_endian(void)
{
    const uint32_t one = 1;
    unsigned char b;
    memcpy(&b, &one, 1);
    return b == 1;
}

/* Reverse the bytes of each 4-byte word (float records on a big-endian host). */
static void swap_words(void *data, size_t nwords)
{
    unsigned char *p = data;
    for (size_t i = 0; i < nwords; i++, p += 4) {
        unsigned char t = p[0];
        p[0] = p[3];
        p[3] = t;
        t = p[1];
        p[1] = p[2];
        p[2] = t;
    }
}

static void put_le(unsigned char *p, uint64_t v, int nbytes)
{
    for (int i = 0; i < nbytes; i++)
        p[i] = (unsigned char)(v >> (8 * i));
}

static uint64_t get_le(const unsigned char *p, int nbytes)
{
    uint64_t v = 0;
    for (int i = 0; i < nbytes; i++)
        v |= (uint64_t)p[i] << (8 * i);
    return v;
}

/* The origin as three little-endian IEEE-754 binary64 values. */
static void put_origin(unsigned char *p, const double origin[3])
{
    for (int a = 0; a < 3; a++) {
        uint64_t bits;
        memcpy(&bits, &origin[a], 8);
        put_le(p + 8 * a, bits, 8);
    }
}

static void get_origin(const unsigned char *p, double origin[3])
{
    for (int a = 0; a < 3; a++) {
        uint64_t bits = get_le(p + 8 * a, 8);
        memcpy(&origin[a], &bits, 8);
    }
}

/* Write n bytes of float records in little-endian order, updating the checksum. */
static int write_records(FILE *f, const void *data, size_t n, uint64_t *h)
{
    if (n == 0) /* data may be NULL then */
        return 1;
    if (host_little_endian()) {
        *h = fnv1a(*h, data, n);
        return fwrite(data, 1, n, f) == n;
    }
    unsigned char buf[4096];
    const unsigned char *p = data;
    while (n > 0) {
        size_t m = n < sizeof buf ? n : sizeof buf;
        memcpy(buf, p, m);
        swap_words(buf, m / 4);
        *h = fnv1a(*h, buf, m);
        if (fwrite(buf, 1, m, f) != m)
            return 0;
        p += m;
        n -= m;
    }
    return 1;
}

static void errno_text(int e, char *buf, size_t len)
{
    if (strerror_r(e, buf, len) != 0)
        snprintf(buf, len, "error %d", e);
}

pm_status pm_map_write(const pm_map *map, FILE *f, const char *name, char *err, size_t errlen)
{
    if (map == NULL || f == NULL || name == NULL) {
        pmi_set_err(err, errlen, "pm_map_write: NULL argument");
        return PM_ERR_ARG;
    }
    unsigned char head[PM_HEADER_BYTES + PM_ORIGIN_BYTES];
    memcpy(head, "PMAP", 4);
    put_le(head + 4, PM_FILE_VERSION, 4);
    put_le(head + 8, (uint64_t)map->nph, 8);
    put_le(head + 16, (uint64_t)map->nseg, 8);
    put_origin(head + PM_HEADER_BYTES, map->origin);
    uint64_t h = fnv1a(FNV_OFFSET, head, sizeof head);
    errno = 0;
    int ok = fwrite(head, 1, sizeof head, f) == sizeof head;
    ok = ok && write_records(f, map->ph, map->nph * sizeof(pm_photon), &h);
    ok = ok && write_records(f, map->seg, map->nseg * sizeof(pm_segment), &h);
    unsigned char tail[PM_CHECKSUM_BYTES];
    put_le(tail, h, 8);
    ok = ok && fwrite(tail, 1, sizeof tail, f) == sizeof tail;
    ok = ok && fflush(f) == 0 && !ferror(f);
    if (!ok) {
        char why[128];
        errno_text(errno ? errno : EIO, why, sizeof why);
        pmi_set_err(err, errlen, "%s: write failed: %s", name, why);
        return PM_ERR_IO;
    }
    return PM_OK;
}

/* Read n bytes of float records written little-endian, updating the checksum. */
static int read_records(FILE *f, void *data, size_t n, uint64_t *h)
{
    if (n == 0) /* data may be NULL then */
        return 1;
    if (fread(data, 1, n, f) != n)
        return 0;
    *h = fnv1a(*h, data, n);
    if (!host_little_endian())
        swap_words(data, n / 4);
    return 1;
}

pm_status pm_map_load(pm_map **out, const char *path, char *err, size_t errlen)
{
    if (out == NULL || path == NULL) {
        pmi_set_err(err, errlen, "pm_map_load: NULL argument");
        return PM_ERR_ARG;
    }
    *out = NULL;
    char why[128];
    FILE *f = fopen(path, "rb");
    if (f == NULL) {
        errno_text(errno, why, sizeof why);
        pmi_set_err(err, errlen, "%s: cannot open: %s", path, why);
        return PM_ERR_IO;
    }
    pm_map *map = NULL;
    pm_status code = PM_ERR_FORMAT;
    struct stat st;
    if (fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode)) {
        pmi_set_err(err, errlen, "%s: not a regular file", path);
        code = PM_ERR_IO;
        goto fail;
    }
    const uint64_t size = (uint64_t)st.st_size;

    /* 1. Header: magic, version, counts (and from version 2 the origin), all checked against
     *    the file size before any allocation, so a corrupt count can never make us allocate
     *    an absurd amount. */
    unsigned char head[PM_HEADER_BYTES + PM_ORIGIN_BYTES];
    size_t got = fread(head, 1, PM_HEADER_BYTES, f);
    if (size == 0) {
        pmi_set_err(err, errlen, "%s: empty file (not a photon map)", path);
        goto fail;
    }
    if (got >= 4 && memcmp(head, "PMAP", 4) != 0) {
        pmi_set_err(err, errlen, "%s: not a photon map (bad magic)", path);
        goto fail;
    }
    const uint64_t version = got >= 8 ? get_le(head + 4, 4) : PM_FILE_VERSION;
    if (version != 1 && version != PM_FILE_VERSION) {
        pmi_set_err(err, errlen, "%s: unsupported version %" PRIu64 " (expected 1 or %u)", path,
                    version, PM_FILE_VERSION);
        goto fail;
    }
    const size_t headlen = PM_HEADER_BYTES + (version >= 2 ? PM_ORIGIN_BYTES : 0);
    const uint64_t minimum = headlen + PM_CHECKSUM_BYTES;
    if (got == PM_HEADER_BYTES && version >= 2)
        got += fread(head + PM_HEADER_BYTES, 1, PM_ORIGIN_BYTES, f);
    if (size < minimum || got < headlen) {
        pmi_set_err(err, errlen,
                    "%s: truncated: expected at least %" PRIu64 " bytes, found %" PRIu64, path,
                    minimum, size);
        goto fail;
    }
    const uint64_t nph = get_le(head + 8, 8), nseg = get_le(head + 16, 8);
    if (nph > (UINT64_MAX - minimum) / PM_PHOTON_BYTES ||
        nseg > (UINT64_MAX - minimum - nph * PM_PHOTON_BYTES) / PM_SEGMENT_BYTES) {
        pmi_set_err(err, errlen,
                    "%s: impossible counts: %" PRIu64 " photons and %" PRIu64
                    " segments, file has %" PRIu64 " bytes",
                    path, nph, nseg, size);
        goto fail;
    }
    const uint64_t expected = minimum + nph * PM_PHOTON_BYTES + nseg * PM_SEGMENT_BYTES;
    if (expected != size) {
        pmi_set_err(err, errlen, "%s: %s: expected %" PRIu64 " bytes, found %" PRIu64, path,
                    size < expected ? "truncated" : "trailing data", expected, size);
        goto fail;
    }
    if (nph > (uint64_t)INT_MAX) {
        pmi_set_err(err, errlen, "%s: %" PRIu64 " photons exceed the limit of %d", path, nph,
                    INT_MAX);
        goto fail;
    }
    double origin[3] = {0.0, 0.0, 0.0}; /* version 1 files have none: origin 0 */
    if (version >= 2)
        get_origin(head + PM_HEADER_BYTES, origin);

    /* 2. Records, then the checksum over header and records. */
    map = pm_map_new();
    if (map != NULL) {
        map->ph = nph > 0 ? malloc((size_t)nph * sizeof(pm_photon)) : NULL;
        map->seg = nseg > 0 ? malloc((size_t)nseg * sizeof(pm_segment)) : NULL;
    }
    if (map == NULL || (nph > 0 && map->ph == NULL) || (nseg > 0 && map->seg == NULL)) {
        pmi_set_err(err, errlen, "%s: out of memory for %" PRIu64 " photons and %" PRIu64
                    " segments", path, nph, nseg);
        code = PM_ERR_NOMEM;
        goto fail;
    }
    map->capph = (size_t)nph;
    map->capseg = (size_t)nseg;
    uint64_t h = fnv1a(FNV_OFFSET, head, headlen);
    unsigned char tail[PM_CHECKSUM_BYTES];
    if (!read_records(f, map->ph, (size_t)nph * sizeof(pm_photon), &h) ||
        !read_records(f, map->seg, (size_t)nseg * sizeof(pm_segment), &h) ||
        fread(tail, 1, sizeof tail, f) != sizeof tail) {
        pmi_set_err(err, errlen, "%s: read failed (file changed while reading?)", path);
        code = PM_ERR_IO;
        goto fail;
    }
    if (get_le(tail, 8) != h) {
        pmi_set_err(err, errlen,
                    "%s: checksum mismatch: stored %016" PRIx64 ", computed %016" PRIx64, path,
                    get_le(tail, 8), h);
        goto fail;
    }

    /* 3. Values: a finite origin, and the same rules as pm_map_add_photons / _add_segments. */
    if (!pmi_finite3d(origin)) {
        pmi_set_err(err, errlen, "%s: origin (%g, %g, %g) is not finite", path, origin[0],
                    origin[1], origin[2]);
        goto fail;
    }
    memcpy(map->origin, origin, sizeof map->origin);
    for (size_t i = 0; i < (size_t)nph; i++) {
        if (!pmi_check_photon(&map->ph[i], why, sizeof why)) {
            pmi_set_err(err, errlen, "%s: photon %zu: %s", path, i, why);
            goto fail;
        }
    }
    for (size_t i = 0; i < (size_t)nseg; i++) {
        if (!pmi_check_segment(&map->seg[i], why, sizeof why)) {
            pmi_set_err(err, errlen, "%s: segment %zu: %s", path, i, why);
            goto fail;
        }
    }
    pmi_grow_bounds(map, map->ph, (size_t)nph); /* while map->nph is still 0 */
    map->nph = (size_t)nph;
    map->nseg = (size_t)nseg;
    fclose(f);
    *out = map;
    return PM_OK;

fail:
    pm_map_free(map);
    fclose(f);
    return code;
}
