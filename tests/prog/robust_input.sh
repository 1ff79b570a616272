#!/usr/bin/env bash
# Untrusted HDF5 input (issue 15, items 1 and 3): files that crash libhdf5
# 1.10 or make it loop (a corrupt global heap), files and stream headers that
# declare far more data than they hold. Every program must end with one line,
# exit 65 and leave no output, in bounded time and memory (run under
# ASan/UBSan with leak detection by `make test SANITIZE=1`).
. "$CROM_TOP/tests/prog/common.bash"
O="$TMP/out"; mkdir -p "$O"
cd "$TMP"
export CROM_PROBE_SECONDS=3   # the contained check's time limit (a hang costs this)

crom-mesh superquadric --exponent 2 --size 0.25 --region bottom='y<-0.45' -o mesh.h5
crom-fullsim --pin bottom --steps 3 --dt 0.01 -q -o traj.h5 mesh.h5
crom-fullsim --pin bottom --steps 3 --dt 0.01 -q -o - mesh.h5 | cat >stream.bin

# corrupt the global heap that holds the root 'schema' string: the size of its
# first object made huge (libhdf5 1.10.8: SIGSEGV in H5HG_read), or the size
# of the collection (an endless loop)
$PY - <<'PYEOF'
import sys
for src in ("mesh.h5", "traj.h5", "stream.bin"):
    b = bytearray(open(src, "rb").read())
    g = b.find(b"GCOL")
    if g < 0:
        sys.exit("no global heap in " + src)
    for tag, off, val in (("crash", 25, 0xFF), ("loop", 8, 0xFF))[:2 if src == "mesh.h5" else 1]:
        c = bytearray(b)
        c[g + off] = val
        open("%s-%s.%s" % (src.split(".")[0], tag, src.split(".")[1]), "wb").write(c)
PYEOF
for t in crash loop; do
  expect_error 65 "mesh-$t.h5: corrupt HDF5 file" - -- crom-info "mesh-$t.h5"
  expect_error 65 "mesh-$t.h5: corrupt HDF5 file" - -- crom-info --check "mesh-$t.h5"
  expect_error 65 "stdin: corrupt HDF5 file" - -- bash -c "crom-info - <mesh-$t.h5"
  expect_error 65 "mesh-$t.h5: corrupt HDF5 file" "$O/m.vtu" -- crom-export --format vtu -o "$O/m.vtu" "mesh-$t.h5"
  expect_error 65 "corrupt HDF5 file" "$O/f.h5" -- crom-fullsim --pin bottom --steps 2 -q -o "$O/f.h5" "mesh-$t.h5"
done
# (the loop needs the mesh file's layout; the crash happens in every file)
expect_error 65 "traj-crash.h5: corrupt HDF5 file" "$O/t.vtu" -- crom-export --format vtu -o "$O/t.vtu" traj-crash.h5
expect_error 65 "traj-crash.h5: corrupt HDF5 file" "$O/s.h5" -- crom-sample --points 10 -o "$O/s.h5" traj-crash.h5
expect_error 65 "stdin: corrupt HDF5 file" - -- bash -c "crom-info --frames - <stream-crash.bin"

# an attribute message ('source' of a region) whose dataspace size is made
# 0x4c08: libhdf5 reads 19 KB past the object header when it looks the name
# up (H5Aexists in crom_mesh_read). Whether that faults depends on the heap
# layout, so the contained walk can survive it where the program would not:
# small files are opened as the child's clean copy, never as these bytes
$PY - <<'PYEOF'
import sys
b = bytearray(open("mesh.h5", "rb").read())
i = b.find(b"\x07\x00\x14\x00\x08\x00source\x00")
if i < 0:
    sys.exit("no 'source' attribute message in mesh.h5")
b[i + 5] = 0x4C
open("mesh-attr.h5", "wb").write(b)
PYEOF
for k in 1 2 3 4 5; do
  rc=0; crom-info mesh-attr.h5 2>attr.err | cat >/dev/null || rc=$?   # (into a pipe: the layout that faulted)
  [ "$rc" -eq 0 ] || [ "$rc" -eq 65 ] || fail "crom-info on a bad attribute message: exit $rc $(cat attr.err)"
done; ok
rc=0; crom-export --format vtu -o "$O/a.vtu" mesh-attr.h5 2>attr.err || rc=$?
[ "$rc" -eq 0 ] || [ "$rc" -eq 65 ] || fail "crom-export on a bad attribute message: exit $rc $(cat attr.err)"; ok

# a 13 KB mesh whose /vertices declares [1e8, 3] doubles and stores none:
# refused before 2.4 GB are allocated for it
$PY - <<'PYEOF'
import h5py, shutil
shutil.copy("mesh.h5", "huge.h5")
with h5py.File("huge.h5", "r+") as f:
    units, desc = f["vertices"].attrs["units"], f["vertices"].attrs["description"]
    del f["vertices"]
    d = f.create_dataset("vertices", shape=(100000000, 3), dtype="f8", chunks=(1024, 3))
    d.attrs["units"] = units; d.attrs["description"] = desc
PYEOF
expect_error 65 "declares 2400000000 bytes but the file stores 0" - -- crom-info --check huge.h5
expect_error 65 "declares 2400000000 bytes" "$O/h.vtu" -- crom-export --format vtu -o "$O/h.vtu" huge.h5
expect_error 65 "declares 2400000000 bytes" "$O/h.h5" -- crom-fullsim --pin bottom --steps 2 -q -o "$O/h.h5" huge.h5

# a stream whose header claims 2^36 bytes (64 GiB) and holds 100: read in
# pieces, so it costs the 100 bytes, not a 64 GiB allocation. Outside ASan the
# address space is limited to 1 GB to prove it.
limit() { case "$CROM_BUILD" in *-san) "$@" ;; *) (ulimit -v 1000000; "$@") ;; esac; }
$PY -c "
import struct, sys
sys.stdout.buffer.write(b'CROMSTRM' + struct.pack('<IIQ', 1, 0, 1 << 36) + b'x' * 100)" >bighead.bin
expect_error 65 "stdin: crom stream header is truncated" - -- limit bash -c "crom-info - <bighead.bin"

# a stream whose header declares frames of 4e8 values (3.2 GB each) and whose
# first frame record claims them but ends after a few bytes: the frame buffer
# grows with the bytes that arrive, so the run ends as an incomplete stream
$PY - <<'PYEOF'
import h5py, io, struct
src = open("stream.bin", "rb").read()
hlen, = struct.unpack("<Q", src[16:24])
img = io.BytesIO()
with h5py.File(io.BytesIO(src[24:24 + hlen]), "r") as old, h5py.File(img, "w") as f:
    for k, v in old.attrs.items():
        f.attrs[k] = v
    g = f.create_group("frames")
    g.attrs["fields"] = "time,q"
    for name, shape in (("time", (0,)), ("q", (0, 400000000))):
        d = g.create_dataset(name, shape=shape, maxshape=(None,) + shape[1:], dtype="f8",
                             chunks=(1,) + tuple(min(s, 1 << 20) for s in shape[1:]))
        d.attrs["units"] = "1"; d.attrs["description"] = "test"
    f.attrs["schema"] = "crom/latent"
h = img.getvalue()
out = b"CROMSTRM" + struct.pack("<IIQ", 1, 0, len(h)) + h
out += b"FRME" + struct.pack("<IQQ", 0, 0, 8 * 400000001) + b"\0" * 64
open("bigframe.bin", "wb").write(out)
PYEOF
rc=0; limit bash -c "crom-info --frames - <bigframe.bin" >bigframe.out 2>bigframe.err || rc=$?
[ "$rc" -ne 70 ] && ! grep -qi "memory" bigframe.err || fail "a claimed 3.2 GB frame was allocated: $(cat bigframe.err)"; ok
[ "$rc" -eq 0 ] || [ "$rc" -eq 65 ] || fail "bigframe: exit $rc: $(cat bigframe.err)"; ok

# the sound files still read
crom-info --check mesh.h5 >/dev/null && crom-info --check traj.h5 >/dev/null || fail "sound files rejected"; ok
crom-info --frames - <stream.bin >/dev/null || fail "sound stream rejected"; ok
done_checks
