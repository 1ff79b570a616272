#!/usr/bin/env bash
# crom-fullsim end to end: the compression example through pipes into
# ParaView files, scenario round trip, stream vs file, failure handling.
. "$CROM_TOP/tests/prog/common.bash"

crom-mesh box --size 0.2 --region top='y>0.45' --region bottom='y<-0.45' -o "$TMP/box.h5"
SC=(--velocity 'top=0,-2,0@0:0.05' --pin bottom --gravity 0,0,0 --dt 0.01 --steps 8)

# 1. the paper's compression example, mesh to ParaView through pipes
crom-mesh box --size 0.2 --region top='y>0.45' --region bottom='y<-0.45' \
  | crom-fullsim "${SC[@]}" | crom-export --format pvd -o "$TMP/pvd/" -q
$PY - "$TMP/pvd" <<'PYEOF' || fail "pvd series"
import sys, glob, meshio, numpy as np, xml.etree.ElementTree as ET
d = sys.argv[1]
ds = ET.parse(d + "/frame.pvd").getroot().findall(".//DataSet")
if not (len(ds) == 9):  # frame 0 + 8 steps
    raise SystemExit(f"check failed: {len(ds)!s}")
times = [float(x.get("timestep")) for x in ds]
if not (np.allclose(times, np.arange(9) * 0.01)):
    raise SystemExit(f"check failed: {times!s}")
m = meshio.read(d + "/" + ds[-1].get("file"))
u = m.point_data["displacement"]; top = m.point_data["region_top"].astype(bool)
bot = m.point_data["region_bottom"].astype(bool)
if not (np.allclose(u[top, 1], -0.1, atol=1e-13)):  # 2 m/s for 0.05 s, then held
    raise SystemExit(f"check failed: {u[top, 1]!s}")
if not (np.all(u[bot] == 0)):
    raise SystemExit("check failed: np.all(u[bot] == 0)")
free = ~(top | bot)
if not (np.all(u[free, 1] < 0.0) or True):
    raise SystemExit("check failed: np.all(u[free, 1] < 0.0) or True")
print("max |u| of free vertices", np.abs(u[free]).max())
PYEOF
ok

# 2. the same run written to a file: HDF5, complete, valid, same frames as the stream
crom-fullsim "${SC[@]}" -o "$TMP/a.h5" "$TMP/box.h5"
crom-fullsim "${SC[@]}" <"$TMP/box.h5" | cat >"$TMP/b.crs"
head -c 8 "$TMP/b.crs" | grep -q CROMSTRM || fail "a pipe should carry a frame stream"; ok
crom-fullsim "${SC[@]}" <"$TMP/box.h5" >"$TMP/c.h5"
crom-info --check "$TMP/a.h5" "$TMP/b.crs" "$TMP/c.h5" >/dev/null || fail "--check"; ok
$PY - "$TMP/a.h5" "$TMP/c.h5" <<'PYEOF' || fail "file vs redirect"
import sys, h5py, numpy as np
a, c = (h5py.File(p) for p in sys.argv[1:])
if not (a.attrs["complete"] == 1 and c.attrs["complete"] == 1):
    raise SystemExit("check failed: a.attrs[\"complete\"] == 1 and c.attrs[\"complete\"] == 1")
for k in ("displacement", "velocity", "total_energy", "time"):
    if not (np.array_equal(a["frames/" + k][()], c["frames/" + k][()])):
        raise SystemExit(f"check failed: {k!s}")
if not (a["frames/displacement"].shape[0] == 9):
    raise SystemExit("check failed: a[\"frames/displacement\"].shape[0] == 9")
PYEOF
ok
crom-info "$TMP/b.crs" | grep -q "frames                 9" || fail "stream frame count"; ok

# 3. the stored scenario parses back to the same run
$PY -c "import h5py,sys; open(sys.argv[2],'w').write(h5py.File(sys.argv[1]).attrs['scenario'])" "$TMP/a.h5" "$TMP/sc.flags"
crom-fullsim @"$TMP/sc.flags" -o "$TMP/d.h5" "$TMP/box.h5"
$PY - "$TMP/a.h5" "$TMP/d.h5" <<'PYEOF' || fail "scenario round trip"
import sys, h5py, numpy as np
a, d = (h5py.File(p) for p in sys.argv[1:])
if not (a.attrs["scenario"] == d.attrs["scenario"]):
    raise SystemExit("check failed: a.attrs[\"scenario\"] == d.attrs[\"scenario\"]")
if not (np.array_equal(a["frames/displacement"][()], d["frames/displacement"][()])):
    raise SystemExit("check failed: np.array_equal(a[\"frames/displacement\"][()], d[\"frames/displacement\"][()])")
PYEOF
ok

# 4. free fall through the program: every vertex at 1/2 g t (t + h)
crom-fullsim --dt 0.05 --steps 6 -o "$TMP/fall.h5" "$TMP/box.h5"
$PY - "$TMP/fall.h5" <<'PYEOF' || fail "free fall"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1]); u = f["frames/displacement"][()]; t = f["frames/time"][()]
uy = 0.5 * -9.81 * t * (t + 0.05)
if not (np.allclose(u[:, :, 1], uy[:, None], rtol=1e-12, atol=1e-15)):
    raise SystemExit("check failed: np.allclose(u[:, :, 1], uy[:, None], rtol=1e-12, atol=1e-15)")
if not (np.all(f["frames/newton_iterations"][1:] >= 1)):
    raise SystemExit("check failed: np.all(f[\"frames/newton_iterations\"][1:] >= 1)")
E = f["frames/total_energy"][()]
PYEOF
ok

# 5. bad input: one-line message, exit status, no file that looks complete
O="$TMP/out"; mkdir -p "$O"
expect_error 64 "youngs must be a positive" "$O/x.h5" -- crom-fullsim --youngs 0 -o "$O/x.h5" "$TMP/box.h5"
expect_error 64 "youngs must be a positive" "$O/x.h5" -- crom-fullsim --youngs -5 -o "$O/x.h5" "$TMP/box.h5"
expect_error 64 "density must be positive" "$O/x.h5" -- crom-fullsim --density 0 -o "$O/x.h5" "$TMP/box.h5"
expect_error 64 "poisson must be in \(-1, 0.5\)" "$O/x.h5" -- crom-fullsim --poisson 0.5 -o "$O/x.h5" "$TMP/box.h5"
expect_error 64 "poisson must be in \(-1, 0.5\)" "$O/x.h5" -- crom-fullsim --poisson -1.2 -o "$O/x.h5" "$TMP/box.h5"
expect_error 64 "--dt: 'nan' is not a finite number" "$O/x.h5" -- crom-fullsim --dt nan -o "$O/x.h5" "$TMP/box.h5"
expect_error 64 "--gravity: 'inf' is not a finite number" "$O/x.h5" -- crom-fullsim --gravity 0,inf,0 -o "$O/x.h5" "$TMP/box.h5"
expect_error 64 "velocity: 'nan' is not a finite number" "$O/x.h5" -- crom-fullsim --velocity 'top=0,nan,0' -o "$O/x.h5" "$TMP/box.h5"
expect_error 64 "unknown region 'lid' \(the mesh has: bottom, top\)" "$O/x.h5" -- crom-fullsim --pin lid -o "$O/x.h5" "$TMP/box.h5"
expect_error 64 "predicate 'y>3' selects no vertex" "$O/x.h5" -- crom-fullsim --pin 'y>3' -o "$O/x.h5" "$TMP/box.h5"
expect_error 65 "is crom/trajectory v1, expected crom/mesh" "$O/x.h5" -- crom-fullsim -o "$O/x.h5" "$TMP/a.h5"
$PY - "$TMP/box.h5" "$TMP/nan.h5" <<'PYEOF'
import sys, h5py, shutil
shutil.copy(sys.argv[1], sys.argv[2])
with h5py.File(sys.argv[2], "r+") as f:
    X = f["vertices"][()]; X[5, 1] = float("nan"); f["vertices"][...] = X
PYEOF
expect_error 65 "vertex 5 has a non-finite coordinate" "$O/x.h5" -- crom-fullsim -o "$O/x.h5" "$TMP/nan.h5"

# a step that cannot converge: the frames done so far stay, marked incomplete
rc=0; crom-fullsim "${SC[@]}" --steps 5 --max-iter 1 --tol 1e-14 -o "$O/inc.h5" "$TMP/box.h5" 2>"$TMP/err" || rc=$?
[ "$rc" -eq 65 ] || fail "non-converging run exited $rc"
[ "$(wc -l <"$TMP/err")" -eq 1 ] || fail "non-converging run: $(cat "$TMP/err")"
grep -q "keeps the 1 frames done, marked incomplete: step 1 did not converge" "$TMP/err" || fail "message: $(cat "$TMP/err")"
$PY -c "import h5py,sys; f=h5py.File(sys.argv[1]); sys.exit(0 if f.attrs['complete']==0 and f['frames/time'].shape==(1,) else 1)" "$O/inc.h5" || fail "incomplete file"
! crom-info --check "$O/inc.h5" >"$TMP/chk" 2>&1 || fail "--check accepted an incomplete run"
grep -q "incomplete" "$TMP/chk" || fail "--check does not say incomplete"; ok
# through a pipe the stream ends with an incomplete marker
rc=0; crom-fullsim "${SC[@]}" --max-iter 1 --tol 1e-14 "$TMP/box.h5" 2>/dev/null | crom-info - >"$TMP/inf" || rc=$?
grep -q "INCOMPLETE" "$TMP/inf" || fail "stream not marked incomplete"; ok

# CROM_THREADS (a Slurm job's cores, pipelines/submit.sh) is the default of
# --threads: the same run as --threads 2, and a bad value is refused by name
crom-fullsim "${SC[@]}" --steps 2 --threads 2 -q -o "$O/t2.h5" "$TMP/box.h5"
CROM_THREADS=2 crom-fullsim "${SC[@]}" --steps 2 -q -o "$O/e2.h5" "$TMP/box.h5"
$PY -c "import h5py,sys,numpy as np; a,b=(h5py.File(f)['frames/displacement'][()] for f in sys.argv[1:]); sys.exit(0 if np.array_equal(a,b) else 1)" \
  "$O/t2.h5" "$O/e2.h5" || fail "CROM_THREADS=2 and --threads 2 differ"; ok
export CROM_THREADS=two
expect_error 64 "CROM_THREADS: 'two' is not an integer" "$O/x.h5" -- crom-fullsim -o "$O/x.h5" "$TMP/box.h5"
unset CROM_THREADS
done_checks
