/* The sanitizer suite's own check (make test; tests/sanitizer_reports.sh --selftest): defects
 * planted in test code, which the sanitizer run must report as failures. They run only when
 * PHOTONMARCH_PLANT names them (the self-test sets it); otherwise they skip, in both runs. */
#include <criterion/criterion.h>
#include <stdlib.h>
#include <string.h>

static int planted(const char *what)
{
    const char *p = getenv("PHOTONMARCH_PLANT");
    return p && strstr(p, what);
}

/* A block whose last pointer is dropped: LeakSanitizer finds it when the worker exits, after the
 * test has passed; the report (tests/support/sanitizer.c names it sanitizer.planted_leak.PID)
 * must fail make test. */
static void *volatile sink;
Test(sanitizer, planted_leak)
{
    if (!planted("leak")) cr_skip_test("PHOTONMARCH_PLANT=leak plants it");
    sink = malloc(4242);
    cr_assert(sink != NULL);
    memset(sink, 1, 4242);
    sink = NULL;
}

/* A read one past a heap block: AddressSanitizer stops the worker there (halt_on_error), so the
 * test crashes. */
Test(sanitizer, planted_overflow)
{
    if (!planted("overflow")) cr_skip_test("PHOTONMARCH_PLANT=overflow plants it");
    char *volatile p = malloc(16);
    cr_assert(p != NULL);
    volatile char c = p[16];
    (void)c;
    free(p);
}
