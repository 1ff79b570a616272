#!/usr/bin/env bash
# Bad input to the foundation programs: each case must end with a one-line
# message naming the problem, the documented exit status, and no output
# file left behind (run under ASan/UBSan by `make test SANITIZE=1`).
. "$CROM_TOP/tests/prog/common.bash"
O="$TMP/out"; mkdir -p "$O"

crom-mesh box --size 0.25 -o "$TMP/good.h5"

# truncated file
head -c 1500 "$TMP/good.h5" >"$TMP/trunc.h5"
expect_error 65 "truncated or corrupt" "$O/t.vtu" -- crom-export --format vtu -o "$O/t.vtu" "$TMP/trunc.h5"
expect_error 65 "truncated or corrupt" - -- crom-info "$TMP/trunc.h5"
# the same through a pipe
expect_error 65 "stdin: HDF5 file is truncated or corrupt" "$O/t.vtu" -- bash -c "cat '$TMP/trunc.h5' | crom-export --format vtu -o '$O/t.vtu'"

# random bytes
head -c 4096 /dev/urandom >"$TMP/random.bin"
expect_error 65 "not a crom file" "$O/r.vtu" -- crom-export --format vtu -o "$O/r.vtu" "$TMP/random.bin"
expect_error 65 "not a crom file" - -- crom-info --check "$TMP/random.bin"
# empty input
expect_error 65 "stdin is empty" "$O/e.vtu" -- bash -c "crom-export --format vtu -o '$O/e.vtu' </dev/null"

# a file of the wrong schema, and a newer schema_version
$PY - "$TMP" <<'PYEOF'
import sys, h5py, shutil
d = sys.argv[1]
with h5py.File(d + "/model.h5", "w") as f:
    f.attrs["schema"] = "crom/model"; f.attrs["schema_version"] = 1
    f.attrs["history"] = "made by a test"; f.attrs["crom_version"] = "0"
shutil.copy(d + "/good.h5", d + "/newer.h5")
with h5py.File(d + "/newer.h5", "r+") as f:
    f.attrs["schema_version"] = 7
with h5py.File(d + "/plain.h5", "w") as f:
    f["x"] = [1, 2, 3]
PYEOF
expect_error 65 "is crom/model v1, expected crom/trajectory" "$O/w.vtu" -- crom-export --format vtu -o "$O/w.vtu" "$TMP/model.h5"
expect_error 65 "crom/mesh v7, newer than this crom understands \(v1\)" "$O/n.vtu" -- crom-export --format vtu -o "$O/n.vtu" "$TMP/newer.h5"
expect_error 65 "1 schema violation" - -- crom-info --check "$TMP/newer.h5"
expect_error 65 "not a crom file \(no 'schema' attribute\)" - -- crom-info "$TMP/plain.h5"

# an open (non-closed) STL, and an STL that is not one
cat >"$TMP/open.stl" <<'STL'
solid open
facet normal 0 0 -1
 outer loop
  vertex 0 0 0
  vertex 0 1 0
  vertex 1 0 0
 endloop
endfacet
facet normal 0 -1 0
 outer loop
  vertex 0 0 0
  vertex 1 0 0
  vertex 0 0 1
 endloop
endfacet
facet normal -1 0 0
 outer loop
  vertex 0 0 0
  vertex 0 0 1
  vertex 0 1 0
 endloop
endfacet
facet normal 0 0 -1
 outer loop
  vertex 1 0 0
  vertex 0 1 0
  vertex 1 1 0
 endloop
endfacet
endsolid open
STL
expect_error 65 "open.stl: surface is not closed \([0-9]+ boundary edges\)" "$O/o.h5" -- crom-mesh import "$TMP/open.stl" -o "$O/o.h5"
head -c 300 /dev/urandom >"$TMP/junk.stl"
expect_error 65 "junk.stl: not an STL file" "$O/j.h5" -- crom-mesh import "$TMP/junk.stl" -o "$O/j.h5"

# missing files
expect_error 66 "/nonexistent/mesh.h5: No such file or directory" "$O/m.vtu" -- crom-export --format vtu -o "$O/m.vtu" /nonexistent/mesh.h5
expect_error 66 "No such file or directory" "$O/m.h5" -- crom-mesh import /nonexistent/shape.stl -o "$O/m.h5"
expect_error 66 "No such file or directory" - -- crom-info /nonexistent/x.h5

# an unknown region name (a gmsh group that the file does not have), and an empty one
cat >"$TMP/b.geo" <<'GEO'
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 1, 1, 1};
Physical Surface("bottom") = {3};
GEO
expect_error 64 "unknown region 'nosuch' \(the mesh has: bottom\)" "$O/g.h5" -- crom-mesh import "$TMP/b.geo" --size 0.3 --region base=nosuch -o "$O/g.h5"
expect_error 64 "predicate 'x>7' selects no vertex" "$O/g.h5" -- crom-mesh box --size 0.3 --region far='x>7' -o "$O/g.h5"
expect_error 64 "'q<1' is not a predicate" "$O/g.h5" -- crom-mesh box --size 0.3 --region far='q<1' -o "$O/g.h5"

# non-positive and non-numeric sizes and dimensions
expect_error 64 "size.*must be positive" "$O/s.h5" -- crom-mesh box --size 0 -o "$O/s.h5"
expect_error 64 "size.*must be positive" "$O/s.h5" -- crom-mesh box --size -0.1 -o "$O/s.h5"
expect_error 64 "not a finite number" "$O/s.h5" -- crom-mesh box --size nan -o "$O/s.h5"
expect_error 64 "dims.*positive" "$O/s.h5" -- crom-mesh box --dims 1,0,1 -o "$O/s.h5"
expect_error 64 "expected 3 comma-separated numbers" "$O/s.h5" -- crom-mesh box --dims 1,1 -o "$O/s.h5"
expect_error 64 "radius.*positive" "$O/s.h5" -- crom-mesh sphere --radius -1 -o "$O/s.h5"
expect_error 64 "too small" "$O/s.h5" -- crom-mesh box --size 1e-5 -o "$O/s.h5"
expect_error 64 "unknown shape 'blob'" "$O/s.h5" -- crom-mesh blob -o "$O/s.h5"
expect_error 64 "unknown option '--sise'" "$O/s.h5" -- crom-mesh box --sise 1 -o "$O/s.h5"
# an unwritable output
expect_error 73 "cannot create /nonexistent-dir/x.h5" - -- crom-mesh box --size 0.3 -o /nonexistent-dir/x.h5

# a flags file stands in for flags; its errors are reported too
printf '# box flags\n--size 0.3   # coarse\n--region "top=y>0.45"\n' >"$TMP/mesh.flags"
crom-mesh box @"$TMP/mesh.flags" -o "$O/f.h5" && crom-info "$O/f.h5" | grep -q "region top" || fail "@FILE flags"; ok
rm -f "$O/f.h5"
expect_error 66 "@/nonexistent.flags: No such file" "$O/f.h5" -- crom-mesh box @/nonexistent.flags -o "$O/f.h5"
done_checks
