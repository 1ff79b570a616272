#!/usr/bin/env bash
# run.sh — run fuzz harnesses one after another, each for SECONDS (with
# FUZZ_RUNS=N, for N inputs or at most SECONDS), starting from the seeds in FUZZ/corpus/NAME/
# and keeping what they find new in FUZZ/work/NAME/. Any crash, sanitizer
# report, leak (LeakSanitizer, third-party leaks of tests/lsan.supp
# suppressed; after each input, or only at exit for the streams, below),
# input slower than FUZZ_TIMEOUT s or memory over FUZZ_RSS_MB
# fails the run; the input that did it is kept as FUZZ/artifacts/NAME-*.
# Prints one line per harness: inputs run, inputs per second, coverage.
# Usage: tests/fuzz/run.sh FUZZ SECONDS NAME...
set -uo pipefail
FUZZ=$1 SECS=$2
shift 2
TOP=$(cd "$(dirname "$0")/../.." && pwd)
TIMEOUT=${FUZZ_TIMEOUT:-10} RSS=${FUZZ_RSS_MB:-2048}
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=0:allocator_may_return_null=1
export LSAN_OPTIONS=suppressions=$TOP/tests/lsan.supp:print_suppressions=0
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1
# the contained HDF5 probe (lib/io/h5probe.h) gives up well within the per-input timeout
export CROM_PROBE_SECONDS=${CROM_PROBE_SECONDS:-3}
mkdir -p "$FUZZ/artifacts" "$FUZZ/logs"
FUZZ=$(cd "$FUZZ" && pwd)
# the harnesses run in an empty directory: a nested @NAME in a flag file
# finds nothing there
EMPTY=$(mktemp -d "${TMPDIR:-/tmp}/crom-fuzz-cwd.XXXXXX")
trap 'rmdir "$EMPTY"' EXIT
cd "$EMPTY"
fails=0
for name in "$@"; do
  case $name in
    flags | atfile) len=2048 extra=(-close_fd_mask=2 -dict="$TOP/tests/fuzz/flags.dict") ;;
    # HDF5's H5LTopen_file_image leaks 72 bytes per stream header opened
    # (tests/lsan.supp): with libFuzzer's leak check after every input that
    # allocates more than it frees, that is a full LeakSanitizer pass per
    # input (30 inputs/s). Leaks are still detected, once, at exit.
    frames) len=4096 extra=(-detect_leaks=0) ;;
    stream) len=131072 extra=(-detect_leaks=0) ;;
    cloud | live) len=4096 extra=() ;;
    obj) len=16384 extra=() ;;
    stl) len=32768 extra=() ;;
    *) len=524288 extra=() ;;     # a trajectory of a few steps is 400 KB
  esac
  [ -f "$FUZZ/fuzz_$name" ] || { echo "fuzz: no harness $FUZZ/fuzz_$name" >&2; exit 2; }
  mkdir -p "$FUZZ/${FUZZ_WORK:-work}/$name" "$FUZZ/corpus/$name"
  log="$FUZZ/logs/${FUZZ_WORK:-work}-$name.log"
  limit=(-max_total_time="$SECS")
  [ -z "${FUZZ_RUNS:-}" ] || limit+=(-runs="$FUZZ_RUNS")
  "$FUZZ/fuzz_$name" "${limit[@]}" -timeout="$TIMEOUT" -rss_limit_mb="$RSS" -max_len=$len \
    -artifact_prefix="$FUZZ/artifacts/$name-" -print_final_stats=1 "${extra[@]}" \
    "$FUZZ/${FUZZ_WORK:-work}/$name" "$FUZZ/corpus/$name" >"$log" 2>&1
  rc=$?
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log")
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log")
  rss=$(sed -n 's/^stat::peak_rss_mb: *//p' "$log")
  cov=$(grep -oE 'cov: [0-9]+ ft: [0-9]+ corp: [0-9]+' "$log" | tail -1)
  if [ $rc -eq 0 ]; then
    printf 'fuzz ok   %-9s %9s inputs %6s/s  %s  rss %s MB\n' "$name" "${runs:-?}" "${rate:-?}" "$cov" "${rss:-?}"
  else
    fails=$((fails + 1))
    printf 'fuzz FAIL %-9s (exit %d) after %s inputs; log %s\n' "$name" $rc "${runs:-?}" "$log"
    grep -E 'ERROR|SUMMARY|Test unit written|==[0-9]+==|^    #[0-9]' "$log" | head -30
  fi
done
[ $fails -eq 0 ] || { echo "fuzz: $fails harness(es) failed" >&2; exit 1; }
