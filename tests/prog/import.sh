#!/usr/bin/env bash
# import.sh — crom-mesh import says what it does with a surface much finer
# than --size (issue 12): it remeshes it at --size by default and says so in
# one line with the counts; --keep-surface keeps the triangles (and says the
# mesh will be far finer); a surface about as coarse as --size is kept quietly.
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
# a sphere of radius 0.5 as a subdivided octahedron: 8 * 4^L triangles
$PY - <<'PYEOF' || fail "could not write the test surfaces"
import numpy as np, struct
def sphere(levels):
    V = [np.array(v, float) for v in [(1,0,0),(-1,0,0),(0,1,0),(0,-1,0),(0,0,1),(0,0,-1)]]
    F = [(0,2,4),(2,1,4),(1,3,4),(3,0,4),(2,0,5),(1,2,5),(3,1,5),(0,3,5)]
    for _ in range(levels):
        cache, NF = {}, []
        def mid(a, b):
            k = (min(a, b), max(a, b))
            if k not in cache:
                p = (V[a] + V[b]) / 2; V.append(p / np.linalg.norm(p)); cache[k] = len(V) - 1
            return cache[k]
        for a, b, c in F:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            NF += [(a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)]
        F = NF
    return 0.5 * np.array(V), np.array(F)
for name, levels in (("fine", 5), ("coarse", 2)):
    V, F = sphere(levels)
    with open(name + ".stl", "wb") as f:
        f.write(b"\0" * 80); f.write(struct.pack("<I", len(F)))
        for t in F:
            p = V[t]; n = np.cross(p[1] - p[0], p[2] - p[0]); n /= np.linalg.norm(n)
            f.write(struct.pack("<12fH", *n, *p[0], *p[1], *p[2], 0))
PYEOF
nv() { crom-info "$1" | sed -n 's/^ *\([0-9]*\) vertices, .*/\1/p' | head -1; }

# 1. fine surface (8192 triangles, median edge ~0.03 m) at --size 0.2: remeshed, one line
crom-mesh import fine.stl --size 0.2 -o auto.h5 2>auto.log
[ "$(wc -l <auto.log)" -eq 1 ] || fail "expected one line on stderr: $(cat auto.log)"; ok
grep -qE '^crom-mesh: fine.stl: 8192 triangles with median edge 0\.0[0-9]+ m, much finer than --size 0.2: remeshing' auto.log \
  || fail "message: $(cat auto.log)"; ok
# 2. --remesh gives the same mesh, silently; --keep-surface keeps the triangles, with a note
crom-mesh import fine.stl --size 0.2 --remesh -o remesh.h5 2>remesh.log
[ ! -s remesh.log ] || fail "--remesh printed: $(cat remesh.log)"; ok
[ "$(nv auto.h5)" = "$(nv remesh.h5)" ] || fail "auto ($(nv auto.h5)) and --remesh ($(nv remesh.h5)) differ"; ok
crom-mesh import fine.stl --size 0.2 --keep-surface -o keep.h5 2>keep.log
grep -qE "^crom-mesh: fine.stl: keeping its 8192 triangles .*far finer than --size" keep.log || fail "keep note: $(cat keep.log)"; ok
a=$(nv auto.h5) k=$(nv keep.h5)
echo "vertices: remeshed $a, kept $k"
# kept: at least the 4098 surface vertices; remeshed at 0.2: a few hundred
[ "$k" -ge 4098 ] || fail "--keep-surface has $k vertices, fewer than the surface's 4098"; ok
[ "$a" -lt 1000 ] || fail "the remeshed sphere at --size 0.2 has $a vertices"; ok
# both are the sphere: volume within 5% of 4/3 pi 0.125 (faceted a little below)
for f in auto.h5 keep.h5; do
  vol=$($PY -c "import h5py,numpy as np,sys
f=h5py.File(sys.argv[1]); X=f['vertices'][:]; T=f['tets'][:]
a,b,c,d=(X[T[:,i]] for i in range(4)); print(np.sum(np.einsum('ij,ij->i',np.cross(b-a,c-a),d-a))/6)" $f)
  close "$vol" 0.5236 0.026 "volume of $f"
done
# 3. a surface about as coarse as --size is kept, quietly (128 triangles, edge ~0.2 m)
crom-mesh import coarse.stl --size 0.2 -o coarse.h5 2>coarse.log
[ ! -s coarse.log ] || fail "coarse import printed: $(cat coarse.log)"; ok
crom-info coarse.h5 >/dev/null || fail "coarse import"; ok
done_checks
