#!/usr/bin/env bash
# crom-mesh and crom-info through pipes and files: same data either way,
# summaries that read back the numbers, schema validation.
# asan: skip (gmsh meshing, which ASan does not instrument but slows threefold; tests/unit/test_mesh.c covers crom's meshing and reading code there)
. "$CROM_TOP/tests/prog/common.bash"

# 1. a pipe into crom-info works and reports the exact unit-box volume
crom-mesh box --size 0.2 --region top='y>0.45' | crom-info - >"$TMP/info.txt"
grep -q "crom/mesh v1" "$TMP/info.txt" || fail "crom-info did not name the schema"
vol=$(sed -n 's/.*tets, volume \([0-9.e+-]*\) m^3/\1/p' "$TMP/info.txt")
close "$vol" 1 1e-9 "unit box volume"
grep -q "region top" "$TMP/info.txt" || fail "region not listed"; ok

# 2. written with -o, through a pipe, and redirected to a file: same data
crom-mesh sphere --size 0.15 --region cap='y>0.3' -o "$TMP/a.h5"
crom-mesh sphere --size 0.15 --region cap='y>0.3' | cat >"$TMP/b.h5"
crom-mesh sphere --size 0.15 --region cap='y>0.3' >"$TMP/c.h5"
$PY - "$TMP/a.h5" "$TMP/b.h5" "$TMP/c.h5" <<'PYEOF' || fail "pipe and -o outputs differ"
import sys, h5py, numpy as np
files = [h5py.File(p, "r") for p in sys.argv[1:]]
def items(f):
    out = {}
    f.visititems(lambda n, o: out.__setitem__(n, o[()]) if isinstance(o, h5py.Dataset) else None)
    return out
ref = items(files[0])
if not (set(ref) == {"vertices", "tets", "regions/cap"}):
    raise SystemExit(f"check failed: {sorted(ref)!s}")
for f in files[1:]:
    other = items(f)
    if not (set(other) == set(ref)):
        raise SystemExit("check failed: set(other) == set(ref)")
    for k in ref:
        if not (np.array_equal(ref[k], other[k])):
            raise SystemExit(f"check failed: {k!s}")
    for a in ("schema", "schema_version", "generator", "target_size"):
        if not (f.attrs[a] == files[0].attrs[a]):
            raise SystemExit(f"check failed: {a!s}")
print("same data in", len(files), "files")
PYEOF
ok

# 3. history names the command; SOURCE_DATE_EPOCH makes it reproducible
$PY -c "import h5py,sys; h=h5py.File(sys.argv[1]).attrs['history']; sys.exit(0 if 'crom-mesh sphere --size 0.15' in h and h.startswith('2023-11-14T22:13:20Z') else 'check failed: ' + str(h))" "$TMP/a.h5" \
  || fail "history attribute"; ok

# 4. --check accepts what crom-mesh writes; every tet positive (re-checked in Python)
crom-info --check "$TMP/a.h5" | grep -q "valid crom/mesh v1" || fail "--check rejected a good mesh"; ok
$PY - "$TMP/a.h5" <<'PYEOF' || fail "orientation"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1]); X = f["vertices"][()]; T = f["tets"][()]
V = np.einsum("ij,ij->i", np.cross(X[T[:,1]]-X[T[:,0]], X[T[:,2]]-X[T[:,0]]), X[T[:,3]]-X[T[:,0]]) / 6
if not (V.min() > 0):
    raise SystemExit(f"check failed: {V.min()!s}")
cap = f["regions/cap"][()]
if not (np.all(X[cap, 1] > 0.3) and np.sum(X[:, 1] > 0.3) == len(cap)):
    raise SystemExit("check failed: np.all(X[cap, 1] > 0.3) and np.sum(X[:, 1] > 0.3) == len(cap)")
PYEOF
ok

# 5. every shape meshes and validates; the superquadric family spans
#    octahedron to cube in volume
prev=0
for p in 1 2 4 10; do
  crom-mesh superquadric --exponent $p --size 0.1 -o "$TMP/sq$p.h5"
  crom-info --check "$TMP/sq$p.h5" >/dev/null || fail "superquadric $p invalid"
  v=$(crom-info "$TMP/sq$p.h5" | sed -n 's/.*tets, volume \([0-9.e+-]*\) m^3/\1/p')
  $PY -c "import sys; sys.exit(0 if float(sys.argv[1]) > float(sys.argv[2]) else 1)" "$v" "$prev" || fail "volumes not increasing with p"
  prev=$v; ok
done
for s in box plate sphere cylinder; do
  crom-mesh $s --size 0.15 | crom-info --check - >/dev/null || fail "$s invalid"; ok
done

# 6. gmsh physical groups of a .geo become regions; --region can rename them
cat >"$TMP/block.geo" <<'GEO'
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 0.5, 0.5};
Physical Volume("solid") = {1};
Physical Surface("left") = {1};
GEO
crom-mesh import "$TMP/block.geo" --size 0.1 --region clamp=left -v -o "$TMP/block.h5" 2>"$TMP/err.txt"
grep -q "region clamp" "$TMP/err.txt" || fail "--region from a gmsh group"
$PY - "$TMP/block.h5" <<'PYEOF' || fail "gmsh group region"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1]); X = f["vertices"][()]
left = f["regions/left"][()]; clamp = f["regions/clamp"][()]
if not (np.array_equal(left, clamp)):
    raise SystemExit("check failed: np.array_equal(left, clamp)")
if not (np.allclose(X[left, 0], 0) and np.sum(np.isclose(X[:, 0], 0)) == len(left)):
    raise SystemExit("check failed: np.allclose(X[left, 0], 0) and np.sum(np.isclose(X[:, 0], 0)) == len(left)")
if not (len(f["regions/solid"][()]) == len(X)):
    raise SystemExit("check failed: len(f[\"regions/solid\"][()]) == len(X)")
PYEOF
ok
v=$(crom-info "$TMP/block.h5" | sed -n 's/.*tets, volume \([0-9.e+-]*\) m^3/\1/p'); close "$v" 0.25 1e-9 "imported block volume"

# 7. a closed OBJ surface is meshed inside; --verbose prints counts and quality
printf 'v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n' >"$TMP/tet.obj"
crom-mesh import "$TMP/tet.obj" --size 0.1 -v -o "$TMP/tet.h5" 2>"$TMP/err.txt"
grep -qE "[0-9]+ vertices, [0-9]+ tets, volume 0.166667 m\^3, quality worst 0\.[0-9]+" "$TMP/err.txt" || fail "verbose summary: $(cat "$TMP/err.txt")"; ok

# 8. help and version on every program
for p in "$CROM_BINDIR"/crom-*; do
  [ -x "$p" ] || continue
  "$p" --help >"$TMP/help.txt" && grep -q "Usage:" "$TMP/help.txt" || fail "$(basename "$p") --help"
  "$p" --version >"$TMP/help.txt" && grep -q "crom" "$TMP/help.txt" || fail "$(basename "$p") --version"
  "$p" --help-man >"$TMP/help.txt" && grep -q '^\.SH SYNOPSIS' "$TMP/help.txt" || fail "$(basename "$p") --help-man"
  ok
done
done_checks
