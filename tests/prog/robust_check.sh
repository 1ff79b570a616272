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

# ---- defect 6: a non-finite frame is bad data (65) for every reader of
# frames, with the same message (crom_result_check_frame)
crom-encode --model modes.h5 -q -o lat.h5 run.h5
crom-cubature --model modes.h5 --scheme optimized --poses lat.h5 -q -o cub.h5 m.h5
$PY - <<'PYEOF'
import shutil, h5py, numpy as np
shutil.copy("run.h5", "nan.h5")
with h5py.File("nan.h5", "r+") as f: f["frames/displacement"][1, 2, 0] = np.nan
shutil.copy("run.h5", "infv.h5")
with h5py.File("infv.h5", "r+") as f: f["frames/velocity"][2, 5, 1] = np.inf
shutil.copy("lat.h5", "latnan.h5")
with h5py.File("latnan.h5", "r+") as f: f["frames/q"][2, 1] = np.nan
PYEOF
nanu="nan.h5: frame 1 has a non-finite displacement at vertex 2"
expect_error 65 "^crom-export: $nanu\$" "$O/n.vtu" -- crom-export --format vtu -o "$O/n.vtu" nan.h5
expect_error 65 "^crom-diff: $nanu\$" "$O/n.csv" -- crom-diff --csv "$O/n.csv" nan.h5 run.h5
expect_error 65 "^crom-diff: $nanu\$" "$O/n.csv" -- crom-diff --csv "$O/n.csv" run.h5 nan.h5
expect_error 65 "^crom-sample: $nanu\$" "$O/s.h5" -- crom-sample --points 10 -o "$O/s.h5" nan.h5
expect_error 65 "^crom-encode: $nanu\$" - -- crom-encode --model modes.h5 -o "$O/l.h5" nan.h5
expect_error 65 "^crom-export: infv.h5: frame 2 has a non-finite velocity at vertex 5\$" "$O/v.vtu" -- \
  crom-export --format vtu -o "$O/v.vtu" infv.h5
nanq="latnan.h5: frame 2 has a non-finite q at index 1"
expect_error 65 "^crom-export: $nanq\$" "$O/q.vtu" -- crom-export --format vtu --model modes.h5 --mesh m.h5 \
  --youngs 1e6 --poisson 0.3 -o "$O/q.vtu" latnan.h5
expect_error 65 "^crom-cubature: $nanq\$" "$O/c.h5" -- crom-cubature --model modes.h5 --scheme optimized \
  --poses latnan.h5 -o "$O/c.h5" m.h5
expect_error 65 "^crom-reducedstep: $nanq\$" "$O/r.h5" -- crom-reducedstep --cubature cub.h5 --pin bottom \
  --steps 2 --init latnan.h5 --init-frame 2 -o "$O/r.h5"
crom-reducedstep --cubature cub.h5 --pin bottom --steps 2 --init latnan.h5 --init-frame 1 -q -o "$O/r.h5" \
  || fail "--init from a finite frame of a file with a NaN in another frame is refused"
# --check says the same
crom-info --check nan.h5 infv.h5 latnan.h5 >"$O/check.txt" 2>/dev/null && fail "--check passed NaN frames"
for m in "$nanu" "infv.h5: frame 2 has a non-finite velocity at vertex 5" "$nanq"; do
  grep -qE "^$m\$" "$O/check.txt" || fail "--check does not report '$m': $(cat "$O/check.txt")"; ok
done

done_checks
