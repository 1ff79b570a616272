#!/usr/bin/env bash
# scene.sh — rigid-body scenes through the programs (issue 17): crom-scene
# (a pendulum, a chain), crom-info's summary and --check, crom-fullsim on a
# scene (the pendulum's small-angle period within 1% of 2 pi sqrt(L/g); a
# 24-link chain whose joints hold to 1e-3 of a link and whose stored poses
# are orthogonal and carry the frame vertices; its energy never grows),
# crom-export of a scene and of its run (the bodies' shapes, a region per
# body), crom-diff between runs, and the one-line refusals: bad scene
# flags, a scene given to a program that does not take scenes, collision
# planes on a scene, and corrupt scene files (a joint naming a missing body,
# a negative weight, a degenerate shape, frame vertices that are not the
# body's), a ring whose tube is thicker than its radius, a slider whose
# axis is not a unit vector; the Klann linkage assembled at rest, and the
# Stewart platform pushed sideways with every ball joint and slider holding.
. "$CROM_TOP/tests/prog/common.bash"

crom-scene pendulum --length 1 --angle 85 -o "$TMP/pend.h5"
crom-info --check "$TMP/pend.h5" >/dev/null || fail "crom-info --check on a scene"
crom-info "$TMP/pend.h5" >"$TMP/info.txt"
grep -q "a rigid-body scene: 1 bodies (0 boxes, 1 spheres, 0 capsules, 0 rings; 12 DOF)" "$TMP/info.txt" \
  || fail "crom-info's scene summary"
ok
# Under the sanitizers (CI's second pass) the long runs are skipped: the
# pendulum's period, the chains' and the Stewart platform's runs. Their
# physics runs under ASan in tests/unit/test_scene.c (the same systems,
# stepped), and the programs' scene paths in the shorter runs here.
SAN=${CROM_SANITIZE:-0}
if [ "$SAN" != 1 ]; then
crom-fullsim "$TMP/pend.h5" --dt 0.001 --steps 4200 --every 5 -o "$TMP/pend-run.h5"
crom-info --check "$TMP/pend-run.h5" >/dev/null || fail "crom-info --check on a scene's run"
$PY - "$TMP/pend-run.h5" <<'PYEOF' || fail "the pendulum's period"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], 'r')
P, t = f['frames/body_pose'][...], f['frames/time'][...]
c = f['mesh/scene/centre'][0]
x = np.einsum('fij,j->fi', P[:, 0, :, :3], c) + P[:, 0, :, 3]
s = np.where(np.diff(np.sign(x[:, 0])) != 0)[0]
tc = t[s] - x[s, 0] * (t[s + 1] - t[s]) / (x[s + 1, 0] - x[s, 0])
T = 2 * (tc[-1] - tc[0]) / (len(tc) - 1)
T0 = 2 * np.pi * np.sqrt(1 / 9.81)
print(f"pendulum: period {T:.5f} s over {len(tc) - 1} half-swings, 2 pi sqrt(L/g) = {T0:.5f} s ({100 * (T / T0 - 1):+.3f}%)")
if len(tc) < 4 or abs(T / T0 - 1) > 0.01:
    sys.exit("period off")
if f['frames/joint_gap'][...].max() > 1e-3:
    sys.exit("the pivot drifted")
PYEOF
ok
fi

crom-scene chain --link capsule --links 24 -o "$TMP/chain.h5"
crom-info "$TMP/chain.h5" >"$TMP/info.txt"
grep -q "24 joints (1 pinned to the world), 0 collision pairs" "$TMP/info.txt" || fail "the chain's joints"
ok
crom-scene chain --links 2 -o "$TMP/mini.h5"
crom-info "$TMP/mini.h5" >"$TMP/info.txt"
grep -q "2 bodies (0 boxes, 0 spheres, 0 capsules, 2 rings; 24 DOF)" "$TMP/info.txt" || fail "the mini chain's bodies"
grep -q "1 joints (1 pinned to the world), 2 collision pairs" "$TMP/info.txt" || fail "the mini chain's pairs"
ok
if [ "$SAN" != 1 ]; then
crom-fullsim "$TMP/chain.h5" --dt 0.01 --steps 150 --every 3 -o "$TMP/chain-run.h5"
$PY - "$TMP/chain-run.h5" <<'PYEOF' || fail "the chain's run"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], 'r')
P, U = f['frames/body_pose'][...], f['frames/displacement'][...]
X = f['mesh/vertices'][...]
gap = f['frames/joint_gap'][...]
E = f['frames/total_energy'][...]
R = P[:, :, :, :3]
orth = np.abs(np.einsum('fbki,fbkj->fbij', R, R) - np.eye(3)).max()
# each body's frame vertices are carried by its pose
x = X + U
pred = np.einsum('fbij,bkj->fbki', R, X.reshape(-1, 4, 3)) + P[:, :, None, :, 3]
carried = np.abs(pred - x.reshape(len(x), -1, 4, 3)).max()
tip = x[:, -4:].mean(1)
print(f"chain: joint gaps <= {gap.max():.2e} m, |R^T R - I| <= {orth:.1e}, poses carry the frames to {carried:.1e} m, "
      f"tip from y = {tip[0, 1]:.3f} down to {tip[:, 1].min():.3f} m, energy {E[0]:.3g} -> {E[-1]:.3g} J")
if gap.max() > 1e-4 or orth > 1e-2 or carried > 1e-12:
    sys.exit("joints, orthogonality or poses")
if tip[:, 1].min() > -1.5:
    sys.exit("the chain did not swing down")
if np.any(np.diff(E) > 1e-6 * np.abs(E).max()):
    sys.exit("implicit Euler's energy grew")
PYEOF
ok

# the mini chain: two interlocked rings held by contacts alone; the second
# falls until the tubes meet and then hangs: the centres never part by
# more than the rings' geometry allows (2(h + R) - 2r) plus a penetration of
# a fifth of the tube radius, and the loose ring does fall
crom-fullsim "$TMP/mini.h5" --dt 0.002 --steps 300 --every 10 --max-iter 200 -o "$TMP/mini-run.h5"
$PY - "$TMP/mini-run.h5" <<'PYEOF' || fail "the mini chain's run"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], 'r')
P, c = f['frames/body_pose'][...], f['mesh/scene/centre'][...]
r, R, L = f['mesh/scene/size'][0]
X = np.einsum('fbij,bj->fbi', P[:, :, :, :3], c) + P[:, :, :, 3]
d = np.linalg.norm(X[:, 1] - X[:, 0], axis=1)
lim = 2 * (L / 2 + R) - 2 * r
print(f"mini chain: centres {d[0]:.4f} m apart at rest, at most {d.max():.5f} m (rings' limit {lim:.4f} m), "
      f"the loose ring's centre down to y = {X[:, 1, 1].min():.3f} m")
if d.max() > lim + 0.2 * r or X[:, 1, 1].min() > -0.02:
    sys.exit("the rings came apart, or nothing fell")
PYEOF
ok

# export: the bodies' shapes (12 rings), a region per body; a run as a pvd series and a strip
crom-export -o "$TMP/chain.vtu" "$TMP/chain.h5"
crom-export -o "$TMP/run.pvd" "$TMP/chain-run.h5"
crom-export --format strip --columns 3 -o "$TMP/strip.png" "$TMP/chain-run.h5"
$PY - "$TMP/chain.vtu" "$TMP/run.pvd" "$TMP/strip.png" <<'PYEOF' || fail "the exported scene"
import sys, os, meshio, numpy as np
m = meshio.read(sys.argv[1])
tri = m.cells_dict['triangle']
if 'region_link23' not in m.point_data or len(m.points) != 24 * (2 + 12 * 24):
    sys.exit(f"{len(m.points)} points, fields {list(m.point_data)}")
frames = sorted(os.listdir(os.path.join(os.path.dirname(sys.argv[2]), 'run')))
last = meshio.read(os.path.join(os.path.dirname(sys.argv[2]), 'run', frames[-1]))
u = last.point_data['displacement']
if len(frames) != 51 or np.abs(u).max() < 0.5:
    sys.exit(f"{len(frames)} frames, largest displacement {np.abs(u).max()}")
if os.path.getsize(sys.argv[3]) < 1000:
    sys.exit("strip")
print(f"export: {len(m.points)} display points, {len(tri)} triangles, {len(frames)} frames")
PYEOF
ok
crom-diff "$TMP/chain-run.h5" "$TMP/chain-run.h5" --max-error 1e-12 >/dev/null || fail "crom-diff of a run with itself"
ok
fi

# data-free training on a scene (Sharp et al.'s energy objective over every
# scene element), its reduced run over the 8-vertex elements, and the
# latent decoded onto the bodies' shapes: the model carries the scene; with
# no load the run stays exactly at rest; crom-diff and crom-export decode it
crom-scene pendulum -o "$TMP/hang.h5"
crom-fitfield --objective energy --mesh "$TMP/hang.h5" --rank 1 --sigma 0.1 --lambda 10 --steps 400 --width 16 \
  --depth 3 -q -o "$TMP/pend-map.h5"
crom-info --check "$TMP/pend-map.h5" >/dev/null || fail "crom-info --check on a scene's energy map"
crom-reducedstep --model "$TMP/pend-map.h5" --dt 0.01 --steps 10 --gravity 0,0,0 -q -o "$TMP/pend-red.h5"
crom-info --check "$TMP/pend-red.h5" >/dev/null || fail "crom-info --check on a scene's latent run"
crom-export -q -o "$TMP/pend-red.pvd" --model "$TMP/pend-map.h5" "$TMP/pend-red.h5"
crom-fullsim "$TMP/hang.h5" --dt 0.01 --steps 10 --gravity 0,0,0 -q -o "$TMP/hang-run.h5"
crom-diff "$TMP/hang-run.h5" "$TMP/pend-red.h5" --model "$TMP/pend-map.h5" >"$TMP/diff.txt" \
  || fail "crom-diff of a scene's latent run"
$PY - "$TMP/pend-map.h5" "$TMP/pend-red.pvd" <<'PYEOF' || fail "the scene's map and its run"
import sys, os, h5py, meshio, numpy as np
f = h5py.File(sys.argv[1], 'r')
if f['field/mesh/scene/shape'][0] != 1 or f.attrs['basis'] != 'energy':
    sys.exit("the map does not carry its scene")
d = os.path.join(os.path.dirname(sys.argv[2]), 'pend-red')
frames = sorted(os.listdir(d))
u = max(np.abs(meshio.read(os.path.join(d, k)).point_data['displacement']).max() for k in frames)
print(f"scene map: {len(frames)} frames of its reduced run at rest, largest displacement {u:.1e} m")
if len(frames) != 11 or u > 1e-12:
    sys.exit("a run with no load left rest")
PYEOF
ok
expect_error 64 "is a rigid-body scene \(1 bodies\): this objective trains on solids and shells" "$TMP/x.h5" -- \
  crom-fitfield --objective neuralmodes --mesh "$TMP/hang.h5" --modes "$TMP/pend-map.h5" -o "$TMP/x.h5"
expect_error 64 "collisions with the world are not simulated on rigid-body scenes" "$TMP/x.h5" -- \
  crom-reducedstep --model "$TMP/pend-map.h5" --plane 0,1,0,-2 --steps 2 -o "$TMP/x.h5"
expect_error 64 "tets 5: a random cubature of tets applies to solids" "$TMP/x.h5" -- \
  crom-fitfield --objective energy --mesh "$TMP/hang.h5" --tets 5 -o "$TMP/x.h5"

# the Klann linkage: five links and seven revolute joints (two point joints
# each), assembled exactly at rest
crom-scene klann --angle 30 -o "$TMP/klann.h5"
crom-info "$TMP/klann.h5" >"$TMP/info.txt"
grep -q "5 bodies (5 boxes, 0 spheres, 0 capsules, 0 rings; 60 DOF)" "$TMP/info.txt" || fail "the Klann linkage's bodies"
grep -q "14 joints (6 pinned to the world)" "$TMP/info.txt" || fail "the Klann linkage's joints"
crom-fullsim "$TMP/klann.h5" --dt 0.005 --steps 40 --gravity 0,0,0 -o "$TMP/klann-run.h5"
$PY - "$TMP/klann-run.h5" <<'PYEOF' || fail "the Klann linkage at rest"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], 'r')
u, g = np.abs(f['frames/displacement'][...]).max(), f['frames/joint_gap'][...].max()
print(f"Klann linkage with no load: largest displacement {u:.1e} m, joint gaps <= {g:.1e} m")
if u > 1e-12 or g > 1e-12:
    sys.exit("the assembled linkage is not at rest")
PYEOF
ok

# the Stewart platform: six telescoping legs (ball joints and sliders);
# pushed sideways with no gravity the platform moves and every joint holds
crom-scene stewart -o "$TMP/stewart.h5"
crom-info "$TMP/stewart.h5" >"$TMP/info.txt"
grep -q "14 bodies (2 boxes, 0 spheres, 12 capsules, 0 rings; 168 DOF)" "$TMP/info.txt" || fail "the Stewart platform"
if [ "$SAN" != 1 ]; then
crom-fullsim "$TMP/stewart.h5" --dt 0.01 --steps 30 --gravity 0,0,0 --force platform=20,0,0 -o "$TMP/stewart-run.h5"
$PY - "$TMP/stewart-run.h5" <<'PYEOF' || fail "the Stewart platform's run"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], 'r')
P, c = f['frames/body_pose'][...], f['mesh/scene/centre'][1]
x = P[-1, 1, :, :3] @ c + P[-1, 1, :, 3]
g = f['frames/joint_gap'][...].max()
kinds = f['mesh/scene/joint_kinds'][...]
print(f"Stewart platform: {int((kinds == 1).sum())} sliders; pushed 0.3 s, the platform moved {x[0] - c[0]:.3f} m, "
      f"joints within {g:.1e} m")
if x[0] - c[0] < 0.02 or g > 1e-3:
    sys.exit("the platform did not move, or a joint gave")
PYEOF
ok
fi
cp "$TMP/stewart.h5" "$TMP/badslider.h5"
$PY -c "import h5py; f = h5py.File('$TMP/badslider.h5', 'r+'); f['scene/joint_axes'][5] *= 2"
expect_error 65 "slider joint 5: it joins two bodies along a unit axis" "$TMP/x.h5" -- \
  crom-fullsim "$TMP/badslider.h5" --steps 1 -o "$TMP/x.h5"

# refusals
expect_error 64 "unknown scene 'knot' \(pendulum, chain, klann, stewart\)" "$TMP/x.h5" -- crom-scene knot -o "$TMP/x.h5"
expect_error 64 "angle is for the pendulum and the Klann linkage" "$TMP/x.h5" -- crom-scene chain --angle 10 -o "$TMP/x.h5"
expect_error 64 "links" "$TMP/x.h5" -- crom-scene chain --links 0 -o "$TMP/x.h5"
expect_error 64 "ring radius 0.004 m must exceed the tube radius 0.005 m" "$TMP/x.h5" -- \
  crom-scene chain --ring-radius 0.004 -o "$TMP/x.h5"
expect_error 64 "--link: 'chain' is not ring or capsule" "$TMP/x.h5" -- crom-scene chain --link chain -o "$TMP/x.h5"
expect_error 64 "ring-radius and --contact-weight are for a chain of rings" "$TMP/x.h5" -- \
  crom-scene chain --link capsule --contact-weight 5 -o "$TMP/x.h5"
expect_error 64 "--links and --link are for a chain" "$TMP/x.h5" -- crom-scene pendulum --links 3 -o "$TMP/x.h5"
expect_error 64 "is a rigid-body scene \(24 bodies\); this program does not take scenes" "$TMP/x.h5" -- \
  crom-modes "$TMP/chain.h5" -o "$TMP/x.h5"
expect_error 64 "is a rigid-body scene" "$TMP/x.h5" -- crom-sample "$TMP/hang-run.h5" -o "$TMP/x.h5"
expect_error 64 "collisions with the world are not simulated on rigid-body scenes" "$TMP/x.h5" -- \
  crom-fullsim "$TMP/chain.h5" --plane 0,1,0,-1 --steps 2 -o "$TMP/x.h5"
expect_error 64 "equilibria takes a solid or a shell" "$TMP/x.h5" -- \
  crom-fullsim "$TMP/chain.h5" --equilibria m.h5 -o "$TMP/x.h5"
corrupt() { # corrupt NAME PYTHON-STATEMENT: a copy of the chain with f (h5py, r+) edited
  cp "$TMP/chain.h5" "$TMP/$1.h5"
  $PY -c "import h5py; f = h5py.File('$TMP/$1.h5', 'r+'); $2"
}
corrupt badjoint "f['scene/joint_bodies'][3, 1] = 40"
corrupt badweight "f['scene/joint_weights'][2] = -5"
corrupt badshape "f['scene/size'][4, 0] = 0"
corrupt badframe "f['vertices'][9, 1] += 0.01"
expect_error 65 "joint 3 names body 40, but the scene has bodies 0..23" "$TMP/x.h5" -- \
  crom-fullsim "$TMP/badjoint.h5" --steps 1 -o "$TMP/x.h5"
expect_error 65 "joint 2 has weight -5 N/m: weights must be non-negative" "$TMP/x.h5" -- \
  crom-fullsim "$TMP/badweight.h5" --steps 1 -o "$TMP/x.h5"
expect_error 65 "body 4 \(capsule\) has size 0 m" "$TMP/x.h5" -- crom-export -o "$TMP/x.vtu" "$TMP/badshape.h5"
expect_error 65 "body 2's frame vertices are not those of its shape and density" "$TMP/x.h5" -- \
  crom-fullsim "$TMP/badframe.h5" --steps 1 -o "$TMP/x.h5"
cp "$TMP/mini.h5" "$TMP/badring.h5"
$PY -c "import h5py; f = h5py.File('$TMP/badring.h5', 'r+'); f['scene/size'][1, 0] = 0.05"
expect_error 65 "body 1 \(ring\) has a tube of radius 0.05 m around a curve of radius 0.02 m: the tube must be thinner" \
  "$TMP/x.h5" -- crom-fullsim "$TMP/badring.h5" --steps 1 -o "$TMP/x.h5"
crom-info --check "$TMP/badjoint.h5" >/dev/null 2>&1 && fail "crom-info --check passed a joint naming a missing body"
ok
done_checks
