#!/usr/bin/env bash
# Keyframing (Neural Modes §5, issue 19 item 5): crom-keyframe interpolates
# keyframes given as latents of a model and writes the in-betweens as a
# crom/latent series that crom-export decodes. The keys come back exactly at
# their frames; for linear modes the energy of the interpolated latent is
# the energy of the interpolated positions (x is linear in q); for neural
# modes of a clamped bar bent up and down, the in-betweens through the map
# store far less strain energy than the linear interpolation of the
# keyframes' positions, which shortens the bending bar. A keys file gives
# the same frames as the flags; bad input is one line.
# asan: skip (training; tests/unit/test_keyframe.c runs the library code under ASan)
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
crom-mesh box --dims 1,0.2,0.2 --size 0.1 --region clamp='x<-0.49' -o bar.h5
MAT=(--youngs 1e6 --poisson 0.3 --density 1000)
crom-modes "${MAT[@]}" --pin clamp --count 3 -q -o modes.h5 bar.h5
crom-fitfield --objective neuralmodes --mesh bar.h5 --modes modes.h5 --steps 1000 --batch 16 --width 32 -q -o nm.h5
KEYS=(--key 0.2,0,0 --key -0.2,0,0 --key 0,0.15,0)

crom-keyframe --model modes.h5 "${KEYS[@]}" --interp linear --between 4 -o lin.h5 2>lin.log
crom-keyframe --model nm.h5 "${KEYS[@]}" --interp linear --between 4 -o nml.h5 2>nml.log
crom-keyframe --model nm.h5 "${KEYS[@]}" -o nmc.h5 2>nmc.log
cat nml.log nmc.log
for f in lin nml nmc; do crom-info --check $f.h5 >/dev/null || fail "crom-info --check $f.h5"; ok; done
grep -q "crom-keyframe: 3 keys, 11 frames (linear): mean strain energy of the 8 in-betweens" nml.log || fail "summary line"; ok
$PY - lin.h5 nml.h5 nmc.h5 <<'PYEOF' || fail "keyframe energies"
import sys, h5py, numpy as np
keys = np.array([[0.2, 0, 0], [-0.2, 0, 0], [0, 0.15, 0]])
def load(p):
    f = h5py.File(p)
    return {k: f["frames"][k][()] for k in f["frames"]}
def need(c, *msg):
    if not c:
        raise SystemExit("check failed: %r" % (msg,))
lin, nml, nmc = (load(p) for p in sys.argv[1:])
for name, d, per in (("lin", lin, 5), ("nml", nml, 5), ("nmc", nmc, 10)):
    need(d["q"].shape == (2 * per + 1, 3), (name, d["q"].shape))
    need(np.array_equal(d["q"][::per], keys), (name, d["q"][::per]))
    need(np.array_equal(d["keyframe"][::per], [0, 1, 2]), name)
    need(np.allclose(d["time"], np.arange(2 * per + 1) / 25.0), name)
    need(np.allclose(d["elastic_energy"][::per], d["lerp_energy"][::per], rtol=1e-12), name)
    need(np.all(d["elastic_energy"] >= 0), name)
# linear modes: the same energy both ways at every frame
rel = np.max(np.abs(lin["elastic_energy"] - lin["lerp_energy"]) / lin["lerp_energy"])
print("linear modes: largest relative energy gap %.2e" % rel)
need(rel < 1e-9, rel)
# neural modes: the in-betweens through the map hold their shape
inb = np.arange(11) % 5 != 0
el, ep = nml["elastic_energy"][inb].mean(), nml["lerp_energy"][inb].mean()
print("neural modes: mean in-between energy %.4g J through the map, %.4g J from positions (ratio %.3f)" % (el, ep, el / ep))
need(el < 0.5 * ep, el, ep)
# halfway between the up and down keys the map passes near rest; the lerp of positions does not
mid = nml["elastic_energy"][2:4].min(), nml["lerp_energy"][2:4].min()
need(mid[0] < 0.2 * mid[1], mid)
PYEOF
ok
# decoded by crom-export like any latent run
crom-export --format pvd --model nm.h5 -o anim.pvd nmc.h5 -q
[ "$(ls anim/*.vtu 2>/dev/null | wc -l)" -eq 21 ] || [ "$(grep -c '<DataSet' anim.pvd)" -eq 21 ] || fail "21 decoded frames"; ok
# the keys from a crom/latent file: every frame a key
crom-keyframe --model nm.h5 --keys nml.h5 --between 0 --interp linear -q -o again.h5
$PY - nml.h5 again.h5 <<'PYEOF' || fail "--keys FILE"
import sys, h5py, numpy as np
a, b = (h5py.File(p)["frames"] for p in sys.argv[1:])
if not (np.array_equal(a["q"][()], b["q"][()]) and np.allclose(a["elastic_energy"][()], b["elastic_energy"][()], rtol=1e-12)):
    raise SystemExit("the frames differ")
PYEOF
ok
crom-keyframe --model nm.h5 --key 0,0,0 --key 0,0,0 -q -o rest.h5
$PY -c "import h5py,sys; e=h5py.File('rest.h5')['frames/elastic_energy'][()]; sys.exit(0 if (abs(e)<1e-12).all() else 1)" \
  || fail "keys at rest store no energy"; ok

# bad input
O=$TMP/out.h5
expect_error 64 "no keys: give two or more" $O -- crom-keyframe --model nm.h5 -o $O
expect_error 64 "keyframing needs at least two keys, got 1" $O -- crom-keyframe --model nm.h5 --key 0,0,0 -o $O
expect_error 64 "--key: expected 3 comma-separated numbers, got 2" $O -- crom-keyframe --model nm.h5 --key 0,0 --key 0,0,0 -o $O
expect_error 64 "--interp: 'spline' is not cubic or linear" $O -- crom-keyframe --model nm.h5 "${KEYS[@]}" --interp spline -o $O
expect_error 64 "--key: 'nan' is not a finite number" $O -- crom-keyframe --model nm.h5 --key 0,nan,0 --key 0,0,0 -o $O
crom-modes "${MAT[@]}" --pin clamp --count 2 -q -o modes2.h5 bar.h5
crom-keyframe --model modes2.h5 --key 0,0 --key 1,0 -q -o two.h5
expect_error 64 "two.h5 has 2 latent coordinates, the model's rank is 3" $O -- crom-keyframe --model nm.h5 --keys two.h5 -o $O
expect_error 66 "nope.h5" $O -- crom-keyframe --model nope.h5 "${KEYS[@]}" -o $O
done_checks
