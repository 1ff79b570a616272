#!/usr/bin/env bash
# crom-export, grown: XDMF+HDF5 series that meshio reads back (vertices,
# tets, regions, every frame's displacement and time), a bare mesh as XDMF,
# --follow-schedule (each frame on the mesh its reduced run had), OBJ/PLY
# sequences with --frame all, PNG frames and strips that decode and are not
# blank, atomic outputs on failure.
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
crom-mesh box --size 0.25 --region top='y>0.45' --region bottom='y<-0.45' -o box.h5
SC=(--velocity 'top=0,-2,0@0:0.04' --pin bottom --gravity 0,-9.81,0 --dt 0.01 --steps 6)
crom-fullsim "${SC[@]}" -q -o full.h5 box.h5

# 1. a trajectory as XDMF: meshio's TimeSeriesReader gets back the mesh, the
#    regions and every frame (time, displacement, velocity) exactly
crom-export --format xdmf -q -o run.xdmf full.h5
[ -f run.xdmf ] && [ -f run.xdmf.h5 ] || fail "xdmf: run.xdmf and run.xdmf.h5 expected"; ok
crom-export -q -o dir/ --format xdmf --name series full.h5           # a directory, --name
crom-fullsim "${SC[@]}" -q box.h5 | crom-export --format xdmf -q -o piped.xdmf   # a stream on stdin
$PY - <<'PYEOF' || fail "meshio reads the XDMF series"
import h5py, meshio, numpy as np
f = h5py.File("full.h5"); X = f["mesh/vertices"][()]; T = f["mesh/tets"][()]
U = f["frames/displacement"][()]; V = f["frames/velocity"][()]; t = f["frames/time"][()]
bot = f["mesh/regions/bottom"][()]
for name in ("run.xdmf", "dir/series.xdmf", "piped.xdmf"):
    with meshio.xdmf.TimeSeriesReader(name) as r:
        p, cells = r.read_points_cells()
        if not (np.array_equal(p, X)):
            raise SystemExit("check failed: " + str("vertices"))
        if not (len(cells) == 1 and cells[0].type == "tetra" and np.array_equal(cells[0].data, T)):
            raise SystemExit("check failed: " + str("tets"))
        if not (r.num_steps == len(t)):
            raise SystemExit(f"check failed: {(r.num_steps, len(t))!s}")
        for k in range(r.num_steps):
            tk, pd, cd = r.read_data(k)
            if not (tk == t[k]):
                raise SystemExit(f"check failed: {(tk, t[k])!s}")
            if not (np.array_equal(pd["displacement"], U[k])):
                raise SystemExit("check failed: " + str("displacement of frame %d" % k))
            if not (np.array_equal(pd["velocity"], V[k])):
                raise SystemExit("check failed: " + str("velocity of frame %d" % k))
            if not (np.array_equal(np.nonzero(pd["region_bottom"])[0], bot)):
                raise SystemExit("check failed: " + str("region mask"))
print("xdmf: %d frames of %d vertices read back exactly" % (len(t), len(X)))
PYEOF
ok
# the heavy data are plain HDF5 with the documented layout
h5ls -r run.xdmf.h5 | grep -q '^/displacement/00006 ' || fail "xdmf: /displacement/00006 missing"; ok
h5ls -r run.xdmf.h5 | grep -q '^/time ' || fail "xdmf: /time missing"; ok
# a bare mesh: one grid, read by meshio.read
crom-export -q -o mesh.xdmf box.h5
$PY -c "
import meshio, h5py, numpy as np
m = meshio.read('mesh.xdmf'); f = h5py.File('box.h5')
if not (np.array_equal(m.points, f['vertices'][()]) and np.array_equal(m.cells_dict['tetra'], f['tets'][()])): raise SystemExit('check failed: mesh')
if not np.array_equal(np.nonzero(m.point_data['region_top'])[0], f['regions/top'][()]): raise SystemExit('check failed: region top')
" || fail "meshio.read of a mesh as XDMF"
ok
# --every keeps every K-th frame
crom-export --format xdmf --every 3 -q -o every.xdmf full.h5
[ "$(grep -c '<Time ' every.xdmf)" -eq 3 ] || fail "xdmf --every 3 of 7 frames: $(grep -c '<Time ' every.xdmf) frames"; ok

# 2. the heavy data never replace an input, and a failed export leaves nothing
cp full.h5 clash.xdmf.h5
expect_error 64 "would overwrite the input" "clash.xdmf" -- crom-export -o clash.xdmf clash.xdmf.h5
crom-fullsim "${SC[@]}" -q --stream -o stream.bin box.h5
# a stream whose 4th frame record is corrupt: the export fails after 3 frames
$PY -c "
b = open('stream.bin', 'rb').read(); i = -1
for _ in range(4): i = b.index(b'FRME', i + 1)
open('cut.bin', 'wb').write(b[:i] + b'XXXX' + b[i + 4:])"
expect_error 65 "cut.bin.*corrupt" "cut.xdmf" -- crom-export --format xdmf -o cut.xdmf cut.bin
[ ! -e cut.xdmf.h5 ] || fail "a failed xdmf export left cut.xdmf.h5"; ok

# 3. a reduced run that switches meshes: --follow-schedule decodes each frame
#    on the mesh of its cubature; VTU and XDMF agree with W q on that mesh
crom-sample --points all -o samples.h5 full.h5
crom-fitfield --basis pod --rank 4 -q -o pod.h5 samples.h5
crom-remesh punch --box -0.6,-0.2,-0.6,0.6,0.2,0 -q -o punched.h5 box.h5
crom-cubature --model pod.h5 --scheme all -q -o cub0.h5 box.h5
crom-cubature --model pod.h5 --scheme all -q -o cub1.h5 punched.h5
echo "4 cub1.h5" >sched.txt
crom-reducedstep --cubature cub0.h5 --schedule sched.txt "${SC[@]}" -q -o red.h5
crom-export --format pvd --follow-schedule --model pod.h5 -q -o fpvd red.h5
crom-export --format xdmf --follow-schedule --model pod.h5 -q -o fx.xdmf red.h5
$PY - <<'PYEOF' || fail "--follow-schedule"
import h5py, meshio, numpy as np
r = h5py.File("red.h5"); q = r["frames/q"][()]; cub = r["frames/cubature"][()]
B = h5py.File("pod.h5")["field/basis"][()]            # [nv][3][r] on box.h5's vertices
X0 = h5py.File("box.h5")["vertices"][()]; X1 = h5py.File("punched.h5")["vertices"][()]
# punched.h5's vertices are a subset of box.h5's: find them
idx = {tuple(x): i for i, x in enumerate(X0)}; sub = np.array([idx[tuple(x)] for x in X1])
if not (list(cub) == [0, 0, 0, 0, 1, 1, 1]):
    raise SystemExit(f"check failed: {cub!s}")
with meshio.xdmf.TimeSeriesReader("fx.xdmf") as xr:
    xr.read_points_cells()
    for k in range(len(q)):
        v = meshio.read("fpvd/frame_%05d.vtu" % k)
        X, rows = (X0, slice(None)) if cub[k] == 0 else (X1, sub)
        if not (np.array_equal(v.points, X)):
            raise SystemExit("check failed: " + str("vtu %d on the wrong mesh" % k))
        u = np.einsum("vcr,r->vc", B[rows], q[k])
        if not (np.allclose(v.point_data["displacement"], u, atol=1e-12)):
            raise SystemExit("check failed: " + str("vtu %d displacement" % k))
        t, pd, cd = xr.read_data(k)
        if not (np.allclose(pd["displacement"], u, atol=1e-12)):
            raise SystemExit("check failed: " + str("xdmf %d displacement" % k))
x = open("fx.xdmf").read()
if not (x.count("fx.xdmf.h5:/mesh_1/vertices") == 3 and x.count("fx.xdmf.h5:/mesh/vertices") == 4):
    raise SystemExit("check failed: x.count(\"fx.xdmf.h5:/mesh_1/vertices\") == 3 and x.count(\"fx.xdmf.h5:/mesh/vertices\") == 4")
print("follow-schedule: frames 0-3 on the box, 4-6 on the punched box")
PYEOF
ok
# without it, every frame is decoded on the one --mesh
crom-export --format pvd --model pod.h5 --mesh box.h5 -q -o onepvd red.h5
[ "$(grep -l 'NumberOfPoints="'"$(h5ls box.h5/vertices | grep -o '{[0-9]*' | tr -d '{')"'"' onepvd/*.vtu | wc -l)" -eq 7 ] \
  || fail "pvd without --follow-schedule: all frames on --mesh"; ok
# an MSH file holds one mesh: a run that switches meshes is refused, nothing left
expect_error 64 "an MSH file holds one mesh" "fx.msh" -- crom-export --format msh --follow-schedule --model pod.h5 -o fx.msh red.h5
expect_error 64 "give it as a file" "s.png" -- bash -c "crom-export --format strip --follow-schedule --model pod.h5 -o s.png - < red.h5"

# 4. --frame all: OBJ and PLY sequences, one surface per frame, the last one
#    equal to --frame -1
crom-export --format obj --frame all -q -o objs full.h5
crom-export --format ply --frame all --every 2 -q -o plys full.h5
crom-export --format obj -q -o last.obj full.h5
[ "$(ls objs/*.obj | wc -l)" -eq 7 ] || fail "obj sequence: $(ls objs | wc -l) files for 7 frames"; ok
[ "$(ls plys/*.ply | wc -l)" -eq 4 ] || fail "ply sequence with --every 2: $(ls plys | wc -l) files"; ok
cmp -s objs/frame_00006.obj last.obj || fail "the last OBJ of the sequence differs from --frame -1"; ok
$PY - <<'PYEOF' || fail "obj/ply sequences read back"
import h5py, meshio, numpy as np
f = h5py.File("full.h5"); X = f["mesh/vertices"][()]; U = f["frames/displacement"][()]
for k in range(7):
    s = meshio.read("objs/frame_%05d.obj" % k)
    # every surface point is a deformed vertex X + u of frame k
    x = X + U[k]
    d = np.min(np.linalg.norm(s.points[:, None, :] - x[None, :, :], axis=2), axis=1)
    if not (d.max() < 1e-8):
        raise SystemExit(f"check failed: {(k, d.max())!s}")
    if k % 2 == 0:
        p = meshio.read("plys/frame_%05d.ply" % (k // 2))
        if not (len(p.points) == len(s.points) and np.allclose(p.points, s.points, atol=1e-6)):
            raise SystemExit("check failed: len(p.points) == len(s.points) and np.allclose(p.points, s.points, atol=1e-6)")
print("obj/ply sequences: every frame's surface at X + u")
PYEOF
ok

# 5. PNG frames and strips decode (stdlib zlib, all five PNG filters undone)
#    and are not blank: they have enough non-white pixels, with colour spread
crom-export --format png --frame all -q -o pngs full.h5
crom-export --format png --panel 200x160 -q -o one.png full.h5
crom-export --format strip --columns 3 --panel 160x120 --model pod.h5 --mesh box.h5 --compare full.h5 -q -o strip.png red.h5
crom-export --format strip --columns 4 --panel 160x120 --follow-schedule --model pod.h5 --compare full.h5 -q -o fstrip.png red.h5
[ "$(ls pngs/*.png | wc -l)" -eq 7 ] || fail "png sequence: $(ls pngs | wc -l) files"; ok
$PY - pngs/frame_00000.png pngs/frame_00006.png one.png strip.png fstrip.png <<'PYEOF' || fail "PNG decode"
import struct, sys, zlib
def decode(path):
    b = open(path, "rb").read()
    if not (b[:8] == b"\x89PNG\r\n\x1a\n"):
        raise SystemExit("check failed: " + str("signature"))
    pos, idat, w = 8, b"", None
    while pos < len(b):
        n, typ = struct.unpack(">I4s", b[pos:pos + 8]); data = b[pos + 8:pos + 8 + n]
        crc, = struct.unpack(">I", b[pos + 8 + n:pos + 12 + n])
        if not (zlib.crc32(typ + data) & 0xffffffff == crc):
            raise SystemExit("check failed: " + str("CRC of " + typ.decode()))
        if typ == b"IHDR":
            w, h, depth, ctype, _, _, interlace = struct.unpack(">IIBBBBB", data)
            if not (depth == 8 and ctype == 2 and interlace == 0):
                raise SystemExit("check failed: " + str("8-bit RGB expected"))
        elif typ == b"IDAT":
            idat += data
        pos += 12 + n
    raw, bpp, stride = zlib.decompress(idat), 3, 3 * w
    if not (len(raw) == h * (stride + 1)):
        raise SystemExit("check failed: " + str("image data size"))
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
                raise SystemExit("check failed: PNG filter %d" % f)
        rows.append(line); prev = line
    return w, h, rows
for path in sys.argv[1:]:
    w, h, rows = decode(path)
    px = [tuple(r[3 * i:3 * i + 3]) for r in rows for i in range(w)]
    nonwhite = sum(p != (255, 255, 255) for p in px) / len(px)
    colours = len(set(px))
    mean = [sum(p[c] for p in px) / len(px) for c in range(3)]
    var = sum((p[c] - mean[c]) ** 2 for p in px for c in range(3)) / (3 * len(px))
    print("%s: %d x %d, %.1f%% non-white, %d colours, variance %.0f" % (path, w, h, 100 * nonwhite, colours, var))
    if not (nonwhite > 0.05 and colours > 20 and var > 100):
        raise SystemExit("check failed: " + str(path + " looks blank"))
    if path == "one.png":
        if not ((w, h) == (200, 160 + 34)):
            raise SystemExit(f"check failed: {(w, h)!s}")
    if path == "strip.png":
        if not ((w, h) == (3 * 160, 2 * 120 + 34)):
            raise SystemExit(f"check failed: {(w, h)!s}")
PYEOF
ok

# 6. an unknown format names the new list
expect_error 64 "not vtu, pvd, xdmf, msh, obj, ply, stl, png or strip" "x.out" -- crom-export --format vtk -o x.out full.h5
done_checks
