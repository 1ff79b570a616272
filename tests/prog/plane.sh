#!/usr/bin/env bash
# 2-D solids in plane strain (issue 19 item 3) through the programs:
# crom-mesh sheet --plane-strain records the kind; crom-fullsim bends a
# clamped 2-D bar under gravity in its plane (z stays 0 exactly) as
# Timoshenko's plane-strain beam predicts for the small load; crom-modes
# finds in-plane modes first; crom-export writes the triangles with their
# cell fields; an energy map trained on it runs in crom-reducedstep --model
# and stays in the plane; a neural-modes map too; bad input is one line.
# (The bistable bar: tests/prog/bistable.sh.)
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
crom-mesh sheet --dims 1,0.1,1 --size 0.02 --thickness 0.1 --plane-strain --region clamp='x<-0.499' \
  --region tip='x>0.499' -o bar.h5
crom-info --check bar.h5 >/dev/null || fail "crom-info --check bar.h5"; ok
$PY -c "import h5py,sys; sys.exit(0 if h5py.File('bar.h5')['triangles'].attrs['plane_strain'] == 1 else 1)" \
  || fail "plane_strain attribute"; ok
# a small tip load: the beam's deflection (Timoshenko, plane strain)
crom-fullsim --youngs 1e7 --poisson 0.3 --gravity 0,0,0 --pin clamp --force tip=0,-1,0 --dt 1000 --steps 1 \
  --tol 1e-10 -q -o tipload.h5 bar.h5
crom-info --check tipload.h5 >/dev/null || fail "crom-info --check tipload.h5"; ok
$PY - <<'PYEOF' || fail "plane-strain cantilever"
import h5py, numpy as np
f = h5py.File("tipload.h5")
X, u = f["mesh/vertices"][()], f["frames/displacement"][-1]
w = -u[X[:, 0] > 0.499, 1].mean()
E, nu, t, h, L, P = 1e7, 0.3, 0.1, 0.1, 1.0, 1.0
want = P * L**3 / (3 * E / (1 - nu**2) * t * h**3 / 12) + P * L / (5 / 6 * E / (2 * (1 + nu)) * t * h)
print("tip deflection %.5g m, Timoshenko %.5g m (ratio %.4f); largest |z| %g" % (w, want, w / want, np.abs(u[:, 2]).max()))
if not (abs(w / want - 1) < 0.1 and np.abs(u[:, 2]).max() == 0):
    raise SystemExit("not the beam")
PYEOF
ok
crom-export --format vtu -o tipload.vtu tipload.h5 -q --youngs 1e7 --poisson 0.3
$PY -c "import meshio,sys; m=meshio.read('tipload.vtu'); sys.exit(0 if m.cells[0].type=='triangle' else 1)" \
  || fail "vtu of triangles"; ok
# modes: the lowest bend the bar in its plane
MAT=(--youngs 1e6 --poisson 0.3 --density 1000)
crom-modes "${MAT[@]}" --pin clamp --count 4 -q -o modes.h5 bar.h5
$PY - <<'PYEOF' || fail "in-plane modes"
import h5py, numpy as np
W = h5py.File("modes.h5")["field/basis"][()]
z = np.abs(W[:, 2, :]).max()
print("modes: largest z component %g" % z)
if z > 1e-9:
    raise SystemExit("a mode leaves the plane")
PYEOF
ok
# data-free: an energy map of the 2-D bar sagging under gravity, and neural
# modes (training: not under the sanitizers, whose pass runs the rest)
if [ "${CROM_SANITIZE:-0}" != 1 ]; then
crom-fitfield --objective energy --mesh bar.h5 "${MAT[@]}" --pin clamp --rank 3 --steps 3000 -q -o e3.h5
crom-fitfield --objective neuralmodes --mesh bar.h5 --modes modes.h5 --derivatives --steps 300 -q -o nm.h5
SAG=(--pin clamp --gravity 0,-9.81,0 --dt 0.02 --steps 60 --damping 20)
crom-fullsim "${MAT[@]}" "${SAG[@]}" -q -o sag.h5 bar.h5
for m in e3 nm; do
  crom-reducedstep --model $m.h5 "${MAT[@]}" "${SAG[@]}" -q -o r$m.h5
  crom-export --format vtu --model $m.h5 -o r$m.vtu r$m.h5 -q
  e=$(crom-diff --model $m.h5 r$m.h5 sag.h5 | sed -n 's/^relative displacement error \([^ ]*\) .*/\1/p')
  echo "$m: relative error $e against crom-fullsim"
  $PY -c "import meshio,sys; u=meshio.read('r$m.vtu').point_data['displacement']; sys.exit(0 if abs(u[:,2]).max()==0 and u[:,1].min()<-0.05 else 1)" \
    || fail "$m: the reduced sag leaves the plane or does not sag"; ok
done
fi
# bad input
O=$TMP/out.h5
expect_error 64 "--plane-strain is for triangles in z = 0" $O -- crom-mesh box --plane-strain -o $O
cp bar.h5 badplane.h5
$PY -c "import h5py; h5py.File('badplane.h5', 'r+')['triangles'].attrs['plane_strain'] = 7"
expect_error 65 "plane_strain must be 0 or 1" $O -- crom-fullsim --steps 1 -o $O badplane.h5
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0.5\nf 1 2 3\n' > tilted.obj
expect_error 65 "--plane-strain: vertex 2 is at z = 0.5" $O -- crom-mesh import tilted.obj --thickness 0.1 --plane-strain -o $O
done_checks
