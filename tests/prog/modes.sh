#!/usr/bin/env bash
# crom-modes end to end: the model it writes (schema, M-orthonormal fields,
# frequencies, attributes, pins), pipes and reproducibility, rigid modes of a
# free body (and a falling bar that needs them), the classic linear modal ROM
# through crom-cubature and crom-reducedstep against crom-fullsim, bad input.
# asan: skip (eigensolves and reduced runs of several bars, 58 s under ASan; tests/unit/test_modes.c and test_mderiv.c cover the same library code there)
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
crom-mesh box --dims 1,0.2,0.2 --size 0.05 --region clamp='x<-0.49' -o bar.h5
MAT=(--youngs 1e7 --poisson 0.3 --density 1000)

# 1. a clamped bar: a valid crom/model with ascending frequencies, fields
#    orthonormal in the mass mean (W^T M W = m I), zero on the clamp
crom-modes "${MAT[@]}" --pin clamp --count 12 -v -o modes.h5 bar.h5 2>modes.log
crom-info --check modes.h5 >/dev/null || fail "crom-info --check modes.h5"; ok
grep -q "crom-modes: 12 modes, .* Hz; no rigid mode" modes.log || fail "summary line: $(cat modes.log)"; ok
grep -q "Lanczos .* solves" modes.log || fail "verbose timing"; ok
$PY - modes.h5 bar.h5 <<'PYEOF' || fail "modes model"
import sys, h5py, numpy as np
f, b = h5py.File(sys.argv[1]), h5py.File(sys.argv[2])
if not (f.attrs["basis"] in (b"modes", "modes") and f.attrs["rank"] == 12):
    raise SystemExit("check failed: f.attrs[\"basis\"] in (b\"modes\", \"modes\") and f.attrs[\"rank\"] == 12")
X = f["field/mesh/vertices"][()]; T = f["field/mesh/tets"][()]; W = f["field/basis"][()]
if not (np.array_equal(X, b["vertices"][()]) and np.array_equal(T, b["tets"][()])):
    raise SystemExit("check failed: np.array_equal(X, b[\"vertices\"][()]) and np.array_equal(T, b[\"tets\"][()])")
# lumped mass: rho V / 4 per tet vertex
P = X[T]; V = np.einsum("ij,ij->i", np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]), P[:, 3] - P[:, 0]) / 6
m = np.zeros(len(X)); np.add.at(m, T.ravel(), np.repeat(1000 * V / 4, 4))
mass = f.attrs["mass"]
if not (abs(mass - m.sum()) < 1e-12 * mass):
    raise SystemExit(f"check failed: {(mass, m.sum())!s}")
G = np.einsum("v,vcr,vcs->rs", m, W, W) / mass
err = np.abs(G - np.eye(12)).max()
print("max |W^T M W / m - I| = %.2e" % err)
if not (err < 1e-10):
    raise SystemExit("check failed: err < 1e-10")
clamp = b["regions/clamp"][()]
if not (np.all(W[clamp] == 0)):
    raise SystemExit("check failed: np.all(W[clamp] == 0)")
fr = f["frequencies"][()]
if not (np.all(np.diff(fr) >= 0) and fr[0] > 0):
    raise SystemExit("check failed: np.all(np.diff(fr) >= 0) and fr[0] > 0")
# Euler-Bernoulli's first bending frequency of this bar is 3.23 Hz; linear tets
# are stiffer (about 7% on this mesh), and the square section makes it a pair
eb = 1.8751**2 / (2 * np.pi) * np.sqrt(1e7 * 0.2**2 / 12 / 1000)
print("frequencies (Hz):", " ".join("%.4g" % x for x in fr), "; EB f1 = %.4g" % eb)
if not (1.0 < fr[0] / eb < 1.15 and abs(fr[1] / fr[0] - 1) < 0.01):
    raise SystemExit("check failed: 1.0 < fr[0] / eb < 1.15 and abs(fr[1] / fr[0] - 1) < 0.01")
s = f.attrs["scenario"]; s = s.decode() if isinstance(s, bytes) else s
if not ("--youngs 10000000" in s and "--poisson 0.29999999999999999" in s and "--pin clamp" in s):
    raise SystemExit(f"check failed: {s!s}")
if not (f.attrs["youngs"] == 1e7 and f.attrs["poisson"] == 0.3 and f.attrs["density"] == 1000):
    raise SystemExit("check failed: f.attrs[\"youngs\"] == 1e7 and f.attrs[\"poisson\"] == 0.3 and f.attrs[\"density\"] == 1000")
if not (f.attrs["rigid_modes"] == 0 and f.attrs["rigid_kept"] == 0):
    raise SystemExit("check failed: f.attrs[\"rigid_modes\"] == 0 and f.attrs[\"rigid_kept\"] == 0")
PYEOF
ok

# 2. through pipes (the same model as the file), the same bytes again, and
#    another seed gives the same frequencies
crom-modes "${MAT[@]}" --pin clamp --count 12 -q <bar.h5 >pipe.h5
crom-modes "${MAT[@]}" --pin clamp --count 12 -q <bar.h5 | cat >pipe2.h5
cmp -s pipe.h5 pipe2.h5 || fail "same inputs and seed, different bytes"; ok
crom-modes "${MAT[@]}" --pin clamp --count 12 -q --seed 5 -o seed5.h5 bar.h5
$PY -c "
import h5py, numpy as np
a, p, s = (h5py.File(x) for x in ('modes.h5', 'pipe.h5', 'seed5.h5'))
if not (a.attrs['model_id'] == p.attrs['model_id'] and np.array_equal(a['field/basis'][()], p['field/basis'][()])): raise SystemExit('check failed: piped model differs')
fa, fs = a['frequencies'][()], s['frequencies'][()]
if not (np.abs(fa / fs - 1).max() < 1e-9): raise SystemExit('check failed: ' + str((fa, fs)))" || fail "pipe or seed"; ok
# a flag file for crom-fullsim serves crom-modes (time-stepping flags ignored)
printf -- '--youngs 1e7 --poisson 0.3 --density 1000\n--pin clamp --gravity 0,-2,0 --dt 0.01 --steps 9\n' >bar.flags
crom-modes @bar.flags --count 12 -q -o flags.h5 bar.h5
$PY -c "
import h5py, numpy as np
a, b = h5py.File('modes.h5'), h5py.File('flags.h5')
if not (np.array_equal(a['field/basis'][()], b['field/basis'][()]) and a.attrs['model_id'] == b.attrs['model_id']): raise SystemExit('check failed: @FILE model differs')" \
  || fail "@FILE with scenario flags"; ok

# 3. a free body: six rigid modes detected and dropped (or kept, in front)
crom-modes --count 4 -v -o free.h5 bar.h5 2>free.log
grep -q "6 rigid modes detected (dropped" free.log || fail "rigid modes: $(cat free.log)"; ok
crom-modes --count 8 --keep-rigid -q -o freek.h5 bar.h5
$PY - free.h5 freek.h5 <<'PYEOF' || fail "free body"
import sys, h5py, numpy as np
d, k = h5py.File(sys.argv[1]), h5py.File(sys.argv[2])
fd, fk = d["frequencies"][()], k["frequencies"][()]
print("free body, rigid kept (Hz):", " ".join("%.4g" % x for x in fk))
if not (d.attrs["rigid_modes"] == 6 and d.attrs["rigid_kept"] == 0 and k.attrs["rigid_kept"] == 1):
    raise SystemExit("check failed: d.attrs[\"rigid_modes\"] == 6 and d.attrs[\"rigid_kept\"] == 0 and k.attrs[\"rigid_kept\"] == 1")
if not (np.all(fk[:6] < 1e-4) and fk[6] > 1e5 * fk[:6].max() + 1):  # six zeros, the seventh far away
    raise SystemExit("check failed: np.all(fk[:6] < 1e-4) and fk[6] > 1e5 * fk[:6].max() + 1")
if not (np.abs(fk[6:8] / fd[:2] - 1).max() < 1e-9):  # the same deformation modes
    raise SystemExit("check failed: np.abs(fk[6:8] / fd[:2] - 1).max() < 1e-9")
W = k["field/basis"][()]
if not (np.allclose(W[:, 0, 0], W[0, 0, 0]) and np.abs(W[:, 1:, 0]).max() < 1e-8):  # mode 1: x translation
    raise SystemExit("check failed: np.allclose(W[:, 0, 0], W[0, 0, 0]) and np.abs(W[:, 1:, 0]).max() < 1e-8")
PYEOF
ok

# a falling bar landing on a plane: with the rigid modes kept the modal ROM
# follows crom-fullsim (measured 0.3%); without them it cannot fall at all
FALL=(--youngs 1e6 --gravity 0,-9.81,0 --plane 0,1,0,-0.3 --dt 0.01 --steps 40)
crom-modes --youngs 1e6 --count 12 --keep-rigid -q -o fallk.h5 bar.h5
crom-modes --youngs 1e6 --count 6 -q -o falld.h5 bar.h5
crom-fullsim "${FALL[@]}" -q -o fall_full.h5 bar.h5
for m in fallk falld; do
  crom-cubature --model $m.h5 --scheme all -q -o cub_$m.h5 bar.h5
  crom-reducedstep --cubature cub_$m.h5 "${FALL[@]}" -q -o red_$m.h5
  e=$(crom-diff red_$m.h5 fall_full.h5 --model $m.h5 -q | sed -n 's/relative displacement error \([0-9.e+-]*\) over.*/\1/p')
  echo "falling bar, $m: relative error $e"
  eval "fall_$m=$e"
done
close "$fall_fallk" 0 0.02 "falling bar with rigid modes kept"
close "$fall_falld" 1 0.01 "falling bar without rigid modes"
# the same bar landing on a fixed frictional ball (--sphere, the same contact code in both simulators):
# the modal ROM follows crom-fullsim to 4.9% (measured; it bends over the ball), and the ball holds it up
BALL=(--youngs 1e6 --gravity 0,-9.81,0 --sphere 0,-1.3,0,1,0.3 --dt 0.01 --steps 40)
crom-fullsim "${BALL[@]}" -q -o ball_full.h5 bar.h5
crom-reducedstep --cubature cub_fallk.h5 "${BALL[@]}" -q -o ball_red.h5
e=$(crom-diff ball_red.h5 ball_full.h5 --model fallk.h5 -q | sed -n 's/relative displacement error \([0-9.e+-]*\) over.*/\1/p')
echo "falling bar onto a ball: modal ROM vs crom-fullsim $e"
close "$e" 0 0.08 "falling bar onto a ball"
$PY - ball_full.h5 <<'PYEOF2' || fail "the ball holds the bar up"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], 'r')
x = f['mesh/vertices'][...][None] + f['frames/displacement'][...]
d = np.linalg.norm(x - np.array([0, -1.3, 0]), axis=2).min(axis=1)
if not (d.min() > 1 - 0.025 and d.min() < 1):  # a penalty: the landing at 2 m/s sinks in 1.5 cm
    sys.exit(f"closest approach {d.min():.4f} m to the centre of the unit ball")
print(f"the ball holds the bar: closest approach {d.min():.4f} m to its centre (radius 1)")
PYEOF2
ok

# 4. the linear modal ROM: cubature over every tet, reduced implicit Euler
#    under gravity, against crom-fullsim. Small amplitude (stiff bar, g = 0.2,
#    tip deflection ~1 mm): within 0.5% (measured 0.035% with 12 modes). At
#    g = 2 the bending-stretching coupling the linear basis cannot follow
#    costs ten times more (measured 2.4%).
crom-cubature --model modes.h5 --scheme all -q -o cub.h5 bar.h5
for g in 0.2 2; do
  SC=(--pin clamp --gravity 0,-$g,0 --dt 0.01 --steps 30 --tol 1e-9)
  crom-fullsim "${MAT[@]}" "${SC[@]}" -q -o full_$g.h5 bar.h5
  crom-reducedstep --cubature cub.h5 "${MAT[@]}" "${SC[@]}" -q -o red_$g.h5
  crom-info --check red_$g.h5 >/dev/null || fail "latent invalid"; ok
  err=$(crom-diff red_$g.h5 full_$g.h5 --model modes.h5 -q | sed -n 's/relative displacement error \([0-9.e+-]*\) over.*/\1/p')
  echo "linear modal ROM (12 modes) vs crom-fullsim at g = $g: relative error $err"
  eval "err_${g/./_}=$err"
done
close "$err_0_2" 0 0.005 "small-amplitude modal ROM vs crom-fullsim"
$PY -c "import sys; sys.exit(0 if $err_2 > 10 * $err_0_2 else 1)" || fail "amplitude should cost accuracy"; ok

# 5. bad input: one line, the right status, no output left
O=out; mkdir -p $O
crom-mesh box --size 0.5 --region lid='y>0.2' -o tiny.h5
nv=$($PY -c "import h5py; print(len(h5py.File('tiny.h5')['vertices']))")
expect_error 64 "--count 5000: 5000 modes asked for, but the body has only $((3 * nv)) free degrees of freedom" $O/m.h5 -- crom-modes --count 5000 -o $O/m.h5 tiny.h5
expect_error 64 "deformation modes asked for, but the body has only $((3 * nv - 6)) \(.* 6 rigid modes\)" $O/m.h5 -- crom-modes --count $((3 * nv)) -o $O/m.h5 tiny.h5
expect_error 64 "--youngs must be a positive modulus in Pa, got 0" $O/m.h5 -- crom-modes --youngs 0 -o $O/m.h5 tiny.h5
expect_error 64 "--youngs: .* is not a finite number" $O/m.h5 -- crom-modes --youngs inf -o $O/m.h5 tiny.h5
expect_error 64 "--density must be positive, got -1" $O/m.h5 -- crom-modes --density -1 -o $O/m.h5 tiny.h5
expect_error 64 "--poisson must be in \(-1, 0.5\), got 0.5" $O/m.h5 -- crom-modes --poisson 0.5 -o $O/m.h5 tiny.h5
expect_error 64 "--poisson must be in \(-1, 0.5\), got -1.2" $O/m.h5 -- crom-modes --poisson=-1.2 -o $O/m.h5 tiny.h5
expect_error 64 "unknown region 'clamp' \(the mesh has: lid\)" $O/m.h5 -- crom-modes --pin clamp -o $O/m.h5 tiny.h5
expect_error 64 "--pin: predicate 'x<-9' selects no vertex" $O/m.h5 -- crom-modes --pin 'x<-9' -o $O/m.h5 tiny.h5
expect_error 64 "every degree of freedom is pinned" $O/m.h5 -- crom-modes --pin all -o $O/m.h5 tiny.h5
expect_error 64 "--count: 0 is out of range" $O/m.h5 -- crom-modes --count 0 -o $O/m.h5 tiny.h5
expect_error 64 "--shift must be negative, got 5" $O/m.h5 -- crom-modes --shift 5 -o $O/m.h5 tiny.h5
expect_error 65 "modes.h5 is crom/model v1, expected crom/mesh" $O/m.h5 -- crom-modes -o $O/m.h5 modes.h5
expect_error 65 "full_2.h5 is crom/trajectory v1, expected crom/mesh" $O/m.h5 -- crom-modes -o $O/m.h5 full_2.h5
expect_error 65 "stdin is empty" $O/m.h5 -- bash -c "crom-modes -o '$O/m.h5' </dev/null"
expect_error 66 "/nonexistent/m.h5: No such file or directory" $O/m.h5 -- crom-modes -o $O/m.h5 /nonexistent/m.h5
expect_error 64 "unexpected operand" $O/m.h5 -- crom-modes -o $O/m.h5 tiny.h5 tiny.h5
done_checks
