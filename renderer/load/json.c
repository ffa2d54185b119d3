/* json.c: the scene loader's typed parameters (pbrt-v4's name): each helper reads one field of
 * a JSON object, checks its type and range, fills in the default of a missing optional field,
 * and on an error writes one line naming the file and the field's path (the error context,
 * ld_ctx in rd_load.h). Also the paths of data files named by the scene. */
#include "load/rd_load.h"

#include <cJSON.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>

rd_status ld_fail(ld_ctx *c, const char *path, const char *fmt, ...)
{
    char msg[RD_ERRLEN];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (c->err && c->errlen) snprintf(c->err, c->errlen, "%s: %s: %s", c->file, path, msg);
    return RD_ERR_SCENE;
}

void ld_join(char *out, size_t n, const char *parent, const char *key)
{
    /* Keys are short; a key that does not fit is cut, never overflowed. */
    snprintf(out, n, "%.200s%s%.90s", parent, parent[0] ? "." : "", key);
}

const char *ld_type_name(const cJSON *j)
{
    if (cJSON_IsNumber(j)) return "a number";
    if (cJSON_IsString(j)) return "a string";
    if (cJSON_IsBool(j)) return "a boolean";
    if (cJSON_IsNull(j)) return "null";
    if (cJSON_IsArray(j)) return "an array";
    if (cJSON_IsObject(j)) return "an object";
    return "something else";
}

/* Reject keys not in `allowed` (NULL-terminated). */
rd_status ld_check_keys(ld_ctx *c, const cJSON *obj, const char *path, const char *const *allowed)
{
    for (const cJSON *it = obj->child; it; it = it->next) {
        int ok = 0;
        for (const char *const *a = allowed; *a; a++)
            if (strcmp(it->string, *a) == 0) ok = 1;
        if (!ok) {
            char p[300], list[256] = "";
            ld_join(p, sizeof p, path, it->string);
            for (const char *const *a = allowed; *a; a++) {
                strncat(list, *a, sizeof list - strlen(list) - 1);
                if (a[1]) strncat(list, ", ", sizeof list - strlen(list) - 1);
            }
            return ld_fail(c, p, "unknown key (allowed: %s)", list);
        }
    }
    return RD_OK;
}

rd_status ld_need_object(ld_ctx *c, const cJSON *j, const char *path)
{
    if (!cJSON_IsObject(j)) return ld_fail(c, path, "expected an object, found %s", ld_type_name(j));
    return RD_OK;
}

/* A finite number in [lo, hi] (open ends when lo_open / hi_open). Missing: default when
 * `required` is 0. */
rd_status ld_get_num(ld_ctx *c, const cJSON *obj, const char *path, const char *key, int required,
                     double def, double lo, int lo_open, double hi, int hi_open, double *out)
{
    char p[300];
    ld_join(p, sizeof p, path, key);
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!j) {
        if (required) return ld_fail(c, p, "missing (required)");
        *out = def;
        return RD_OK;
    }
    if (!cJSON_IsNumber(j)) return ld_fail(c, p, "expected a number, found %s", ld_type_name(j));
    double v = j->valuedouble;
    if (!isfinite(v)) return ld_fail(c, p, "must be finite");
    if ((lo_open ? v <= lo : v < lo) || (hi_open ? v >= hi : v > hi))
        return ld_fail(c, p, "must be in %c%.10g, %.10g%c, found %.10g", lo_open ? '(' : '[', lo, hi,
                       hi_open ? ')' : ']', v);
    *out = v;
    return RD_OK;
}

rd_status ld_get_int(ld_ctx *c, const cJSON *obj, const char *path, const char *key, int required,
                     long long def, long long lo, long long hi, long long *out)
{
    double v;
    rd_status st = ld_get_num(c, obj, path, key, required, (double)def, (double)lo, 0, (double)hi, 0, &v);
    if (st) return st;
    if (v != floor(v)) {
        char p[300];
        ld_join(p, sizeof p, path, key);
        return ld_fail(c, p, "expected an integer, found %g", v);
    }
    *out = (long long)v;
    return RD_OK;
}

/* Three finite numbers (or, when `allow_scalar`, one number replicated), each in [lo, hi]. */
rd_status ld_get_vec3(ld_ctx *c, const cJSON *obj, const char *path, const char *key, int required,
                      vec3 def, int allow_scalar, double lo, double hi, vec3 *out)
{
    char p[300];
    ld_join(p, sizeof p, path, key);
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(obj, key);
    char range[64] = "";
    if (isfinite(lo) || isfinite(hi)) snprintf(range, sizeof range, " in [%g, %g]", lo, hi);
    const char *want = allow_scalar ? "a number or 3 numbers" : "3 numbers";
    if (!j) {
        if (required) return ld_fail(c, p, "missing (required: %s)", want);
        *out = def;
        return RD_OK;
    }
    double v[3];
    if (allow_scalar && cJSON_IsNumber(j)) {
        v[0] = v[1] = v[2] = j->valuedouble;
    } else {
        if (!cJSON_IsArray(j) || cJSON_GetArraySize(j) != 3)
            return ld_fail(c, p, "expected %s%s", want, range);
        for (int i = 0; i < 3; i++) {
            const cJSON *e = cJSON_GetArrayItem(j, i);
            if (!cJSON_IsNumber(e)) return ld_fail(c, p, "expected %s%s", want, range);
            v[i] = e->valuedouble;
        }
    }
    for (int i = 0; i < 3; i++)
        if (!isfinite(v[i]) || v[i] < lo || v[i] > hi)
            return ld_fail(c, p, "expected %s%s, found %g", want, range, v[i]);
    *out = v3(v[0], v[1], v[2]);
    return RD_OK;
}

rd_status ld_get_str(ld_ctx *c, const cJSON *obj, const char *path, const char *key, int required,
                     const char *def, const char **out)
{
    char p[300];
    ld_join(p, sizeof p, path, key);
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!j) {
        if (required) return ld_fail(c, p, "missing (required)");
        *out = def;
        return RD_OK;
    }
    if (!cJSON_IsString(j) || !j->valuestring[0])
        return ld_fail(c, p, "expected a non-empty string, found %s", ld_type_name(j));
    *out = j->valuestring;
    return RD_OK;
}

rd_status ld_get_bool(ld_ctx *c, const cJSON *obj, const char *path, const char *key, int def, int *out)
{
    char p[300];
    ld_join(p, sizeof p, path, key);
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(obj, key);
    if (!j) { *out = def; return RD_OK; }
    if (!cJSON_IsBool(j)) return ld_fail(c, p, "expected true or false, found %s", ld_type_name(j));
    *out = cJSON_IsTrue(j);
    return RD_OK;
}

/* Map a string to one of `names` (NULL-terminated); the index goes to *out. */
rd_status ld_get_enum(ld_ctx *c, const cJSON *obj, const char *path, const char *key, int required,
                      const char *const *names, int def, int *out)
{
    const char *s;
    rd_status st = ld_get_str(c, obj, path, key, required, NULL, &s);
    if (st) return st;
    if (!s) { *out = def; return RD_OK; }
    for (int i = 0; names[i]; i++)
        if (strcmp(s, names[i]) == 0) { *out = i; return RD_OK; }
    char p[300], list[256] = "";
    ld_join(p, sizeof p, path, key);
    for (int i = 0; names[i]; i++) {
        strncat(list, names[i], sizeof list - strlen(list) - 1);
        if (names[i + 1]) strncat(list, ", ", sizeof list - strlen(list) - 1);
    }
    return ld_fail(c, p, "unknown value \"%s\" (expected one of: %s)", s, list);
}

void ld_resolve_path(const ld_ctx *c, const char *file, char *out, size_t n)
{
    if (file[0] == '/' || !c->dir[0]) snprintf(out, n, "%s", file);
    else snprintf(out, n, "%s/%s", c->dir, file);
}

/* What to add to a density file's error (written into buf): a file that does not exist and that
 * the scene says a script makes ("made_by") is not committed, so name the script to run. */
const char *ld_missing_hint(const char *file, const char *made_by, char *buf, size_t n)
{
    buf[0] = '\0';
    struct stat sb;
    if (made_by && stat(file, &sb) != 0)
        snprintf(buf, n, " (not committed: made by %s; run it first)", made_by);
    return buf;
}
