/* lsan_workers.c: LeakSanitizer checks every test's worker process, not Criterion's runner
 * (make test's sanitizer suite; docs/robustness.md, "AddressSanitizer + UBSan over the suite").
 *
 * Criterion runs each test in a worker, a fresh process of this binary, and the runner (the
 * process make test starts) only collects results. The runner leaks a few of Criterion's own
 * blocks at exit (calloc in libcriterion.so; 432 bytes in 9 blocks for the whole suite), which
 * LeakSanitizer would report; the only suppression that names them, `leak:libcriterion.so`,
 * would also hide every leak in a test, since every test's stack passes through
 * criterion_internal_test_main in that library. So make test turns the at-exit check off
 * (leak_check_at_exit=0) and this file runs it in the workers only: at exit, a process that ran a
 * test (criterion_current_test set; only compared, never read: Criterion has freed it by then)
 * calls __lsan_do_leak_check, which reports to make test's report folder
 * (tests/sanitizer_reports.sh). In a build without AddressSanitizer this file is empty. */
#if defined(__SANITIZE_ADDRESS__)
#define RT_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define RT_ASAN 1
#endif
#endif

#ifdef RT_ASAN
#include <criterion/criterion.h>
#include <sanitizer/lsan_interface.h>
#include <stdlib.h>

static void check_the_worker(void)
{
    if (criterion_current_test) __lsan_do_leak_check();
}

/* Registered after the sanitizer runtime's own at-exit check (installed before any
 * constructor), so it runs first; that one then does nothing (it is off in make test, and
 * LeakSanitizer checks a process once). */
__attribute__((constructor)) static void install_worker_leak_check(void)
{
    atexit(check_the_worker);
}
#else
typedef int rt_no_sanitizer; /* a translation unit must declare something */
#endif
