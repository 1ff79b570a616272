#!/usr/bin/env bash
# crom-live (issue 21 item 1): a reduced run steered by commands between its
# steps.
#   - a script of force and step commands gives the trajectory of the
#     equivalent offline crom-reducedstep run (--force windows starting half a
#     step after each command), to round-off, with and without the clock;
#   - with the clock the run takes at least its simulated time of wall time,
#     and its frames say when they were written (wall_time, late);
#   - a drag pulls its region toward the point: a stiff one brings the region's
#     centroid to it, the dragged vertex of '#N' moves toward it, and release
#     lets the body spring back; pin, unpin and schedule keep the state;
#   - bad commands (unknown, an unknown region, NaN, a bad count) are one
#     line each and the run goes on; a reader that goes away ends it (141);
#     bad flags are one line and no output.
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
SC=(--velocity 'top=0,-2,0@0:0.1' --pin bottom --gravity 0,-9.81,0 --dt 0.01 --steps 30)
crom-mesh box --size 0.15 --region top='y>0.45' --region bottom='y<-0.45' -q -o mesh.h5
crom-fullsim "${SC[@]}" -q -o full.h5 mesh.h5
crom-sample --points all full.h5 -o s.h5 2>/dev/null
crom-fitfield --basis pod --rank 6 -q -o pod.h5 s.h5
crom-cubature --model pod.h5 --scheme all -q -o cub.h5 mesh.h5
RUN=(--cubature cub.h5 --pin bottom --gravity 0,0,0 --youngs 2e5 --dt 0.01)

# q of run A against run B: max |qa - qb| / max |qb|
qdiff() { $PY -c "
import h5py, numpy as np, sys
a, b = (h5py.File(f, 'r')['frames/q'][()] for f in sys.argv[1:3])
if a.shape != b.shape: sys.exit('shapes %s %s' % (a.shape, b.shape))
print('%.3g' % (np.abs(a - b).max() / np.abs(b).max()))" "$1" "$2"; }

# ---- forces: live against offline
printf 'force top 0,-400,0\nstep 15\nforce top 100,0,0\nstep 10\nforce top 0,0,0\nstep 10\n' >forces.txt
crom-live "${RUN[@]}" --no-clock --commands forces.txt -q -o live.h5
crom-reducedstep "${RUN[@]}" --steps 35 --force 'top=0,-400,0@0.005:0.155' --force 'top=100,0,0@0.155:0.255' \
  -q -o off.h5
d=$(qdiff live.h5 off.h5); echo "forces: live (no clock) against crom-reducedstep: $d"
awk -v d="$d" 'BEGIN { exit !(d <= 1e-12) }' || fail "live run differs from the offline one by $d"; ok
$PY -c "import h5py, numpy as np, sys; q = h5py.File('off.h5')['frames/q'][()]; sys.exit(0 if np.abs(q).max() > 1e-3 else 'no motion')" \
  || fail "the forces did not move the body"; ok
# the clock paces the steps and changes nothing else
unset SOURCE_DATE_EPOCH
start=$(date +%s.%N)
crom-live "${RUN[@]}" <forces.txt -q -o clock.h5
took=$($PY -c "import sys; print(float(sys.argv[2]) - float(sys.argv[1]))" "$start" "$(date +%s.%N)")
export SOURCE_DATE_EPOCH=1700000000
d=$(qdiff clock.h5 off.h5); echo "forces: live (clock) against crom-reducedstep: $d; $took s of wall time for 0.35 s"
awk -v d="$d" 'BEGIN { exit !(d <= 1e-12) }' || fail "live run with the clock differs by $d"; ok
awk -v t="$took" 'BEGIN { exit !(t >= 0.34) }' || fail "35 steps of 10 ms took $took s: not paced"; ok
$PY - clock.h5 <<'PYEOF' || fail "wall_time and late"
import h5py, numpy as np, sys
f = h5py.File(sys.argv[1], "r")["frames"]
t, w, late = f["time"][()], f["wall_time"][()], f["late"][()]
if not (len(t) == 36 and t[-1] > 0.349): raise SystemExit("frames %d, last time %g" % (len(t), t[-1]))
if not np.all(np.diff(w) > 0): raise SystemExit("wall times not increasing")
if not np.all(w[1:] >= t[:-1] - 1e-3): raise SystemExit("a step began before its time")  # paced: step k+1 starts at t_k
if not np.array_equal(late, (w > t) & (np.arange(len(t)) > 0)): raise SystemExit("late is not wall_time > time")
print("wall_time - time: %.4f .. %.4f s; %d late" % ((w - t).min(), (w - t).max(), late.sum()))
PYEOF
ok
# a step slower than dt is late, and the run says so once and counts them
printf 'step 5\n' | crom-live "${RUN[@]}" --dt 1e-7 -o slow.h5 2>slow.err || fail "slow run: $(cat slow.err)"
grep -q "warning: step 1 ended .* after its simulated time: steps take longer than --dt" slow.err || fail "no lateness warning: $(cat slow.err)"; ok
grep -q "5 of 5 steps ended after their simulated time" slow.err || fail "no lateness count: $(cat slow.err)"; ok

# through a pipe, frame by frame, into crom-export (decoded on the mesh as they come)
crom-live "${RUN[@]}" --no-clock <forces.txt 2>/dev/null | crom-export --model pod.h5 --mesh mesh.h5 -q -o piped.pvd \
  || fail "crom-live | crom-export"
[ "$(ls piped/*.vtu | wc -l)" = 36 ] || fail "$(ls piped/*.vtu | wc -l) frames through the pipe, expected 36"; ok

# ---- drags
# the region's centroid decoded from q: mass-weighted over its vertices
centroid() { $PY -c "
import h5py, numpy as np, sys
c = h5py.File('cub.h5', 'r'); W = c['W'][()]; X = c['mesh/vertices'][()]; V = c['lumped_volume'][()]
r = W.shape[-1]; W = W.reshape(len(X), 3, r)
idx = c['mesh/regions/' + sys.argv[2]][()] if not sys.argv[2].startswith('#') else np.array([int(sys.argv[2][1:])])
q = h5py.File(sys.argv[1], 'r')['frames/q'][()][int(sys.argv[3])]
x = X[idx] + W[idx] @ q
print(*(np.average(x, axis=0, weights=V[idx])))" "$@"; }
# (the POD basis of a vertical compression moves the top's centroid only
# vertically: the point is above it; the box's own stiffness there is about
# E A / L = 2e5 N/m, so a spring of 1e7 N/m takes it 98% of the way)
read -r X0 Y0 Z0 < <(centroid live.h5 top 0)
TX=$X0 TY=0.6 TZ=$Z0
printf 'drag top %s,%s,%s 1e7\nstep 60\n' $TX $TY $TZ | crom-live "${RUN[@]}" --damping 20 --no-clock -q -o drag.h5
read -r X1 Y1 Z1 < <(centroid drag.h5 top -1)
echo "drag top toward ($TX, $TY, $TZ): centroid from ($X0, $Y0, $Z0) to ($X1, $Y1, $Z1)"
$PY -c "
import sys, math
x0, x1, t = [list(map(float, sys.argv[i:i + 3])) for i in (1, 4, 7)]
d0, d1 = math.dist(x0, t), math.dist(x1, t)
print('distance to the point: %.4f -> %.4f m' % (d0, d1))
sys.exit(0 if d1 < 0.05 * d0 else 1)" $X0 $Y0 $Z0 $X1 $Y1 $Z1 $TX $TY $TZ || fail "a stiff drag did not bring the centroid to the point"; ok
# one vertex, then released: it springs back toward rest
read -r V VT < <($PY -c "
import h5py, numpy as np
X = h5py.File('cub.h5', 'r')['mesh/vertices'][()]
v = int(np.argmax(X[:, 1] + 0.1 * X[:, 0]))
print(v, '%.17g,%.17g,%.17g' % (X[v, 0], X[v, 1] + 0.1, X[v, 2]))")
printf 'drag #%s %s 2e5\nstep 40\nrelease\nstep 60\n' "$V" "$VT" | crom-live "${RUN[@]}" --damping 20 --no-clock -q -o vdrag.h5
$PY - vdrag.h5 "$V" <<'PYEOF' || fail "vertex drag"
import h5py, numpy as np, sys
c = h5py.File("cub.h5", "r"); W = c["W"][()]; X = c["mesh/vertices"][()]
W = W.reshape(len(X), 3, W.shape[-1]); v = int(sys.argv[2])
q = h5py.File(sys.argv[1], "r")["frames/q"][()]
x = X[v] + np.einsum("ij,fj->fi", W[v], q)
t = X[v] + np.array([0, 0.1, 0])
d0, d40, d100 = (np.linalg.norm(x[k] - t) for k in (0, 40, 100))
back = np.linalg.norm(x[100] - X[v])
print("vertex #%d: %.4f m from the point at rest, %.4f after the drag, %.4f from rest after the release" % (v, d0, d40, back))
if not (d40 < 0.7 * d0 and back < 0.2 * np.linalg.norm(x[40] - X[v])): raise SystemExit("the vertex did not follow the drag and spring back")
PYEOF
ok
# pin holds the region at rest (the penalty pulls it back), unpin lets the
# force move it again, schedule switches the cubature and keeps the state
printf 'force top 0,-4000,0\nstep 10\npin top\nstep 5\nunpin top\nschedule cub.h5\nstep 5\n' \
  | crom-live "${RUN[@]}" --no-clock -q -o pins.h5
read -r _ ya _ < <(centroid pins.h5 top 10)
read -r _ yb _ < <(centroid pins.h5 top 15)
read -r _ yc _ < <(centroid pins.h5 top 20)
echo "top's centroid: y = $ya pushed, $yb pinned 5 steps, $yc free again"
$PY -c "
import sys, h5py, numpy as np
ya, yb, yc = (float(v) - 0.5 for v in sys.argv[1:4])   # displacements (the top is at y = 0.5)
c = h5py.File('pins.h5', 'r')['frames/cubature'][()]
if not (ya < -1e-3 and abs(yb) < 0.1 * abs(ya) and abs(yc - yb) > 10 * abs(yb)): raise SystemExit(str((ya, yb, yc)))
if not (c[15] == 0 and c[16] == 1 and c[-1] == 1): raise SystemExit(str(c))
" $ya $yb $yc || fail "pin/unpin/schedule"; ok

# ---- bad commands: one line each, the run goes on
printf 'bogus 1\ndrag nowhere 0,0,0\ndrag top nan,0,0\nforce top 1,2\nstep -3\nunpin top\ncondition E=2\nschedule missing.h5\nstep 3\n' \
  | crom-live "${RUN[@]}" --no-clock -o bad.h5 2>bad.err || fail "the run did not go on: $(cat bad.err)"
cat bad.err
for pat in "line 1: unknown command 'bogus'" "line 2: drag: unknown region 'nowhere'" "line 3: drag: 'nan' is not a finite" \
  "line 4: force:" "line 5: step" "line 6: unpin top: not pinned" "line 7: condition E=2: model .* has no conditions" \
  "line 8: .*missing.h5"; do
  [ "$(grep -c "^crom-live: warning: $pat" bad.err)" = 1 ] || fail "no one-line message /$pat/"; ok
done
[ "$(grep -c warning bad.err)" = 8 ] || fail "$(grep -c warning bad.err) warnings for 8 bad lines"; ok
$PY -c "import h5py, sys; sys.exit(0 if h5py.File('bad.h5')['frames/q'].shape[0] == 4 else 1)" || fail "the 3 steps after the bad lines"; ok
# a reader that goes away: the run ends at once with SIGPIPE's status, nothing more
set +o pipefail
rc=$( (printf 'step 100000\n' | crom-live "${RUN[@]}" --no-clock 2>pipe.err; echo $? >rc.txt) | head -c 200 >/dev/null; cat rc.txt)
set -o pipefail
[ "$rc" = 141 ] || fail "a closed pipe: exit $rc: $(cat pipe.err)"; ok
# bad flags
expect_error 64 "--cubature CUB is required" out.h5 -- crom-live --pin bottom -o out.h5
expect_error 66 "nope.txt: No such file" out.h5 -- crom-live "${RUN[@]}" --commands nope.txt -o out.h5
expect_error 64 "--drag-stiffness" out.h5 -- crom-live "${RUN[@]}" --drag-stiffness -1 -o out.h5
expect_error 64 "unknown region 'nowhere'" out.h5 -- crom-live --cubature cub.h5 --pin nowhere -o out.h5
done_checks
