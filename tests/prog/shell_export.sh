#!/usr/bin/env bash
# crom-export and crom-diff on thin shells: a sheet (crom-mesh sheet) swung
# out of its plane by crom-fullsim exports as its triangles to VTU
# (VTK_TRIANGLE cells, read back with xml.etree: points, connectivity,
# displacement of the HDF5 frame, per-triangle area, area ratio J and
# membrane energy density and von Mises stress against a numpy evaluation of the StVK membrane
# law), PVD, XDMF (a Triangle topology, through meshio), MSH, OBJ, PLY, STL
# and PNG (not blank, and the same picture with the triangles' orientation
# reversed: both sides are drawn); crom-diff compares shell runs with the
# lumped mass of the triangles; the tet-only paths (crom-sample,
# a latent of a solid's model decoded onto a shell) refuse a shell in one line
# naming it; crom-modes finds a free sheet's six rigid modes.
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"

# 1. the sheet of the shell example and a run of it swinging out of plane
crom-mesh sheet --dims 1,1,1 --size 0.05 --thickness 0.002 --region top='y>0.49' -q -o hs.h5
SC=(--pin top --youngs 1e6 --poisson 0.3 --density 500 --dt 0.02 --steps 20)
crom-fullsim "${SC[@]}" --gravity 0,-9.81,1 -q -o traj.h5 hs.h5
crom-fullsim "${SC[@]}" --gravity 0,-9.81,0 -q -o flat.h5 hs.h5      # stays in its plane

# 2. every format, from the trajectory and from the bare mesh
crom-export -q -o last.vtu traj.h5
crom-export -q -o f5.vtu --frame 5 traj.h5
crom-export -q -o run.pvd traj.h5
crom-export -q -o run.xdmf traj.h5
crom-export -q -o run.msh traj.h5
crom-export -q -o last.obj traj.h5
crom-export -q -o last.ply traj.h5
crom-export -q -o last.stl traj.h5
crom-export -q -o last.png traj.h5
crom-export -q --format png --frame all --every 10 -o pngs traj.h5
crom-export -q -o mesh.vtu hs.h5
crom-export -q -o mesh.xdmf hs.h5
crom-export -q -o mesh.png hs.h5
crom-export -q --mesh hs.h5 -o withmesh.vtu traj.h5         # a trajectory's --mesh of the same kind
[ "$(ls pngs/*.png | wc -l)" -eq 3 ] || fail "png sequence: $(ls pngs | wc -l) files"; ok
NTRI=$($PY -c 'import h5py; print(len(h5py.File("hs.h5")["triangles"]))')
[ "$(grep -c 'facet normal' last.stl)" -eq "$NTRI" ] || fail "stl: $(grep -c 'facet normal' last.stl) facets, $NTRI triangles"; ok

$PY - <<'PYEOF' || fail "VTU, PVD, XDMF, MSH, OBJ and PLY of a shell"
import base64, re, struct, sys
import xml.etree.ElementTree as ET
import h5py, meshio, numpy as np

def bad(msg):
    sys.exit("check failed: " + msg)

def vtu(path):
    """Points, cells and point/cell data of a crom VTU (binary, UInt32 headers)."""
    root = ET.parse(path).getroot()
    piece = root.find("UnstructuredGrid/Piece")
    def arr(el):
        raw = base64.b64decode(el.text.strip())
        n, = struct.unpack("<I", raw[:4])
        dt = {"Float64": "<f8", "Int32": "<i4", "UInt8": "u1"}[el.get("type")]
        a = np.frombuffer(raw[4:4 + n], dt)
        k = int(el.get("NumberOfComponents", "1"))
        return a.reshape(-1, k) if k > 1 else a
    get = lambda sec: {e.get("Name"): arr(e) for e in piece.findall(sec + "/DataArray")}
    return (int(piece.get("NumberOfPoints")), int(piece.get("NumberOfCells")), get("Points")["Points"],
            get("Cells"), get("PointData"), get("CellData"), root)

h = h5py.File("traj.h5")
X = h["mesh/vertices"][()]; T = h["mesh/triangles"][()]; t = h["mesh/triangles"].attrs["thickness"]
U = h["frames/displacement"][()]; V = h["frames/velocity"][()]; times = h["frames/time"][()]
Eel = h["frames/elastic_energy"][()]
nv, ntri = len(X), len(T)
E, nu = 1e6, 0.3
mu, lam = E / (2 * (1 + nu)), E * nu / (1 - nu * nu)

def membrane(u):
    """Rest area, area ratio and StVK membrane energy per rest volume of each triangle."""
    def edges(x):
        return x[T[:, 1]] - x[T[:, 0]], x[T[:, 2]] - x[T[:, 0]]
    def gram(a, b):
        return np.stack([np.stack([(a * a).sum(1), (a * b).sum(1)], 1),
                         np.stack([(a * b).sum(1), (b * b).sum(1)], 1)], 1)
    a0, b0 = edges(X); a1, b1 = edges(X + u)
    A = 0.5 * np.linalg.norm(np.cross(a0, b0), axis=1)
    J = 0.5 * np.linalg.norm(np.cross(a1, b1), axis=1) / A
    C = np.linalg.solve(gram(a0, b0), gram(a1, b1))          # G^-1 g: F^T F in mixed form
    Em = 0.5 * (C - np.eye(2))
    trE = np.trace(Em, axis1=1, axis2=2); trE2 = np.einsum("tij,tji->t", Em, Em)
    return A, J, mu * trE2 + 0.5 * lam * trE ** 2

def mises(u):
    """von Mises of the membrane's Cauchy stress: principal stresses = eigenvalues of S C / J."""
    a0, b0 = X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]]
    a1, b1 = (X + u)[T[:, 1]] - (X + u)[T[:, 0]], (X + u)[T[:, 2]] - (X + u)[T[:, 0]]
    g = lambda a, b: np.stack([np.stack([(a * a).sum(1), (a * b).sum(1)], 1), np.stack([(a * b).sum(1), (b * b).sum(1)], 1)], 1)
    C = np.linalg.solve(g(a0, b0), g(a1, b1))
    Em = 0.5 * (C - np.eye(2))
    S = 2 * mu * Em + lam * np.trace(Em, axis1=1, axis2=2)[:, None, None] * np.eye(2)
    J = np.sqrt(np.linalg.det(C))
    s = np.real(np.linalg.eigvals(S @ C)) / J[:, None]
    return np.sqrt(s[:, 0] ** 2 - s[:, 0] * s[:, 1] + s[:, 1] ** 2)

PSI = membrane(U[-1])[2].max()   # the scale of the energy densities (0 at rest)
SIG = mises(U[-1]).max()         # and of the stresses
def close(a, b, what, rel=1e-9, scale=0.0):
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape or not np.all(np.abs(a - b) <= rel * max(np.abs(b).max(), scale, 1e-300)):
        bad("%s: %r, expected %r" % (what, a.ravel()[:4], b.ravel()[:4]))

# VTU of the last frame and of frame 5: triangles, the frame's displacement
for path, k in (("last.vtu", len(U) - 1), ("f5.vtu", 5)):
    npt, nc, P, cells, pd, cd, root = vtu(path)
    if (npt, nc) != (nv, ntri):
        bad("%s: %d points, %d cells; the mesh has %d vertices, %d triangles" % (path, npt, nc, nv, ntri))
    if not np.all(cells["types"] == 5):
        bad("%s: cell types %s, expected 5 (VTK_TRIANGLE)" % (path, sorted(set(cells["types"].tolist()))))
    if not np.array_equal(cells["offsets"], 3 * np.arange(1, ntri + 1)):
        bad(path + ": offsets are not 3, 6, 9, ...")
    if not np.array_equal(cells["connectivity"].reshape(-1, 3), T):
        bad(path + ": connectivity is not the mesh's triangles")
    if not np.array_equal(P, X):
        bad(path + ": points are not the rest positions")
    if not np.array_equal(pd["displacement"], U[k]) or not np.array_equal(pd["velocity"], V[k]):
        bad("%s: displacement/velocity differ from frame %d of traj.h5" % (path, k))
    if not np.array_equal(pd["region_top"] == 1, np.isin(np.arange(nv), h["mesh/regions/top"][()])):
        bad(path + ": region_top mask")
    if sorted(cd) != ["J", "area", "energy_density", "von_mises_stress"]:
        bad("%s: cell data %s, expected area, J, energy_density, von_mises_stress" % (path, sorted(cd)))
    A, J, psi = membrane(U[k])
    close(cd["area"], A, path + " area", 1e-12)
    close(cd["J"], J, path + " J", 1e-9)
    close(cd["energy_density"], psi, path + " energy density", 1e-7, PSI)
    close(cd["von_mises_stress"], mises(U[k]), path + " von Mises stress", 1e-7, SIG)
    tv = float(root.find("UnstructuredGrid/FieldData/DataArray").text)
    if tv != times[k]:
        bad("%s: TimeValue %r, frame time %r" % (path, tv, times[k]))
A, J, psi = membrane(U[-1])
if abs(A.sum() - 1) > 1e-12:
    bad("the areas sum to %r m^2, the sheet is 1 m^2" % A.sum())
memb = (t * A * psi).sum()
if not (0 < memb <= Eel[-1] * (1 + 1e-9)):
    bad("membrane energy %r J against the run's elastic energy %r J (membrane + bending)" % (memb, Eel[-1]))
print("vtu: %d triangles (type 5), %d points, frame displacements exact; area sums to %.12g m^2, "
      "J in [%.6f, %.6f], membrane energy %.4g J of the run's %.4g J" % (ntri, nv, A.sum(), J.min(), J.max(), memb, Eel[-1]))

# the bare mesh: area only; --mesh of the same kind
npt, nc, P, cells, pd, cd, root = vtu("mesh.vtu")
if (npt, nc) != (nv, ntri) or not np.all(cells["types"] == 5) or sorted(cd) != ["area"] or "displacement" in pd:
    bad("bare mesh vtu: %d points, %d cells, cell data %s, point data %s" % (npt, nc, sorted(cd), sorted(pd)))
close(cd["area"], membrane(0 * X)[0], "bare mesh area", 1e-12)
if vtu("withmesh.vtu")[1] != ntri:
    bad("--mesh of the same kind")

# PVD: every frame, each a VTU of triangles with its frame's displacement
pvd = ET.parse("run.pvd").getroot().findall("Collection/DataSet")
if len(pvd) != len(U):
    bad("pvd: %d datasets for %d frames" % (len(pvd), len(U)))
for k in (0, 7, len(U) - 1):
    npt, nc, P, cells, pd, cd, root = vtu(pvd[k].get("file"))
    if nc != ntri or not np.all(cells["types"] == 5) or not np.array_equal(pd["displacement"], U[k]):
        bad("pvd frame %d" % k)
    if float(pvd[k].get("timestep")) != times[k]:
        bad("pvd timestep %d" % k)

# XDMF through meshio: Triangle topology, the frames, cell data per triangle
xml = open("run.xdmf").read()
if 'TopologyType="Triangle"' not in xml or "Tetrahedron" in xml or 'NodesPerElement="3"' not in xml:
    bad("xdmf topology is not Triangle")
with meshio.xdmf.TimeSeriesReader("run.xdmf") as r:
    pts, cl = r.read_points_cells()
    if cl[0].type != "triangle" or not np.array_equal(cl[0].data, T) or not np.array_equal(pts, X):
        bad("xdmf mesh: %s %s" % (cl[0].type, cl[0].data.shape))
    if r.num_steps != len(U):
        bad("xdmf: %d steps for %d frames" % (r.num_steps, len(U)))
    for k in (0, len(U) - 1):
        tk, pdk, cdk = r.read_data(k)
        if tk != times[k] or not np.array_equal(pdk["displacement"], U[k]):
            bad("xdmf frame %d" % k)
        A, J, psi = membrane(U[k])
        close(cdk["area"][0], A, "xdmf area", 1e-12); close(cdk["J"][0], J, "xdmf J")
        close(cdk["energy_density"][0], psi, "xdmf energy density", 1e-7, PSI)
        close(cdk["von_mises_stress"][0], mises(U[k]), "xdmf von Mises stress", 1e-7, SIG)
        if "volume" in cdk:
            bad("xdmf: a shell has no volume: %s" % sorted(cdk))
x = h5py.File("run.xdmf.h5")
if x["mesh/triangles"].shape != (ntri, 3) or x["mesh/area"].attrs["units"] not in ("m^2", b"m^2") or "mesh/tets" in x:
    bad("xdmf heavy data: %s" % list(x["mesh"]))
if 'TopologyType="Triangle"' not in open("mesh.xdmf").read():
    bad("bare mesh xdmf")

# MSH (gmsh): one surface of triangles with the displacement views
m = meshio.read("run.msh")
tri = [c for c in m.cells if c.type == "triangle"]
if len(tri) != 1 or len(tri[0].data) != ntri or any(c.type == "tetra" for c in m.cells):
    bad("msh cells: %s" % [(c.type, len(c.data)) for c in m.cells])

# OBJ and PLY: the triangles at X + u
for path in ("last.obj", "last.ply"):
    s = meshio.read(path)
    c = s.cells_dict.get("triangle")
    if c is None or len(c) != ntri or len(s.points) != nv:
        bad("%s: %d points, %s" % (path, len(s.points), [(b.type, len(b.data)) for b in s.cells]))
    # the mesh's triangles, in order, at X + u (PLY in float)
    if not np.allclose(s.points[c], (X + U[-1])[T], rtol=0, atol=1e-6):
        bad(path + ": its triangles are not the mesh's at X + u of the last frame")
print("pvd (%d frames), xdmf (Triangle), msh, obj and ply of the shell check out" % len(U))
PYEOF
ok

# 3. pictures: not blank, and both sides drawn alike (reversing every
#    triangle's orientation, i.e. looking at the other side, gives the same
#    picture)
$PY - <<'PYEOF'
import h5py, shutil
shutil.copy("traj.h5", "flipped.h5")
with h5py.File("flipped.h5", "r+") as f:
    T = f["mesh/triangles"]
    T[...] = T[()][:, [0, 2, 1]]
PYEOF
crom-export -q -o flipped.png flipped.h5
cmp -s last.png flipped.png || fail "the picture changes when the triangles are reversed: a side is not drawn"; ok
$PY - last.png mesh.png pngs/frame_00002.png <<'PYEOF' || fail "PNG of a shell"
import struct, sys, zlib
def decode(path):
    b = open(path, "rb").read()
    if b[:8] != b"\x89PNG\r\n\x1a\n":
        sys.exit(path + ": not a PNG")
    pos, idat = 8, b""
    while pos < len(b):
        n, typ = struct.unpack(">I4s", b[pos:pos + 8]); data = b[pos + 8:pos + 8 + n]
        if typ == b"IHDR":
            w, h, depth, ctype, _, _, interlace = struct.unpack(">IIBBBBB", data)
            if (depth, ctype, interlace) != (8, 2, 0):
                sys.exit(path + ": 8-bit RGB expected")
        elif typ == b"IDAT":
            idat += data
        pos += 12 + n
    raw, bpp, stride = zlib.decompress(idat), 3, 3 * w
    rows, prev = [], bytearray(stride)
    for y in range(h):
        f, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - bpp] if i >= bpp else 0; up = prev[i]; c = prev[i - bpp] if i >= bpp else 0
            if f == 1: line[i] = (line[i] + a) & 255
            elif f == 2: line[i] = (line[i] + up) & 255
            elif f == 3: line[i] = (line[i] + (a + up) // 2) & 255
            elif f == 4:
                p = a + up - c; pa, pb, pc = abs(p - a), abs(p - up), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else up if pb <= pc else c)) & 255
            elif f != 0:
                sys.exit("%s: PNG filter %d" % (path, f))
        rows.append(line); prev = line
    return w, h, rows
for path in sys.argv[1:]:
    w, h, rows = decode(path)
    px = [tuple(r[3 * i:3 * i + 3]) for r in rows for i in range(w)]
    nonwhite = sum(p != (255, 255, 255) for p in px) / len(px)
    print("%s: %d x %d, %.1f%% non-white" % (path, w, h, 100 * nonwhite))
    if nonwhite < 0.2:
        sys.exit(path + " looks blank: the sheet should fill much of the panel")
PYEOF
ok

# 4. crom-diff on shell runs: 0 against itself; against the in-plane run the
#    error of the lumped mass of the triangles (t A / 3 per corner)
crom-diff -q traj.h5 traj.h5 >self.txt
grep -q "^relative displacement error 0 over 21 frames" self.txt || fail "self diff: $(cat self.txt)"; ok
crom-diff -q --csv diff.csv traj.h5 flat.h5 >diff.txt
$PY - <<'PYEOF' || fail "crom-diff of two shell runs"
import csv, sys, h5py, numpy as np
a, b = h5py.File("traj.h5"), h5py.File("flat.h5")
X = a["mesh/vertices"][()]; T = a["mesh/triangles"][()]; t = a["mesh/triangles"].attrs["thickness"]
A = 0.5 * np.linalg.norm(np.cross(X[T[:, 1]] - X[T[:, 0]], X[T[:, 2]] - X[T[:, 0]]), axis=1)
m = np.zeros(len(X))
for k in range(3):
    np.add.at(m, T[:, k], t * A / 3)
ua, ub = a["frames/displacement"][()], b["frames/displacement"][()]
d = ((ua - ub) ** 2).sum(2) @ m; n = (ub ** 2).sum(2) @ m
rows = list(csv.DictReader(open("diff.csv")))
if len(rows) != len(ua):
    sys.exit("%d csv rows for %d frames" % (len(rows), len(ua)))
for k in range(1, len(ua)):
    want = np.sqrt(d[k] / n[k]); got = float(rows[k]["relative_error"])
    if not abs(got - want) <= 1e-9 * want:
        sys.exit("frame %d: relative error %r, expected %r" % (k, got, want))
total = np.sqrt(d.sum() / n.sum())
line = open("diff.txt").read()
got = float(line.split("error ")[1].split()[0])
if not (total > 0.01 and abs(got - total) <= 1e-5 * total):
    sys.exit("run error %r, expected %r: %s" % (got, total, line))
print("crom-diff swinging vs in-plane sheet: %.6g over the run, per frame as the lumped triangle mass gives" % total)
PYEOF
ok

# 5. tet-only paths refuse a shell in one line naming it
crom-modes --count 8 -o modes.h5 hs.h5 2>modes.log   # a free sheet: its six rigid modes are found and dropped
grep -q "6 rigid modes detected" modes.log || fail "free sheet modes: $(cat modes.log)"; ok
expect_error 64 "interior samples the inside of tets.*shell surface" samples.h5 -- crom-sample --mode interior --points 50 -o samples.h5 traj.h5
crom-mesh box --size 0.25 --region top='y>0.45' --region bottom='y<-0.45' -q -o box.h5
BC=(--velocity 'top=0,-2,0@0:0.04' --pin bottom --gravity 0,0,0 --dt 0.01 --steps 4)
crom-fullsim "${BC[@]}" -q -o full.h5 box.h5
crom-sample --points all -q -o samples.h5 full.h5
crom-fitfield --basis pod --rank 3 -q -o pod.h5 samples.h5
crom-cubature --model pod.h5 --scheme all -q -o cubbox.h5 box.h5
crom-reducedstep --cubature cubbox.h5 "${BC[@]}" -q -o red.h5
expect_error 64 "hs.h5 holds a shell surface.*tet meshes only" x.vtu -- crom-export --model pod.h5 --mesh hs.h5 -o x.vtu red.h5
expect_error 64 "hs.h5 holds a shell surface.*tet meshes only" x.png -- crom-export --format strip --model pod.h5 --mesh hs.h5 -o x.png red.h5
expect_error 64 "shell" cub.h5 -- crom-cubature --model pod.h5 --scheme all -o cub.h5 hs.h5
expect_error 64 "shell" - -- crom-diff red.h5 traj.h5 --model pod.h5
expect_error 65 "hs.h5 holds a shell surface, but full.h5 was computed on a tet mesh" x.vtu -- crom-export --mesh hs.h5 -o x.vtu full.h5
expect_error 65 "full.h5 holds a tet mesh, but traj.h5 was computed on a shell surface" - -- crom-diff full.h5 traj.h5
done_checks
