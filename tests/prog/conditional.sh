#!/usr/bin/env bash
# Conditional subspaces (Sharp et al. §3.5; issue 19 item 2): crom-fitfield
# --condition trains one energy map over a range of a scenario parameter
# (here the modulus ratio of the clamped half of a bar, 1 to 10), and
# crom-reducedstep --model --condition runs it at a value: the static sag
# under gravity at ratios 2 and 7 (not drawn as such in training) against
# crom-fullsim with that region's modulus, decoded at the condition each
# frame records (after 20000 steps of training on 110 vertices, seeds 1-4:
# 18%, 12%, 5.9%, 8.8% at ratio 2 and 11%, 7.9%, 3.9%, 3.5% at 7; the
# bound is 25%; decoding every frame at the middle of the range instead,
# as before frames recorded their condition, gave 37-47%);
# the reduced sag follows the stiffness (half as large at 7 as at 2); a run
# whose ratio jumps from 1 to 10 mid-run stays finite and dissipates at
# every step but the change's; a gravity condition scales the sag; a map
# over where a pinned end is held (pin:tip:y) holds the end there and sags
# like crom-fullsim moving it, and follows a schedule; bad conditions are
# one line.
# asan: skip (training; tests/unit/test_datafree.c checks the conditional loss and map under ASan)
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
crom-mesh box --dims 1,0.2,0.2 --size 0.1 --region clamp='x<-0.49' --region tip='x>0.49' -o bar.h5
MAT=(--youngs 2e5 --poisson 0.45 --density 1000)
STATIC=(--pin clamp --gravity 0,-9.81,0 --dt 0.02 --steps 100 --damping 20 --max-iter 200)
crom-fitfield --objective energy --mesh bar.h5 "${MAT[@]}" --pin clamp --rank 4 --condition 'ratio:x<0=1:10' \
  --steps 20000 -q -o cmap.h5
crom-info --check cmap.h5 >/dev/null || fail "crom-info --check cmap.h5"; ok
$PY - cmap.h5 <<'PYEOF' || fail "the model records its condition"
import sys, h5py
f = h5py.File(sys.argv[1])
s = lambda v: v.decode() if isinstance(v, bytes) else v
if s(f.attrs["conditions"]) != "ratio:x<0=1:10\n" or f.attrs["rank"] != 4:
    raise SystemExit("conditions %r, rank %r" % (f.attrs["conditions"], f.attrs["rank"]))
PYEOF
ok
for c in 2 7; do
  crom-fullsim "${MAT[@]}" --youngs "x<0=$(awk "BEGIN {print 2e5 * $c}")" "${STATIC[@]}" -q -o full$c.h5 bar.h5
  crom-reducedstep --model cmap.h5 "${MAT[@]}" "${STATIC[@]}" --condition "ratio:x<0=$c" -q -o red$c.h5
  crom-info --check red$c.h5 >/dev/null || fail "crom-info --check red$c.h5"; ok
  crom-diff --model cmap.h5 red$c.h5 full$c.h5 > diff$c.txt
done
$PY - <<'PYEOF' || fail "conditional static sag"
import h5py, numpy as np
def last_error(path):
    rows = [l.split() for l in open(path) if l.strip()[:1].isdigit()]
    return float(rows[-1][2])
s = lambda v: v.decode() if isinstance(v, bytes) else v
e = {c: last_error("diff%d.txt" % c) for c in (2, 7)}
tip = {}
for c in (2, 7):
    f = h5py.File("full%d.h5" % c)
    X = f["mesh/vertices"][()]
    tip[c] = f["frames/displacement"][-1][X[:, 0] > 0.49, 1].mean()
    sc = s(h5py.File("red%d.h5" % c).attrs["scenario"])
    if not any(l.startswith("--youngs x<0=") and float(l.split("=")[1]) == 2e5 * c for l in sc.splitlines()):
        raise SystemExit("the reduced run's scenario lacks the region's modulus: %r" % sc)
print("static error at ratio 2: %.3f, at 7: %.3f; full tip sag %.3f and %.3f m" % (e[2], e[7], tip[2], tip[7]))
if not (e[2] < 0.25 and e[7] < 0.25):
    raise SystemExit("static error above 25%")
if not (tip[2] < 1.8 * tip[7]):           # (sags are negative)
    raise SystemExit("the full runs do not depend on the ratio")
PYEOF
ok
# the reduced sag follows the ratio: decoded tip sags
for c in 2 7; do crom-export --format vtu --model cmap.h5 -o red$c.vtu red$c.h5 -q; done
$PY - <<'PYEOF' || fail "the reduced sag does not follow the ratio"
import meshio
t = {}
for c in (2, 7):
    m = meshio.read("red%d.vtu" % c)
    t[c] = m.point_data["displacement"][m.points[:, 0] > 0.49, 1].mean()
print("reduced tip sag at ratio 2: %.3f m, at 7: %.3f m" % (t[2], t[7]))
if not (t[2] < 1.6 * t[7] < 0):
    raise SystemExit(str(t))
PYEOF
ok
# the ratio jumps from 1 to 10 at t = 0.6 s in a lightly damped run
crom-reducedstep --model cmap.h5 "${MAT[@]}" --pin clamp --gravity 0,-9.81,0 --dt 0.02 --steps 100 --damping 2 \
  --condition 'ratio:x<0=1' --condition 'ratio:x<0=10@0.6' -q -o jump.h5
$PY - <<'PYEOF' || fail "a mid-run change of condition"
import h5py, numpy as np
f = h5py.File("jump.h5")["frames"]
t, tot, q = f["time"][()], f["total_energy"][()], f["q"][()]
if not (np.all(np.isfinite(tot)) and np.all(np.isfinite(q))):
    raise SystemExit("not finite")
# damped implicit Euler under constant loads dissipates: the total energy
# falls at every step but the one where the condition changes (the same q
# in the stiffer map's shape: the jump is that step's)
d = np.diff(tot)
jump = np.flatnonzero(np.abs(t[1:] - 0.6) < 1e-9)
print("mid-run change: total energy %.4g J before it, %.4g J after; largest rise elsewhere %.3g J"
      % (tot[jump[0]], tot[jump[0] + 1], np.delete(d, jump).max()))
if not (len(jump) == 1 and np.all(np.delete(d, jump) <= 1e-9 * np.abs(tot).max())):
    raise SystemExit("the energy grew away from the change")
PYEOF
ok
# a gravity condition: twice the gravity, more sag
crom-fitfield --objective energy --mesh bar.h5 "${MAT[@]}" --pin clamp --rank 3 --condition 'gravity:y=-15:-3' \
  --steps 6000 -q -o gmap.h5
for g in 4 12; do
  crom-reducedstep --model gmap.h5 "${MAT[@]}" "${STATIC[@]}" --condition "gravity:y=-$g" -q -o g$g.h5
  crom-export --format vtu --model gmap.h5 -o g$g.vtu g$g.h5 -q
done
$PY - <<'PYEOF' || fail "the gravity condition"
import meshio
t = {g: (lambda m: m.point_data["displacement"][m.points[:, 0] > 0.49, 1].mean())(meshio.read("g%d.vtu" % g))
     for g in (4, 12)}
print("reduced tip sag at g = 4: %.3f m, at 12: %.3f m" % (t[4], t[12]))
if not (t[12] < 1.5 * t[4] < 0):
    raise SystemExit(str(t))
PYEOF
ok

# where a pinned end is held (Sharp's conditional bar): the bar pinned at
# both ends, its far end moved along y; crom-fullsim moves it there with
# --velocity and holds it
crom-fitfield --objective energy --mesh bar.h5 "${MAT[@]}" --pin clamp --pin tip --gravity 0,-9.81,0 --rank 4 \
  --condition 'pin:tip:y=-0.2:0.2' --steps 20000 -q -o pmap.h5
PST=(--gravity 0,-9.81,0 --dt 0.02 --steps 100 --damping 20 --max-iter 200)
for c in 0.1 -0.15; do
  crom-fullsim "${MAT[@]}" "${PST[@]}" --pin clamp --velocity tip=0,$(awk "BEGIN {print $c / 0.5}"),0@0:0.5 -q \
    -o pfull$c.h5 bar.h5
  crom-reducedstep --model pmap.h5 "${MAT[@]}" "${PST[@]}" --pin clamp --pin tip --condition "pin:tip:y=$c" -q \
    -o pred$c.h5
  crom-diff --model pmap.h5 pred$c.h5 pfull$c.h5 > pdiff$c.txt
  crom-export --format vtu --model pmap.h5 -o pred$c.vtu pred$c.h5 -q
done
# measured (seed 1): 5.3 % at 0.1 m and 10.9 % at -0.15 m (seeds 2 and 3:
# 5.7 % and 9.9 %, 6.5 % and 6.5 %; 60000 steps: 4.9 % and 3.8 %)
$PY - <<'PYEOF' || fail "the pin condition's static error"
import h5py, meshio, numpy as np
for c in ("0.1", "-0.15"):
    rows = [l.split() for l in open("pdiff%s.txt" % c) if l.strip()[:1].isdigit()]
    e = float(rows[-1][2])
    m = meshio.read("pred%s.vtu" % c)
    tip = m.point_data["displacement"][m.points[:, 0] > 0.49, 1]
    f = h5py.File("pfull%s.h5" % c)
    X = f["mesh/vertices"][()]
    mid = f["frames/displacement"][-1][np.abs(X[:, 0]) < 0.06, 1].mean()
    red = m.point_data["displacement"][np.abs(m.points[:, 0]) < 0.06, 1].mean()
    print("pin at %s m: the reduced tip at %.6f..%.6f m; middle %.4f m (full %.4f m); static error %.3f"
          % (c, tip.min(), tip.max(), red, mid, e))
    if not (np.abs(tip - float(c)).max() < 1e-12 and e < 0.2):
        raise SystemExit("pin at %s" % c)
PYEOF
ok
# the pin moves mid-run: the decoded far end follows the schedule
crom-reducedstep --model pmap.h5 "${MAT[@]}" "${PST[@]}" --steps 60 --pin clamp --pin tip --condition 'pin:tip:y=0' \
  --condition 'pin:tip:y=0.12@0.6' -q -o pjump.h5
crom-export --format vtu --model pmap.h5 --frame 29 -o pj29.vtu pjump.h5 -q
crom-export --format vtu --model pmap.h5 -o pj60.vtu pjump.h5 -q
$PY - <<'PYEOF' || fail "the pin's schedule"
import meshio, numpy as np
a = [meshio.read(p) for p in ("pj29.vtu", "pj60.vtu")]
y = [m.point_data["displacement"][m.points[:, 0] > 0.49, 1] for m in a]
print("far end before the change %.3g m, after %.6f m" % (np.abs(y[0]).max(), y[1].mean()))
if not (np.abs(y[0]).max() < 1e-12 and np.abs(y[1] - 0.12).max() < 1e-12):
    raise SystemExit("the far end does not follow")
PYEOF
ok

# bad conditions
O=$TMP/out.h5
expect_error 64 "--condition pin:tip:y: the region is not pinned \(give --pin tip\)" $O -- crom-fitfield --objective energy --mesh bar.h5 --pin clamp --condition 'pin:tip:y=0:1' -o $O
expect_error 64 "--condition 'pin:tip:w=0:1': expected pin:REGION:x\|y\|z" $O -- crom-fitfield --objective energy --mesh bar.h5 --pin clamp --pin tip --condition 'pin:tip:w=0:1' -o $O
expect_error 64 "--condition 'stiff': not a condition" $O -- crom-fitfield --objective energy --mesh bar.h5 --condition stiff=1:2 -o $O
expect_error 64 "--condition 'ratio:x<0=3:1': the range is empty" $O -- crom-fitfield --objective energy --mesh bar.h5 --condition 'ratio:x<0=3:1' -o $O
expect_error 64 "--condition applies to --objective energy" $O -- crom-fitfield --objective field --mesh bar.h5 --condition 'ratio:x<0=1:2' -o $O
expect_error 64 "--condition gravity:y: model .* has no such condition" $O -- crom-reducedstep --model cmap.h5 --condition gravity:y=-3 -o $O
crom-modes "${MAT[@]}" --pin clamp --count 2 -q -o modes.h5 bar.h5
expect_error 64 "--condition ratio:x<0: model .* is not conditional" $O -- crom-reducedstep --model modes.h5 --pin clamp --condition 'ratio:x<0=2' -o $O
expect_error 64 "--condition applies to --model" $O -- crom-reducedstep --cubature nope.h5 --condition 'ratio:x<0=2' -o $O
# a model whose conditions attribute is not one (the reader refuses it in one line)
cp cmap.h5 badc.h5
$PY -c "import h5py; h5py.File('badc.h5', 'r+').attrs['conditions'] = 'stiff=1:2\n'"
expect_error 65 "conditions 'stiff': not a condition" $O -- crom-reducedstep --model badc.h5 --pin clamp -o $O
crom-info --check pmap.h5 >/dev/null || fail "crom-info --check pmap.h5"; ok
cp pmap.h5 nolift.h5
$PY -c "import h5py; del h5py.File('nolift.h5', 'r+')['field/lifts']"
expect_error 65 "a map with a pin condition needs its static lifts field/lifts" $O -- crom-reducedstep --model nolift.h5 --pin clamp --pin tip -o $O
expect_error 64 "--condition .*: the time must be >= 0" $O -- crom-reducedstep --model cmap.h5 --condition 'ratio:x<0=2@-1' -o $O
expect_error 64 "predicate 'x<-5' selects no vertex" $O -- crom-fitfield --objective energy --mesh bar.h5 --pin clamp --condition 'ratio:x<-5=1:2' -o $O
done_checks
