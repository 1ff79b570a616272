#!/usr/bin/env bash
# fuzz_regress.sh — the fuzz harnesses of tests/fuzz/, linked without
# libFuzzer (tests/fuzz/replay.c), replay every reproducer kept in
# tests/fuzz/regress/NAME/ (inputs that once crashed, hung or leaked in
# harness NAME): each must now be read or refused cleanly, under the
# sanitizers too with `make test SANITIZE=1`. Every harness also takes an
# empty input and a one-byte one.
source "$(dirname "$0")/common.bash"
R="$CROM_BUILD/fuzz"
[ -d "$R" ] || fail "no replay programs in $R (make test builds them)"
: >"$TMP/empty"
printf 'x' >"$TMP/one"
n=0
for h in "$R"/replay_*; do
  [ -x "$h" ] || continue
  name=${h##*/replay_}
  files=("$TMP/empty" "$TMP/one")
  if [ -d "$CROM_TOP/tests/fuzz/regress/$name" ]; then
    for f in "$CROM_TOP/tests/fuzz/regress/$name"/*; do [ -f "$f" ] && files+=("$f"); done
  fi
  rc=0
  (cd "$TMP" && timeout 120 "$h" "${files[@]}") >"$TMP/log" 2>&1 || rc=$?
  [ $rc -eq 0 ] || fail "harness $name on its reproducers exited $rc: $(tail -20 "$TMP/log")"
  n=$((n + ${#files[@]} - 2))
  ok
done
[ "$NCHECK" -ge 14 ] || fail "only $NCHECK replay programs in $R"
# every reproducer is in the folder of a harness that exists
for d in "$CROM_TOP"/tests/fuzz/regress/*/; do
  [ -d "$d" ] || continue
  name=$(basename "$d")
  [ -x "$R/replay_$name" ] || fail "tests/fuzz/regress/$name/ names no harness"
  ok
done
echo "replayed $n reproducers"
done_checks
