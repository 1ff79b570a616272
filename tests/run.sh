#!/usr/bin/env bash
# Run crom's whole test suite: unit tests of lib/ (BUILD/tests/test_*), then the
# program and pipeline tests (tests/prog/*.sh) with BINDIR first on PATH.
# Usage: tests/run.sh BUILD BINDIR [PATTERN]
# Each test's output goes to BUILD/test-logs/NAME.log; failures are printed.
set -uo pipefail
BUILD=${1:-build}
BINDIR=$(cd "${2:-bin}" && pwd)
PATTERN=${3:-${TESTS:-}}
TOP=$(cd "$(dirname "$0")/.." && pwd)
LOGS="$TOP/$BUILD/test-logs"
mkdir -p "$LOGS"
export PATH="$BINDIR:$PATH" CROM_TOP="$TOP" CROM_BINDIR="$BINDIR" CROM_BUILD="$TOP/$BUILD"
export OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=0}
export LSAN_OPTIONS=${LSAN_OPTIONS:-suppressions=$TOP/tests/lsan.supp:print_suppressions=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
JOBS=${JOBS:-2}

list=()
for t in "$TOP/$BUILD"/tests/test_*; do
  [ -x "$t" ] && [ "${t%.d}" = "$t" ] && [ "${t%.o}" = "$t" ] && list+=("$t")
done
for t in "$TOP"/tests/prog/*.sh; do [ -f "$t" ] && list+=("$t"); done
if [ -n "$PATTERN" ]; then
  sel=(); for t in "${list[@]}"; do [[ "$(basename "$t")" == *$PATTERN* ]] && sel+=("$t"); done
  list=("${sel[@]}")
fi
# Under the sanitizers (CROM_SANITIZE=1, from make test SANITIZE=1) a program
# test whose header has a line '# asan: skip (REASON)' is skipped with that
# reason: training runs whose library code the unit tests cover under ASan
# too, and which ASan slows 3-4x.
skipped=()
if [ "${CROM_SANITIZE:-0}" = 1 ]; then
  sel=()
  for t in "${list[@]}"; do
    if [[ "$t" == *.sh ]] && reason=$(grep -m1 '^# asan: skip' "$t"); then
      skipped+=("$(basename "${t%.sh}") ${reason#\# asan: skip }")
    else
      sel+=("$t")
    fi
  done
  list=("${sel[@]}")
fi
# CROM_TEST_SANITIZED_ELSEWHERE=1 (CI's plain pass, which the sanitized pass
# follows): the unit tests and only the program tests that the sanitized
# pass skips in whole or in part (those that read CROM_SANITIZE); every other
# program test runs once in CI, under ASan + UBSan.
if [ "${CROM_TEST_SANITIZED_ELSEWHERE:-0}" = 1 ]; then
  sel=()
  for t in "${list[@]}"; do
    if [[ "$t" == *.sh ]] && ! grep -q '^# asan: skip\|CROM_SANITIZE' "$t"; then
      skipped+=("$(basename "${t%.sh}") (run by the sanitized pass)")
    else
      sel+=("$t")
    fi
  done
  list=("${sel[@]}")
fi
# the slowest first (measured in CI's two passes), so that two jobs end together
slow=(robust_check faults datafree badflags slurm pipelines_more reduced shell_subspace bistable equilibria
      shell_export export_more pipelines rod schemas conditional robust_input skinning test_datafree mpi view
      materials scene learn_badinput shell remesh export_cells fullsim live learn)
ord=()
for n in "${slow[@]}"; do for t in "${list[@]}"; do [ "$(basename "${t%.sh}")" = "$n" ] && ord+=("$t"); done; done
for t in "${list[@]}"; do [[ " ${slow[*]} " == *" $(basename "${t%.sh}") "* ]] || ord+=("$t"); done
list=("${ord[@]}")

run_one() {
  t=$1; name=$(basename "$t"); name=${name%.sh}
  log="$LOGS/$name.log"
  start=$EPOCHREALTIME
  if [[ "$t" == *.sh ]]; then ( cd "$TOP" && bash "$t" ) >"$log" 2>&1; else ( cd "$TOP" && "$t" ) >"$log" 2>&1; fi
  rc=$?
  secs=$(awk -v a="$start" -v b="$EPOCHREALTIME" 'BEGIN{print b-a}')
  if [ $rc -eq 0 ]; then printf 'ok   %-28s %6.1fs\n' "$name" "$secs"
  else printf 'FAIL %-28s %6.1fs  (exit %d, log %s)\n' "$name" "$secs" "$rc" "${log#$TOP/}"; fi
}
export -f run_one
export LOGS TOP
for k in "${skipped[@]}"; do printf 'skip %s\n' "$k"; done
printf '%s\n' "${list[@]}" | xargs -P "$JOBS" -I{} bash -c 'run_one "$@"' _ {} | tee "$LOGS/summary.txt"
fails=$(grep -c '^FAIL' "$LOGS/summary.txt")
total=${#list[@]}
if [ "$fails" -ne 0 ]; then
  echo
  for f in $(grep '^FAIL' "$LOGS/summary.txt" | awk '{print $2}'); do
    echo "---- $f (last 30 lines) ----"; tail -n 30 "$LOGS/$f.log"
  done
  echo "tests: $fails of $total FAILED"
  exit 1
fi
echo "tests: all $total passed${skipped:+ (${#skipped[@]} skipped: see the skip lines above)}"
