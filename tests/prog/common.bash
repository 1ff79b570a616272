# common.bash — shared helpers of crom's program tests (sourced, not run).
# The runner puts the built programs first on PATH and sets CROM_TOP.
set -euo pipefail
PY=/usr/bin/python3          # Debian's interpreter, with numpy, h5py, meshio
TMP=$(mktemp -d /tmp/crom-prog.XXXXXX)
trap 'rm -rf "$TMP"' EXIT
export SOURCE_DATE_EPOCH=${SOURCE_DATE_EPOCH:-1700000000}
NCHECK=0

fail() { echo "FAIL: $*" >&2; exit 1; }
ok() { NCHECK=$((NCHECK + 1)); }
done_checks() { echo "$(basename "$0" .sh): all $NCHECK checks passed"; }

# expect_error CODE PATTERN OUTFILE -- command...
# The command must exit with CODE, print exactly one line on stderr that
# matches PATTERN (grep -E), and leave neither OUTFILE nor a temporary file.
expect_error() {
  local code=$1 pat=$2 out=$3; shift 4
  local rc=0
  "$@" >"$TMP/stdout" 2>"$TMP/stderr" </dev/null || rc=$?
  [ "$rc" -eq "$code" ] || fail "'$*' exited $rc, expected $code; stderr: $(cat "$TMP/stderr")"
  local lines; lines=$(wc -l <"$TMP/stderr")
  [ "$lines" -eq 1 ] || fail "'$*' printed $lines lines on stderr, expected one: $(cat "$TMP/stderr")"
  grep -qE -e "$pat" "$TMP/stderr" || fail "'$*': message '$(cat "$TMP/stderr")' does not match /$pat/"
  if [ "$out" != "-" ]; then
    [ ! -e "$out" ] || fail "'$*' left an output file $out"
    local d; d=$(dirname "$out")
    ! ls -a "$d" | grep -q '\.tmp$' || fail "'$*' left a temporary file in $d"
  fi
  ok
}

# close A B TOL: |A - B| <= TOL
close() { $PY -c "import sys; a,b,t=map(float,sys.argv[1:]); sys.exit(0 if abs(a-b)<=t else 1)" "$1" "$2" "$3" \
  || fail "$1 and $2 differ by more than $3${4:+ ($4)}"; ok; }
