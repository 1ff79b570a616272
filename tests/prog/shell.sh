#!/usr/bin/env bash
# shell.sh — thin shells through the programs (issue 16): crom-mesh sheet
# (exact area, consistent orientation, the thickness stored; regular rows or
# gmsh's), disk (gmsh;
# area converging to pi R^2) and import of
# an .obj surface as a shell (round trip, subdivision) and of a gmsh .msh
# surface (its triangles and physical groups), crom-fullsim on
# a sheet (a pinned sheet swinging out of plane; free fall of an unpinned
# one, which implicit Euler moves by exactly g h² N(N+1)/2 with no strain),
# crom-info, and the one-line refusals: shell flags on a solid, a shell
# given to a tet-only program, a surface that is inconsistently oriented,
# non-manifold or without a positive thickness, an open surface imported as
# a solid.
. "$CROM_TOP/tests/prog/common.bash"

crom-mesh sheet --dims 0.8,0.4,1 --size 0.05 --thickness 0.003 --region top='y>0.19' -o "$TMP/sheet.h5"
crom-info --check "$TMP/sheet.h5" >/dev/null || fail "crom-info --check on a sheet"
ok
$PY - "$TMP/sheet.h5" <<'EOF' || fail "the sheet's mesh"
import sys, h5py, numpy as np
def need(c, what):
    if not c:
        sys.exit(f"{what}")
f = h5py.File(sys.argv[1], 'r')
need('tets' not in f, 'a sheet has no tets')
X, T = f['vertices'][...], f['triangles'][...]
t = f['triangles'].attrs['thickness']
need(abs(t - 0.003) < 1e-15, t)
need(np.all(X[:, 2] == 0) and abs(X[:, 0].min() + 0.4) < 1e-12 and abs(X[:, 1].max() - 0.2) < 1e-12,
     'the sheet is not the 0.8 x 0.4 rectangle in the xy-plane centred at the origin')
e1, e2 = X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]]
nz = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
need(np.all(nz > 0), 'every triangle faces +z')
need(abs(0.5 * nz.sum() - 0.32) < 1e-12, 0.5 * nz.sum())
# interior edges are shared by two triangles running along them in opposite directions
edges = {}
for tri in T:
    for k in range(3):
        a, b = int(tri[k]), int(tri[(k + 1) % 3])
        need((a, b) not in edges, 'an edge runs twice the same way')
        edges[(a, b)] = 1
l = np.sqrt((e1 ** 2).sum(1))
need(0.02 < np.median(l) < 0.06, np.median(l))
print(f"sheet: {len(X)} vertices, {len(T)} triangles, area {0.5 * nz.sum():.12g} m^2, thickness {t} m")
EOF
ok
crom-info "$TMP/sheet.h5" | grep -q "triangles (a shell), thickness 0.003 m, area 0.32 m^2" || fail "crom-info's summary"
ok

# import of a surface as a shell: the sheet's own triangles through an OBJ come back as they were, and
# --size subdivides them 1-to-4
crom-export --format obj -o "$TMP/sheet.obj" "$TMP/sheet.h5"
crom-mesh import "$TMP/sheet.obj" --thickness 0.003 -o "$TMP/imported.h5"
crom-mesh import "$TMP/sheet.obj" --thickness 0.003 --size 0.03 -o "$TMP/fine.h5"
$PY - "$TMP/sheet.h5" "$TMP/imported.h5" "$TMP/fine.h5" <<'EOF' || fail "the imported shells"
import sys, h5py, numpy as np
def need(c, what):
    if not c:
        sys.exit(f"{what}")
def area(f):
    X, T = f['vertices'][...], f['triangles'][...]
    e1, e2 = X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]]
    return 0.5 * np.sqrt((np.cross(e1, e2) ** 2).sum(1)).sum()
a, b, c = (h5py.File(p, 'r') for p in sys.argv[1:4])
need(len(b['vertices']) == len(a['vertices']) and len(b['triangles']) == len(a['triangles']), 'counts')
need(abs(area(b) - 0.32) < 1e-12 and abs(area(c) - 0.32) < 1e-12, f"areas {area(b)} {area(c)}")
need(len(c['triangles']) == 4 * len(a['triangles']), f"{len(c['triangles'])} triangles after subdivision")
need(b['triangles'].attrs['thickness'] == 0.003, 'thickness')
print(f"import: {len(b['triangles'])} triangles back, {len(c['triangles'])} after --size 0.03, area kept")
EOF
ok

# a disk meshed by gmsh: area towards pi R^2 as the edge shrinks, facing +z, consistently oriented
crom-mesh disk --radius 0.3 --size 0.03 --thickness 0.002 -o "$TMP/disk.h5"
crom-mesh disk --radius 0.3 --size 0.015 --thickness 0.002 | cat >"$TMP/disk2.h5"
$PY - "$TMP/disk.h5" "$TMP/disk2.h5" <<'EOF' || fail "the disks"
import sys, h5py, numpy as np
def need(c, what):
    if not c:
        sys.exit(f"{what}")
errs = []
for p in sys.argv[1:3]:
    f = h5py.File(p, 'r')
    X, T = f['vertices'][...], f['triangles'][...]
    e1, e2 = X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]]
    nz = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    need(np.all(nz > 0), f"{p}: a triangle faces -z")
    need(np.abs(np.hypot(X[:, 0], X[:, 1])).max() < 0.3 + 1e-9 and np.all(X[:, 2] == 0), f"{p}: outside the disk")
    seen = set()
    for tri in T:
        for k in range(3):
            e = (int(tri[k]), int(tri[(k + 1) % 3]))
            need(e not in seen, f"{p}: edge {e} runs twice the same way")
            seen.add(e)
    errs.append(abs(0.5 * nz.sum() - np.pi * 0.09) / (np.pi * 0.09))
need(errs[1] < errs[0] < 0.01, f"area errors {errs}")
print(f"disks: area {errs[0]:.2e} and {errs[1]:.2e} off pi R^2")
EOF
ok
# the sheet meshed by gmsh instead of rows: the exact area, facing +z
crom-mesh sheet --dims 1,0.5,1 --size 0.05 --unstructured --thickness 0.002 -o "$TMP/usheet.h5"
$PY - "$TMP/usheet.h5" <<'EOF' || fail "the unstructured sheet"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1], 'r')
X, T = f['vertices'][...], f['triangles'][...]
e1, e2 = X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]]
nz = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
if not (np.all(nz > 0) and abs(0.5 * nz.sum() - 0.5) < 1e-12 and abs(X[:, 0]).max() <= 0.5 + 1e-12):
    sys.exit(f"unstructured sheet: area {0.5 * nz.sum()}, {np.sum(nz <= 0)} triangles not facing +z")
print(f"unstructured sheet: {len(X)} vertices, {len(T)} triangles, area {0.5 * nz.sum():.15g}")
EOF
ok
expect_error 64 "unstructured is for a sheet" "$TMP/x.h5" -- crom-mesh box --unstructured -o "$TMP/x.h5"

# a gmsh .msh surface imported as a shell: its triangles kept (the exact
# area), its physical groups as regions (the clamp curve: every vertex on
# x = -0.5 and no other), and the clamped plate sags under crom-fullsim
cat >"$TMP/sq.geo" <<'GEO'
SetFactory("OpenCASCADE");
Rectangle(1) = {-0.5, -0.25, 0, 1, 0.5};
Physical Curve("clamp") = {4};
Physical Surface("plate") = {1};
Mesh.MeshSizeMax = 0.05;
GEO
gmsh -2 "$TMP/sq.geo" -o "$TMP/sq.msh" >/dev/null 2>&1 || fail "gmsh -2 sq.geo"
crom-mesh import "$TMP/sq.msh" --thickness 0.003 -o "$TMP/sqmsh.h5"
crom-info --check "$TMP/sqmsh.h5" >/dev/null || fail "crom-info --check on an imported .msh shell"; ok
crom-fullsim --pin clamp --youngs 1e7 --poisson 0.3 --density 500 --gravity 0,0,-9.81 --dt 0.05 --steps 3 \
  -q -o "$TMP/sqmsh_run.h5" "$TMP/sqmsh.h5"
$PY - "$TMP/sqmsh.h5" "$TMP/sq.msh" "$TMP/sqmsh_run.h5" <<'EOF' || fail "the imported .msh shell"
import sys, h5py, numpy as np, meshio
def need(c, what):
    if not c:
        sys.exit(what)
f, g = h5py.File(sys.argv[1], 'r'), meshio.read(sys.argv[2])
X, T = f['vertices'][...], f['triangles'][...]
ntri = sum(len(c.data) for c in g.cells if c.type == 'triangle')
need(len(T) == ntri and len(X) == len(g.points), f"{len(T)} triangles on {len(X)} vertices, gmsh {ntri} on {len(g.points)}")
need(f['triangles'].attrs['thickness'] == 0.003, 'thickness 0.003')
e1, e2 = X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]]
area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1).sum()
need(abs(area - 0.5) < 1e-12, f"area {area}")
clamp, plate = f['regions/clamp'][...], f['regions/plate'][...]
need(np.all(X[clamp, 0] == -0.5) and np.sum(X[:, 0] == -0.5) == len(clamp), 'the clamp curve is the x = -0.5 edge')
need(len(plate) == len(X), 'the plate surface holds every vertex')
u = h5py.File(sys.argv[3], 'r')['frames/displacement'][...]
need(np.abs(u[:, clamp]).max() == 0 and u[-1][:, 2].min() < -1e-4, 'clamped, and the free end sags')
print(f".msh shell: {len(X)} vertices, {len(T)} triangles, area {area:.15g}, clamp {len(clamp)} vertices, "
      f"sag {-u[-1][:, 2].min():.3g} m")
EOF
ok
cat >"$TMP/cube.geo" <<'GEO'
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 1, 1};
Mesh.MeshSizeMax = 0.5;
GEO
gmsh -3 "$TMP/cube.geo" -o "$TMP/cube.msh" >/dev/null 2>&1 || fail "gmsh -3 cube.geo"
expect_error 64 "cube.msh holds a volume mesh \(tetrahedra\): import it without --thickness" "$TMP/x.h5" -- \
  crom-mesh import "$TMP/cube.msh" --thickness 0.01 -o "$TMP/x.h5"
printf 'not a mesh\n' >"$TMP/junk.msh"
expect_error 65 "junk.msh holds no 3-node triangles for a shell" "$TMP/x.h5" -- \
  crom-mesh import "$TMP/junk.msh" --thickness 0.01 -o "$TMP/x.h5"

# a pinned sheet swinging out of plane
crom-fullsim --pin top --youngs 2e5 --poisson 0.3 --density 400 --gravity 0,-9.81,4 --dt 0.02 --steps 10 \
  -o "$TMP/swing.h5" "$TMP/sheet.h5"
crom-info --check "$TMP/swing.h5" >/dev/null || fail "crom-info --check on a shell trajectory"
ok
$PY - "$TMP/swing.h5" <<'EOF' || fail "the swinging sheet"
import sys, h5py, numpy as np
def need(c, what):
    if not c:
        sys.exit(f"{what}")
f = h5py.File(sys.argv[1], 'r')
u = f['frames/displacement'][...]
top = f['mesh/regions/top'][...]
need('triangles' in f['mesh'] and f['mesh/triangles'].attrs['thickness'] == 0.003, "'triangles' in f['mesh'] and f['mesh/triangles'].attrs['thickness'] == 0.003")
need(np.abs(u[0]).max() == 0 and np.abs(u[:, top]).max() == 0, 'the pinned edge stays')
need(u[-1][:, 2].max() > 1e-3, 'it swings out of plane')
for k in ('kinetic_energy', 'elastic_energy', 'total_energy'):
    need(np.all(np.isfinite(f['frames/' + k][...])), k)
need(f['frames/elastic_energy'][-1] > 0, "f['frames/elastic_energy'][-1] > 0")
print(f"swing: largest out-of-plane displacement {u[-1][:, 2].max():.4g} m after 10 steps")
EOF
ok

# free fall: no strain, every vertex moves by g h^2 N(N+1)/2
crom-fullsim --youngs 2e5 --poisson 0.3 --density 400 --gravity 0,0,-9.81 --dt 0.01 --steps 7 --tol 1e-12 \
  -o "$TMP/fall.h5" "$TMP/sheet.h5"
$PY - "$TMP/fall.h5" <<'EOF' || fail "free fall of a sheet"
import sys, h5py, numpy as np
def need(c, what):
    if not c:
        sys.exit(f"{what}")
f = h5py.File(sys.argv[1], 'r')
u = f['frames/displacement'][-1]
expect = -9.81 * 0.01 ** 2 * 7 * 8 / 2
need(np.abs(u[:, 2] - expect).max() < 1e-12, np.abs(u[:, 2] - expect).max())
need(np.abs(u[:, :2]).max() < 1e-12, 'np.abs(u[:, :2]).max() < 1e-12')
need(np.abs(f['frames/elastic_energy'][...]).max() < 1e-18, "np.abs(f['frames/elastic_energy'][...]).max() < 1e-18")
print(f"free fall: {u[0, 2]:.15g} m, implicit Euler's {expect:.15g} m")
EOF
ok

# refusals, one line each, nothing written
expect_error 64 "thickness is for a shell" "$TMP/x.h5" -- crom-mesh box --thickness 0.01 -o "$TMP/x.h5"
expect_error 64 "thickness" "$TMP/x.h5" -- crom-mesh sheet --thickness 0 -o "$TMP/x.h5"
expect_error 64 "algorithm is for a tet mesh" "$TMP/x.h5" -- crom-mesh sheet --algorithm hxt -o "$TMP/x.h5"
expect_error 64 "keep-surface is for a tet mesh" "$TMP/x.h5" -- crom-mesh import "$TMP/sheet.obj" --thickness 0.01 --keep-surface -o "$TMP/x.h5"
expect_error 64 "disk takes --radius" "$TMP/x.h5" -- crom-mesh disk --dims 1,1,1 -o "$TMP/x.h5"
expect_error 64 "shell surface.*tet meshes" "$TMP/x.h5" -- crom-remesh refine -o "$TMP/x.h5" "$TMP/sheet.h5"
$PY - "$TMP" <<'EOF' || fail "making bad surfaces"
import sys, h5py, numpy as np
def need(c, what):
    if not c:
        sys.exit(f"{what}")
d = sys.argv[1]
X = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1]], float)
def write(name, T, t):
    with h5py.File(f"{d}/{name}.h5", 'w') as f:
        f.attrs['schema'] = 'crom/mesh'
        f.attrs['schema_version'] = np.int64(1)
        f['vertices'] = X
        f['triangles'] = np.array(T, np.int32)
        f['triangles'].attrs['thickness'] = t
write('flipped', [[0, 1, 2], [0, 1, 3]], 0.01)
write('nonmanifold', [[0, 1, 2], [1, 0, 3], [0, 1, 4]], 0.01)
write('thin', [[0, 1, 2], [1, 0, 3]], 0.0)
EOF
printf 'v 0 0 0\nv 1 0 0\nv 0.5 1 0\nv 0.5 -1 0\nv 0.5 0 1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n' >"$TMP/fan.obj"
printf 'v 0 0 0\nv 1 0 0\nv 0.5 1 0\nv 0.5 -1 0\nf 1 2 3\nf 1 2 4\n' >"$TMP/flip.obj"
expect_error 65 "non-manifold" "$TMP/x.h5" -- crom-mesh import "$TMP/fan.obj" --thickness 0.01 -o "$TMP/x.h5"
expect_error 65 "not consistently oriented" "$TMP/x.h5" -- crom-mesh import "$TMP/flip.obj" --thickness 0.01 -o "$TMP/x.h5"
expect_error 65 "not closed" "$TMP/x.h5" -- crom-mesh import "$TMP/sheet.obj" -o "$TMP/x.h5"
expect_error 64 "an .stl, .obj or .msh surface" "$TMP/x.h5" -- crom-mesh import "$TMP/x.ply" --thickness 0.01 -o "$TMP/x.h5"
expect_error 66 "nothere.msh: No such file or directory" "$TMP/x.h5" -- crom-mesh import "$TMP/nothere.msh" --thickness 0.01 -o "$TMP/x.h5"
expect_error 65 "not consistently oriented" "$TMP/x.h5" -- crom-fullsim --steps 1 -o "$TMP/x.h5" "$TMP/flipped.h5"
expect_error 65 "not manifold" "$TMP/x.h5" -- crom-fullsim --steps 1 -o "$TMP/x.h5" "$TMP/nonmanifold.h5"
expect_error 65 "thickness" "$TMP/x.h5" -- crom-fullsim --steps 1 -o "$TMP/x.h5" "$TMP/thin.h5"
done_checks
