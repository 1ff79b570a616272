#!/usr/bin/env bash
# crom-export: VTU that meshio reads back with the same vertices, tets and
# volume; surface OBJ/PLY closed and outward.
. "$CROM_TOP/tests/prog/common.bash"

crom-mesh cylinder --size 0.12 --region base='y<-0.45' -o "$TMP/c.h5"
crom-export --format vtu -o "$TMP/c.vtu" <"$TMP/c.h5"
crom-mesh cylinder --size 0.12 --region base='y<-0.45' | crom-export -o "$TMP/p.vtu"   # format from the extension
crom-export --format obj -o "$TMP/c.obj" "$TMP/c.h5"
crom-export --format ply -o "$TMP/c.ply" "$TMP/c.h5"
$PY - "$TMP" <<'PYEOF' || fail "meshio round trip"
import sys, h5py, meshio, numpy as np
d = sys.argv[1]
f = h5py.File(d + "/c.h5"); X = f["vertices"][()]; T = f["tets"][()]; base = f["regions/base"][()]
for name in ("c.vtu", "p.vtu"):
    m = meshio.read(d + "/" + name)
    if not (np.array_equal(m.points, X)):
        raise SystemExit("check failed: " + str("vertices differ"))
    if not (np.array_equal(m.cells_dict["tetra"], T)):
        raise SystemExit("check failed: " + str("tets differ"))
    mask = m.point_data["region_base"]
    if not (np.array_equal(np.nonzero(mask)[0], base)):
        raise SystemExit("check failed: " + str("region mask differs"))
def vol(X, T):
    return np.sum(np.einsum("ij,ij->i", np.cross(X[T[:,1]]-X[T[:,0]], X[T[:,2]]-X[T[:,0]]), X[T[:,3]]-X[T[:,0]])) / 6
V = vol(m.points, m.cells_dict["tetra"])
if not (abs(V - vol(X, T)) < 1e-14):
    raise SystemExit("check failed: abs(V - vol(X, T)) < 1e-14")
# the surfaces enclose the same volume (divergence theorem), outward oriented
for name in ("c.obj", "c.ply"):
    s = meshio.read(d + "/" + name); P = s.points.astype(float); F = s.cells_dict["triangle"]
    Vs = np.sum(np.einsum("ij,ij->i", P[F[:,0]], np.cross(P[F[:,1]], P[F[:,2]]))) / 6
    tol = 1e-6 if name.endswith("ply") else 1e-7   # PLY stores float32
    if not (abs(Vs - V) < tol * 10):
        raise SystemExit(f"check failed: {(name, Vs, V)!s}")
print("volume", V)
PYEOF
ok
# crom-info reports the same volume
v=$(crom-info "$TMP/c.h5" | sed -n 's/.*tets, volume \([0-9.e+-]*\) m^3/\1/p')
$PY -c "
import meshio, numpy as np, sys
m = meshio.read(sys.argv[1]); X = m.points; T = m.cells_dict['tetra']
V = np.sum(np.einsum('ij,ij->i', np.cross(X[T[:,1]]-X[T[:,0]], X[T[:,2]]-X[T[:,0]]), X[T[:,3]]-X[T[:,0]])) / 6
sys.exit(0 if abs(V - float(sys.argv[2])) < 1e-5 * V else 1)" "$TMP/c.vtu" "$v" || fail "crom-info volume vs meshio"
ok
# VTU to a terminal is text, but PLY to a terminal is refused: stdout on a
# pseudo-terminal
$PY - "$TMP/c.h5" <<'PYEOF' || fail "terminal output"
import os, pty, subprocess, sys
def on_tty(fmt):
    master, slave = pty.openpty()
    p = subprocess.Popen(["crom-export", "--format", fmt, sys.argv[1]], stdin=subprocess.DEVNULL, stdout=slave,
                         stderr=subprocess.PIPE)
    os.close(slave)
    out = b""
    try:                     # read while it writes (a terminal holds little)
        while True:
            chunk = os.read(master, 65536)
            if not chunk:
                break
            out += chunk
    except OSError:          # EIO once the terminal's writer has gone
        pass
    os.close(master)
    err = p.stderr.read().decode()
    return p.wait(), err, out
rc, err, out = on_tty("ply")
if rc != 64 or "refusing to write binary output to a terminal" not in err or out:
    sys.exit("ply to a terminal: exit %d, stderr %r, %d bytes written" % (rc, err, len(out)))
rc, err, out = on_tty("vtu")
if rc != 0 or b"<VTKFile" not in out:
    sys.exit("vtu to a terminal: exit %d, stderr %r" % (rc, err))
print("ply to a terminal refused (exit 64), vtu written (%d bytes)" % len(out))
PYEOF
ok
expect_error 64 "format" "$TMP/x.vtu" -- crom-export --format xyz -o "$TMP/x.vtu" "$TMP/c.h5"
done_checks
