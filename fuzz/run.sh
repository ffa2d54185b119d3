#!/usr/bin/env bash
# fuzz/run.sh BUILD SECONDS TARGET...: run each libFuzzer target BUILD/fuzz/fuzz_TARGET for
# SECONDS, from its seed corpus (fuzz/seeds/TARGET, the regression inputs tests/data/fuzz/TARGET
# and, for scenes and volumes, the files in scenes/ and tests/data/bad/) plus what earlier runs
# found (BUILD/fuzz/corpus/TARGET). The targets write their temporary files under a fresh
# TMPDIR, removed at the end. Prints one line per target; exits 1 if any target found a crash
# (the input is kept in BUILD/fuzz/crashes/, the log in BUILD/fuzz/TARGET.log).
#
# Timeouts are reported, crashes fail. An input that runs longer than FUZZ_TIMEOUT seconds
# (default 60, wall time: on a loaded machine a slow seed scene can reach it without any hang) is
# kept as crashes/TARGET-timeout-*, counted in the summary line ("oom/timeout/crash") and the
# fuzzing goes on (fork mode's -ignore_timeouts). libFuzzer then exits with the code of its last
# job, so a run whose last job timed out ends with -timeout_exitcode (70) and one whose last job
# ran out of memory with its OOM code (71); both are "reported", not failures. Any other non-zero
# exit is a crash (fork mode stops at the first one and prints "INFO: log from the inner
# process"): FAILED. docs/robustness.md, "Fuzzing".
#
# FUZZ_FRESH=1 (make test's short run): start from the seeds alone (without the slow example
# scenes), with a fixed libFuzzer seed, so every run tries the same inputs in the same order
# (only how far it gets depends on time).
# FUZZ_JOBS (default 2): how many targets run at once, each its own libFuzzer process for the full
# SECONDS (the summary lines still come in the order given). With -fork=1 a target keeps one core
# busy (its parent only waits), so on the 2-core CI machine two at a time give each target the
# same core-seconds as one after the other, in half the wall time.
# UBSan and LSan suppressions, each with its reason: fuzz/ubsan.supp, fuzz/lsan.supp.
# libFuzzer runs in fork mode with -ignore_ooms: an input that makes a loader take more than
# 2 GiB (rss_limit_mb) is kept in BUILD/fuzz/crashes/ as oom-* and counted in the summary
# ("oom/timeout/crash"), not a failure: the loaders accept sizes up to documented caps (a .vdb's
# dense copy up to 2^31 voxels), and an allocation the machine cannot give is reported by them.
set -uo pipefail
build=$1 secs=$2
shift 2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$build/fuzz/crashes"
jobs=${FUZZ_JOBS:-2}
timeout_code=70 # -timeout_exitcode, passed below
oom_code=71     # libFuzzer's fixed exit code for an out-of-memory input (no flag sets it)
# run_one TARGET: fuzz it, write its summary line(s) to $work/summary-TARGET; exit 1 on a crash.
run_one() {
  local t=$1
  local corpus=$build/fuzz/corpus/$t
  local fixed=()
  if [ "${FUZZ_FRESH:-0}" = 1 ]; then corpus=$work/corpus-$t; fixed=(-seed=1); fi
  local seeds=$work/seeds-$t
  mkdir -p "$corpus" "$seeds" "$work/tmp-$t"
  touch "$work/start-$t"
  cp fuzz/seeds/$t/* "$seeds"/ 2>/dev/null
  cp tests/data/fuzz/$t/* "$seeds"/ 2>/dev/null
  case $t in
    scene) # the example scenes take up to seconds each to load (their majorant grids):
           # left out of the short run
           cp tests/data/bad/*.json "$seeds"/
           [ "${FUZZ_FRESH:-0}" = 1 ] || cp scenes/*.json "$seeds"/ ;;
    vdb) cp tests/data/bad/*.vdb "$seeds"/ ;;
  esac
  # image: the suppression of OpenImageIO's PNG leak (fuzz/lsan.supp) names a frame inside the
  # library, which only the slow unwinder sees (system libraries have no frame pointers)
  local unwind=
  [ "$t" = image ] && unwind=:fast_unwind_on_malloc=0
  local log=$build/fuzz/$t.log
  # -ignore_crashes=0: the first crash stops the target; -timeout_exitcode and -error_exitcode
  # pinned to their defaults, which the verdict below reads.
  TMPDIR=$work/tmp-$t ASAN_OPTIONS=allocator_may_return_null=1:detect_leaks=1$unwind \
    UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1:suppressions=$PWD/fuzz/ubsan.supp \
    LSAN_OPTIONS=suppressions=$PWD/fuzz/lsan.supp:print_suppressions=0 \
    "$build/fuzz/fuzz_$t" "${fixed[@]}" -fork=1 -ignore_ooms=1 -ignore_timeouts=1 -ignore_crashes=0 \
    -timeout_exitcode=$timeout_code -error_exitcode=77 -max_total_time="$secs" -timeout="${FUZZ_TIMEOUT:-60}" \
    -rss_limit_mb=2048 -max_len=65536 -artifact_prefix="$build/fuzz/crashes/$t-" "$corpus" "$seeds" >"$log" 2>&1
  local code=$?
  local last runs cov ooms
  last=$(grep -E '^#[0-9]+: cov' "$log" | tail -1)
  runs=$(sed -n 's/^#\([0-9]*\): cov.*/\1/p' <<<"$last")
  cov=$(grep -o 'cov: [0-9]*' <<<"$last")
  ooms=$(grep -o 'oom/timeout/crash: [0-9/]*' <<<"$last")
  # A timeout or an out-of-memory (the last job's code, only when no crash stopped the run) is
  # reported with its inputs; anything else is a crash.
  local crashed=1
  if [ $code -eq 0 ]; then crashed=0
  elif { [ $code -eq $timeout_code ] || [ $code -eq $oom_code ]; } && ! grep -q 'INFO: log from the inner process' "$log"; then
    crashed=0
  fi
  if [ $crashed = 0 ]; then
    local note=
    [ $code -ne 0 ] && note=" (libFuzzer exit $code: its last job $([ $code -eq $timeout_code ] && echo timed out || echo ran out of memory); reported, not a failure)"
    local kept
    kept=$(find "$build/fuzz/crashes" -newer "$work/start-$t" \( -name "$t-timeout-*" -o -name "$t-oom-*" \) | wc -l)
    [ "$kept" -gt 0 ] && note="$note; $kept timeout/oom inputs kept in $build/fuzz/crashes/"
    echo "fuzz $t: ${runs:-?} runs in $secs s, $cov, corpus $(ls "$corpus" | wc -l) files, ${ooms:-no crash}$note" >"$work/summary-$t"
    return 0
  fi
  { echo "fuzz $t: FAILED (exit $code) after ${runs:-?} runs: $(grep -m1 -E 'ERROR|runtime error|SUMMARY' "$log")"
    echo "  log $log; input $(ls -t "$build"/fuzz/crashes/$t-* 2>/dev/null | head -1)"; } >"$work/summary-$t"
  return 1
}

# At most $jobs targets at a time; a target's exit status is collected from its own wait.
pids=()
for t in "$@"; do
  while [ "$(jobs -rp | wc -l)" -ge "$jobs" ]; do wait -n; done
  run_one "$t" &
  pids+=($!)
done
status=0
i=0
for t in "$@"; do
  wait "${pids[$i]}" || status=1
  cat "$work/summary-$t"
  i=$((i + 1))
done
exit $status
