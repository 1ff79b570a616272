#!/usr/bin/env bash
# Regression tests of issue 15 (defects 4, 6, 7 and part of 3): text output
# that cannot be written, non-finite frames, and files that `crom-info
# --check` must refuse because the programs refuse them. Each case must end
# with the documented exit status and one line on stderr naming the problem
# (run under ASan/UBSan by `make test SANITIZE=1`).
. "$CROM_TOP/tests/prog/common.bash"
O="$TMP/out"; mkdir -p "$O"
cd "$TMP"

# expect_full CODE PATTERN -- command...: like expect_error, with stdout on
# /dev/full (every write to it fails with ENOSPC).
expect_full() {
  local code=$1 pat=$2; shift 3
  local rc=0
  "$@" >/dev/full 2>"$TMP/stderr" </dev/null || rc=$?
  [ "$rc" -eq "$code" ] || fail "'$*' >/dev/full exited $rc, expected $code; stderr: $(cat "$TMP/stderr")"
  local lines; lines=$(wc -l <"$TMP/stderr")
  [ "$lines" -eq 1 ] || fail "'$*' >/dev/full printed $lines lines on stderr, expected one: $(cat "$TMP/stderr")"
  grep -qE -e "$pat" "$TMP/stderr" || fail "'$*' >/dev/full: message '$(cat "$TMP/stderr")' does not match /$pat/"
  ok
}

crom-mesh box --size 0.25 --region bottom='y<-0.4' -o m.h5
crom-fullsim --pin bottom --steps 3 --dt 0.01 -q -o run.h5 m.h5
crom-fullsim --pin bottom --steps 3 --dt 0.01 -q m.h5 >run.stream
crom-modes --pin bottom --count 3 -q -o modes.h5 m.h5

# ---- defect 4: a failed write to stdout is an I/O error (74), not success
full="cannot write to stdout: No space left on device\$"
n=0
for p in "$CROM_BINDIR"/crom-*; do
  [ -x "$p" ] || continue
  name=$(basename "$p")
  for flag in --help --help-man --version; do
    expect_full 74 "^$name: $full" -- "$p" $flag
    "$p" $flag >"$O/help.txt" || fail "$name $flag exits non-zero on a writable stdout"
  done
  n=$((n + 1))
done
[ "$n" -ge 13 ] || fail "only $n programs found in $CROM_BINDIR"
text_modes=(
  "crom-info m.h5"
  "crom-info --check run.h5"
  "crom-info --frames run.h5"
  "crom-info --frames run.stream"
  "crom-diff run.h5 run.h5"
  "crom-diff --csv - run.h5 run.h5 -q"
  "crom-metrics --samples 4 --mesh m.h5 modes.h5"
)
for c in "${text_modes[@]}"; do
  prog=${c%% *}
  expect_full 74 "^$prog: $full" -- $c
  $c >"$O/text.txt" || fail "'$c' exits non-zero on a writable stdout"
  [ -s "$O/text.txt" ] || fail "'$c' printed nothing"
done
# through a pipe, and when --max-error is exceeded (exit 1 otherwise)
expect_full 74 "^crom-info: $full" -- bash -c "crom-info --frames - <run.stream"
crom-fullsim --pin bottom --steps 3 --dt 0.01 --gravity 0,-20,0 -q -o run2.h5 m.h5
rc=0; crom-diff --max-error 1e-9 run.h5 run2.h5 >/dev/null 2>&1 || rc=$?
[ "$rc" -eq 1 ] || fail "crom-diff --max-error on differing runs exited $rc, expected 1"
expect_full 74 "^crom-diff: $full" -- crom-diff -q --max-error 1e-9 run.h5 run2.h5

done_checks
