#!/usr/bin/env bash
# crom-export for gmsh: an MSH file (written through the gmsh API) that the
# gmsh program itself reads back with the same node and element counts, the
# displacement and velocity of every frame as NodeData views at the frames'
# times; an STL of the deformed boundary surface that gmsh reads, closed and
# outward; the binary PLY's per-vertex |u| named displacement_magnitude.
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
crom-mesh box --size 0.25 --region top='y>0.45' --region bottom='y<-0.45' -o box.h5
SC=(--velocity 'top=0,-2,0@0:0.04' --pin bottom --gravity 0,-9.81,0 --dt 0.01 --steps 6)
crom-fullsim "${SC[@]}" -q -o full.h5 box.h5
nv=$(h5ls full.h5/mesh/vertices | grep -o '{[0-9]*' | tr -d '{')
nt=$(h5ls full.h5/mesh/tets | grep -o '{[0-9]*' | tr -d '{')

# 1. gmsh reads what crom-export wrote, and counts what crom wrote
crom-export -q -o run.msh full.h5                       # a series: format from the extension
crom-export -q --format msh -o mesh.msh box.h5          # a bare mesh
crom-export -q --format msh full.h5 >piped.msh          # to stdout
crom-export -q -o last.stl full.h5                      # the last frame's surface
crom-export -q -o last.obj full.h5
crom-export -q --format stl --frame all --every 3 -o stls full.h5
for f in run.msh mesh.msh; do
  gmsh "$f" -0 >"$f.log" 2>&1 || fail "gmsh cannot read $f: $(tail -3 "$f.log")"; ok
  grep -q "Info *: $nv nodes" "$f.log" && grep -q "Info *: $nt elements" "$f.log" \
    || fail "gmsh reads $f with other counts than $nv nodes, $nt tets: $(grep -E 'nodes|elements' "$f.log")"; ok
done
cmp -s run.msh piped.msh || fail "msh to stdout differs from -o run.msh"; ok
nf=$(grep -c '^f ' last.obj)
for f in last.stl stls/frame_00000.stl stls/frame_00002.stl; do
  gmsh "$f" -0 >stl.log 2>&1 || fail "gmsh cannot read $f: $(tail -3 stl.log)"; ok
  grep -q "Info *: $nf facets" stl.log || fail "gmsh reads $f with $(grep -o '[0-9]* facets' stl.log), expected $nf"; ok
done
[ "$(ls stls/*.stl | wc -l)" -eq 3 ] || fail "stl --frame all --every 3 of 7 frames: $(ls stls | wc -l) files"; ok

# 2. the MSH's views hold the frames exactly, at their times; the STL is
#    the deformed surface, closed and outward (it encloses the deformed volume)
$PY - <<'PYEOF' || fail "msh views and stl surface"
import sys, h5py, meshio, numpy as np
f = h5py.File("full.h5"); X = f["mesh/vertices"][()]; T = f["mesh/tets"][()]
U = f["frames/displacement"][()]; V = f["frames/velocity"][()]; t = f["frames/time"][()]
def views(path):                       # the $NodeData blocks of an MSH 4.1 ASCII file
    out = {}; lines = open(path).read().split("\n"); i = 0
    while i < len(lines):
        if lines[i] == "$NodeData":
            ns = int(lines[i + 1]); name = lines[i + 2].strip('"'); j = i + 2 + ns
            nr = int(lines[j]); time = float(lines[j + 1]); j += 1 + nr
            ni = int(lines[j]); step, nc, n = (int(x) for x in lines[j + 1:j + 4]); j += 1 + ni
            rows = np.array([[float(x) for x in l.split()] for l in lines[j:j + n]])
            out.setdefault(name, []).append((step, time, rows))
            i = j + n
        i += 1
    return out
v = views("run.msh")
for name, ref in (("displacement", U), ("velocity", V)):
    steps = v.get(name, [])
    if [s for s, _, _ in steps] != list(range(len(t))):
        sys.exit("%s: steps %s, expected %d" % (name, [s for s, _, _ in steps], len(t)))
    for k, (s, time, rows) in enumerate(steps):
        if abs(time - t[k]) > 1e-15 * max(1.0, abs(t[k])):    # gmsh prints 16 digits
            sys.exit("%s step %d at time %r, expected %r" % (name, k, time, t[k]))
        if not np.array_equal(rows[:, 0], np.arange(1, len(X) + 1)):
            sys.exit("%s step %d: node tags" % (name, k))
        if np.abs(rows[:, 1:] - ref[k]).max() > 1e-15 * max(1.0, np.abs(ref).max()):
            sys.exit("%s step %d differs by %g" % (name, k, np.abs(rows[:, 1:] - ref[k]).max()))
if views("mesh.msh"):
    sys.exit("a bare mesh's msh has views")
m = meshio.read("run.msh")
if np.abs(m.points - X).max() > 1e-15 or not np.array_equal(m.cells_dict["tetra"], T):
    sys.exit("msh mesh differs")
x = X + U[-1]
def vol(P, F):
    return np.sum(np.einsum("ij,ij->i", P[F[:, 0]], np.cross(P[F[:, 1]], P[F[:, 2]]))) / 6
Dm = np.stack([x[T[:, i]] - x[T[:, 0]] for i in (1, 2, 3)], 2); Vx = np.sum(np.linalg.det(Dm)) / 6
s = meshio.read("last.stl"); P = s.points.astype(float); F = s.cells_dict["triangle"]
d = np.min(np.linalg.norm(P[:, None, :] - x[None, :, :], axis=2), axis=1)
if d.max() > 1e-6:
    sys.exit("stl vertex %g from the deformed mesh" % d.max())
if abs(vol(P, F) - Vx) > 1e-5 * Vx:
    sys.exit("stl encloses %r, the deformed mesh has %r" % (vol(P, F), Vx))
print("msh: %d frames x 2 views to 1e-15; stl: %d triangles enclosing %.6f m^3" % (len(t), len(F), Vx))
PYEOF
ok

# 3. binary PLY: |u| per vertex is 'displacement_magnitude' (not 'u')
crom-export -q -o last.ply full.h5
head -c 400 last.ply | grep -aq '^property float displacement_magnitude$' || fail "ply: no displacement_magnitude property"; ok
! head -c 400 last.ply | grep -aq '^property float u$' || fail "ply still has a property 'u'"; ok
$PY - <<'PYEOF' || fail "ply displacement_magnitude values"
import sys, h5py, meshio, numpy as np
f = h5py.File("full.h5"); X = f["mesh/vertices"][()]; U = f["frames/displacement"][-1]
p = meshio.read("last.ply"); P = p.points.astype(float); m = p.point_data["displacement_magnitude"]
x = X + U
i = np.argmin(np.linalg.norm(P[:, None, :] - x[None, :, :], axis=2), axis=1)
if np.abs(m - np.linalg.norm(U[i], axis=1)).max() > 1e-6 * max(np.abs(U).max(), 1e-12):
    sys.exit("displacement_magnitude is not |u| of the vertex")
print("ply: %d vertices, |u| up to %.4f m" % (len(P), m.max()))
PYEOF
ok
expect_error 64 "not vtu, pvd, xdmf, msh, obj, ply, stl" x.out -- crom-export --format vtk -o x.out full.h5
done_checks
