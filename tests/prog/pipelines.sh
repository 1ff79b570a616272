#!/usr/bin/env bash
# Small versions of the shapes and tearing experiments (pipelines/*.mk) run
# end to end; their tables' numbers are checked against bounds, and changing
# one stage variable reruns only that stage onward.
# asan: skip (make pipelines of simulations and training; their stages run under ASan in reduced.sh, fullsim.sh and the export tests)
. "$CROM_TOP/tests/prog/common.bash"
MK="make --no-print-directory -j2 -f $CROM_TOP/pipelines"

# column N of the row LABEL of a table CSV
cell() { awk -F, -v l="$2" -v c="$3" '$1 == l {print $c}' "$1"; }
below() { $PY -c "import sys; v=float(sys.argv[1]); sys.exit(0 if v == v and v < float(sys.argv[2]) else 1)" "$1" "$2" || fail "$3: $1 is not below $2"; ok; }
above() { $PY -c "import sys; v=float(sys.argv[1]); sys.exit(0 if v == v and v > float(sys.argv[2]) else 1)" "$1" "$2" || fail "$3: $1 is not above $2"; ok; }

# shapes: two training shapes and one unseen, tiny meshes
S="$TMP/shapes"
$MK/shapes.mk OUT="$S" TRAIN="2 box" TEST="4" SIZE=0.18 STEPS=12 EPOCHS=800 RANK=10 COUNT=40 POINTS=100 QUIET=-q >"$TMP/shapes.log" 2>&1 \
  || { tail -20 "$TMP/shapes.log"; fail "shapes pipeline"; }
T="$S/rows.txt.csv"
for r in shape-2 shape-box unseen-4; do
  below "$(cell "$T" $r 6)" 0.4 "shapes $r relative error"
  above "$(cell "$T" $r 5)" 3 "shapes $r speedup"
done
below "$(cell "$T" shape-box 6)" 0.08 "shapes box relative error"
# the error indicator of each reduced run (no full run needed) reads within
# a factor of 5 of crom-diff's error
for r in shape-2 shape-box unseen-4; do
  ratio=$($PY -c "print($(cell "$T" $r 7) / $(cell "$T" $r 6))")
  above "$ratio" 0.2 "shapes $r indicator / error"
  below "$ratio" 5 "shapes $r indicator / error"
done
for f in strip-2.png strip-4.png red-4.pvd red-4/red-4_00000.vtu; do [ -s "$S/$f" ] || fail "missing $f"; ok; done
$PY - "$S/strip-4.png" <<'PYEOF' || fail "strip picture"
import sys, zlib, struct
d = open(sys.argv[1], "rb").read()
if not (d[:8] == b"\x89PNG\r\n\x1a\n"):
    raise SystemExit("check failed: d[:8] == b\"\\x89PNG\\r\\n\\x1a\\n\"")
w, h = struct.unpack(">II", d[16:24])
idat = b""; i = 8
while i < len(d):
    n, = struct.unpack(">I", d[i:i+4]); t = d[i+4:i+8]
    if t == b"IDAT": idat += d[i+8:i+8+n]
    i += 12 + n
raw = zlib.decompress(idat)
if not (len(raw) == h * (1 + 3 * w)):
    raise SystemExit(f"check failed: {(len(raw), w, h)!s}")
nonwhite = sum(1 for y in range(0, h, 4) for x in range(0, w, 4) if raw[y*(1+3*w) + 1 + 3*x] < 200)
if not (nonwhite > 0.05 * (w // 4) * (h // 4)):  # not blank: the bodies cover the picture
    raise SystemExit(f"check failed: {nonwhite!s}")
print("strip %dx%d, %d sampled pixels drawn" % (w, h, nonwhite))
PYEOF
ok
# one stage variable reruns that stage onward only: the cubature changes, the model does not
m0=$(stat -c %Y "$S/model.h5"); c0=$(stat -c %Y "$S/cub-box.h5"); sleep 1
$MK/shapes.mk OUT="$S" TRAIN="2 box" TEST="4" SIZE=0.18 STEPS=12 EPOCHS=800 RANK=10 COUNT=30 CUBATURE=metis POINTS=100 QUIET=-q >"$TMP/shapes2.log" 2>&1 \
  || { tail -20 "$TMP/shapes2.log"; fail "shapes rerun"; }
[ "$(stat -c %Y "$S/model.h5")" = "$m0" ] || fail "the model was retrained for a cubature change"; ok
[ "$(stat -c %Y "$S/cub-box.h5")" != "$c0" ] || fail "the cubature was not rebuilt"; ok
crom-info "$S/cub-box.h5" | grep -q "scheme *metis" || fail "cubature scheme not switched"; ok

# tearing: intact and Y-cut plate, the cut grown during the reduced run (a
# small plate, 0.3 s, the flaps of the Y falling through the cut). Issue 18's
# bounds: the intact plate within 10% of its full run, the cut one within 15%
# (measured 7.3% and 9.1%; a field of X alone, CUT_FEATURES=0, is 46% off on
# the cut plate).
P="$TMP/tearing"
$MK/tearing.mk OUT="$P" SIZE=0.0625 STEPS=30 STAGES=2 EPOCHS=1500 RANK=12 COUNT=60 POINTS=500 QUIET=-q \
  >"$TMP/tearing.log" 2>&1 || { tail -20 "$TMP/tearing.log"; fail "tearing pipeline"; }
T="$P/rows.txt.csv"
below "$(cell "$T" intact 6)" 0.10 "tearing: the intact plate's relative error"
below "$(cell "$T" Y-cut 6)" 0.15 "tearing: the Y-cut plate's relative error"
for r in intact Y-cut; do
  above "$(cell "$T" $r 5)" 3 "tearing $r speedup"
done
crom-info "$P/model.h5" | grep -qE "cut_axis +y" || fail "the tearing field has no cut features"; ok
$PY -c "
import h5py, numpy as np, sys
t = h5py.File(sys.argv[1]); c = t['frames/cubature'][()]
if not (c[0] == 0 and c[-1] == 2 and np.all(np.diff(c) >= 0)): raise SystemExit('check failed: ' + str(c))   # the cut grew in two stages
if not np.all(np.isfinite(t['frames/total_energy'][()])): raise SystemExit('check failed: non-finite energy')
" "$P/tear.h5" || fail "progressive tear schedule"; ok
[ -s "$P/strip.png" ] && [ -s "$P/basis.png" ] && [ -s "$P/tear.pvd" ] || fail "tearing pictures"; ok
# the ParaView frames follow the cut: the last frame's mesh has the duplicated
# crack vertices the first one lacks
n0=$(grep -o 'NumberOfPoints="[0-9]*"' "$P/tear/tear_00000.vtu" | tr -dc 0-9)
n1=$(grep -o 'NumberOfPoints="[0-9]*"' "$(ls "$P"/tear/tear_*.vtu | tail -1)" | tr -dc 0-9)
[ "$n1" -gt "$n0" ] || fail "tearing frames not on the cut meshes ($n0 -> $n1 vertices)"; ok

# a corrupt intermediate stops make with that stage's message, and leaves no
# stale target behind
head -c 4096 /dev/urandom >"$S/model.h5"
touch "$S/model.h5"
rm -f "$S/poses-box.h5"
rc=0; $MK/shapes.mk OUT="$S" TRAIN="2 box" TEST="4" SIZE=0.18 STEPS=12 EPOCHS=800 RANK=10 COUNT=30 CUBATURE=metis POINTS=100 QUIET=-q >"$TMP/broken.log" 2>&1 || rc=$?
[ $rc -ne 0 ] || fail "make succeeded on a corrupt model"; ok
grep -q "crom-encode: .*model.h5 is not a crom file" "$TMP/broken.log" || fail "stage message: $(tail -3 "$TMP/broken.log")"; ok
[ ! -e "$S/poses-box.h5" ] || fail "a stale poses file was left behind"; ok
! ls -a "$S" | grep -q '\.tmp$' || fail "temporary files left behind"; ok
done_checks
