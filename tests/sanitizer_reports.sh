#!/usr/bin/env bash
# tests/sanitizer_reports.sh DIR: the verdict on the sanitizer reports that make test's sanitizer
# suite left in DIR (ASAN_OPTIONS and UBSAN_OPTIONS log_path=DIR/process: one file, process.PID,
# per process that reported). Prints every report that names an error (AddressSanitizer,
# LeakSanitizer, UBSan) and exits 1 if there is one.
# Why a folder: LeakSanitizer looks for leaks when a process exits, and Criterion's worker has
# reported its test's result to the runner by then, so a leak cannot fail the test itself (the
# test shows as passed). The report's stack names the test: our code has frame pointers, so the
# allocation's stack reaches the test's function (SUITE_TEST_impl). Leaks and errors inside the libraries are suppressed before they get here
# (fuzz/lsan.supp, fuzz/ubsan.supp, each entry with its reason); what is left is ours. The
# allocator's warnings for the out-of-memory tests' impossible requests (allocator_may_return_null)
# are not errors.
#
# tests/sanitizer_reports.sh --selftest DIR RUN_TESTS: proves the check. Runs the planted defects
# of tests/test_sanitizer.c in the sanitizer build's RUN_TESTS, with the suite's sanitizer options
# (from the environment) but reports to DIR, and expects both to be caught: the leak as a report
# through sanitizer_planted_leak_impl, the heap overflow as a failed test with its report. Exits 1
# if either was missed.
set -uo pipefail

errors_in() { grep -l -E 'ERROR: (AddressSanitizer|LeakSanitizer)|runtime error:' "$1"/* 2>/dev/null; }

if [ "${1:-}" = --selftest ]; then
  dir=$2 bin=$3
  rm -rf "$dir" && mkdir -p "$dir"
  opts() { sed "s|log_path=[^:]*|log_path=$dir/process|" <<<"$1"; }
  out=$(ASAN_OPTIONS=$(opts "${ASAN_OPTIONS:-}") UBSAN_OPTIONS=$(opts "${UBSAN_OPTIONS:-}") \
        PHOTONMARCH_PLANT=leak,overflow "$bin" --filter 'sanitizer/*' 2>&1)
  ok=1
  leak=$(grep -l 'LeakSanitizer' $(errors_in "$dir") /dev/null | xargs -r grep -l 'sanitizer_planted_leak_impl')
  if [ -n "$leak" ]; then
    echo "sanitizer self-test: the planted leak was reported ($leak)"
  else
    echo "sanitizer self-test: FAILED: the planted leak in sanitizer/planted_leak left no report in $dir"; ok=0
  fi
  if grep -q '^\[FAIL\] sanitizer::planted_overflow' <<<"$out" &&
     grep -q 'heap-buffer-overflow' "$dir"/process.* 2>/dev/null; then
    echo "sanitizer self-test: the planted heap overflow failed its test"
  else
    echo "sanitizer self-test: FAILED: the planted heap overflow in sanitizer/planted_overflow was not caught"; ok=0
    echo "$out" | tail -5
  fi
  [ $ok = 1 ]
  exit
fi

dir=$1
found=$(errors_in "$dir")
if [ -z "$found" ]; then
  echo "sanitizer reports: none with an error ($(ls "$dir" | wc -l) files in $dir, warnings only)"
  exit 0
fi
for f in $found; do
  echo "== sanitizer report $f"
  cat "$f"
done
echo "sanitizer reports: $(wc -w <<<"$found") with an error (above; a leak found when a test worker exits fails no test by itself: its stack names the test)"
exit 1
