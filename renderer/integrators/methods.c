/* methods.c: the table of render methods, made from the rows of method_list.h. Adding a method
 * is one file defining a `const rd_method` (rd_method.h) plus one row in method_list.h. */
#include "integrators/rd_method.h"

#include <string.h>

static const rd_method *const table[] = {
#define RD_METHOD(id) &rd_method_##id,
#include "integrators/method_list.h"
#undef RD_METHOD
};
enum { N_METHODS = sizeof table / sizeof table[0] };

const rd_method *rd_method_find(const char *name)
{
    for (int i = 0; name && i < N_METHODS; i++)
        if (!strcmp(table[i]->name, name)) return table[i];
    return NULL;
}

int rd_method_count(void) { return N_METHODS; }
const char *rd_method_name(int i) { return i >= 0 && i < N_METHODS ? table[i]->name : NULL; }
const char *rd_method_summary(int i) { return i >= 0 && i < N_METHODS ? table[i]->summary : NULL; }
unsigned rd_method_needs(int i) { return i >= 0 && i < N_METHODS ? table[i]->needs : 0u; }

size_t rd_methods(char *buf, size_t n)
{
    size_t len = 0, written = 0;
    for (int i = 0; i < N_METHODS; i++) {
        const char *sep = i ? ", " : "", *name = table[i]->name;
        size_t k = strlen(sep) + strlen(name);
        if (buf && written == len && len + k < n) { /* whole names only */
            memcpy(buf + len, sep, strlen(sep));
            memcpy(buf + len + strlen(sep), name, strlen(name));
            written += k;
        }
        len += k;
    }
    if (buf && n) buf[written] = 0;
    return len;
}

unsigned rd_method_needs_for(const char *name, const rd_scene *s)
{
    const rd_method *m = rd_method_find(name);
    if (!m) return 0u;
    return m->needs_for ? m->needs_for(s) : m->needs;
}
