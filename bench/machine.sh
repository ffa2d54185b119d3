# bench/machine.sh: sourced by the benchmark scripts. bench_machine_note prints, to stderr, the
# load average and a warning when the kernel's autogroup scheduling is on: with it, `nice` acts
# only inside a terminal session's group, so other sessions' niced builds take as much CPU as a
# benchmark at normal priority, and wall times move by several times (found in session 4,
# docs/guided-marching.md). Turn it off for a benchmark (as root):
#     echo 0 > /proc/sys/kernel/sched_autogroup_enabled
bench_machine_note() {
  echo "bench: load average $(cut -d' ' -f1-3 /proc/loadavg), $(nproc) cores" >&2
  local ag=/proc/sys/kernel/sched_autogroup_enabled
  if [ -r "$ag" ] && [ "$(cat "$ag")" = 1 ]; then
    echo "bench: warning: kernel.sched_autogroup_enabled = 1: other sessions' niced work competes" \
         "with this benchmark as equals; times may move several-fold (bench/machine.sh says how to turn it off)" >&2
  fi
}

# The benchmark's eight scenes (the hard-light and easy suites with beam.json), the default
# SCENES of the scripts that compare builds (bench_ab.sh, bench_speed.sh).
BENCH_EIGHT="beam default homogeneous plume-env hard-window-beam hard-narrow-spot hard-dense-block hard-lens-caustic"

# bench_compare SCRIPT LOG BIN ARGS...: one `BIN compare ARGS...` with its output in LOG; on
# failure, says so naming SCRIPT and LOG, shows LOG's last lines and exits (set -e alone would
# stop the script without a word, the output being in LOG).
bench_compare() {
  local script=$1 log=$2
  shift 2
  if ! "$@" > "$log" 2>&1; then
    echo "$script: compare failed (log $log):" >&2
    tail -n 5 "$log" >&2
    exit 1
  fi
}

# bench_reference SCRIPT NAME: the reference image of scene NAME for the equal-time scripts
# (bench_ab.sh, bench_passes.sh), the first $REFS/NAME-*ref.exr that is not a standard-error
# image; exits naming SCRIPT when there is none.
bench_reference() {
  local ref
  ref=$(ls "$REFS/$2"-*ref.exr 2>/dev/null | grep -v -- -stderr | head -1 || true)
  if [ -z "$ref" ]; then
    echo "$1: no reference $REFS/$2-*ref.exr" >&2
    exit 2
  fi
  echo "$ref"
}
