#!/usr/bin/env bash
# The reduced pipeline end to end (LiCROM §4-6 with a POD basis, which is
# fast and deterministic): accuracy against crom-fullsim on the training
# scenario, pins, cubature schemes, schedule switches to punched meshes,
# crom-diff, bad input.
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
crom-mesh box --size 0.15 --region top='y>0.45' --region bottom='y<-0.45' -o box.h5
SC=(--velocity 'top=0,-2,0@0:0.08' --pin bottom --gravity 0,-9.81,0 --dt 0.01 --steps 16)
crom-fullsim "${SC[@]}" -o full.h5 box.h5
crom-sample --points all -o samples.h5 full.h5
crom-fitfield --basis pod --rank 6 -q -o pod.h5 <samples.h5
crom-encode --model pod.h5 -q -o poses.h5 <full.h5

# 1. every cubature scheme runs; optimized fits its poses closely
for s in "all" "random --count 40" "metis --count 40" "optimized --count 40"; do
  n=${s%% *}
  crom-cubature --model pod.h5 --scheme $s --poses poses.h5 -o cub_$n.h5 box.h5 2>cub_$n.log
  crom-info --check cub_$n.h5 >/dev/null || fail "cubature $n invalid"; ok
done
grep -q "relative error on .* poses: elastic energy" cub_optimized.log || fail "cubature error report"
ferr=$(sed -n 's/.*reduced force \([0-9.e+-]*\)/\1/p' cub_optimized.log)
close "$ferr" 0 0.02 "optimized cubature force error on its poses"

# 2. the reduced run on the training scenario stays close to the full one
for n in all optimized; do
  crom-reducedstep --cubature cub_$n.h5 "${SC[@]}" -o red_$n.h5
  crom-info --check red_$n.h5 >/dev/null || fail "latent $n invalid"; ok
  err=$(crom-diff red_$n.h5 full.h5 --model pod.h5 -q | sed -n 's/relative displacement error \([0-9.e+-]*\) over.*/\1/p')
  echo "reduced ($n cubature) vs full: relative error $err"
  close "$err" 0 0.02 "reduced run with $n cubature vs crom-fullsim"
done
# through pipes, streamed: the same numbers as the file
crom-reducedstep --cubature cub_optimized.h5 "${SC[@]}" | crom-diff - full.h5 --model pod.h5 -q >pipe.txt
crom-diff red_optimized.h5 full.h5 --model pod.h5 -q >file.txt
cmp -s pipe.txt file.txt || fail "streamed and file latent runs differ"; ok

# 3. pinned vertices stay pinned: decoded bottom displacement and the reported residual
$PY - red_all.h5 pod.h5 box.h5 <<'PYEOF' || fail "pins"
import sys, h5py, numpy as np
r, p, b = (h5py.File(x) for x in sys.argv[1:])
B = p["field/basis"][()]; q = r["frames/q"][()]; bot = b["regions/bottom"][()]
u = np.einsum("vcr,fr->fvc", B[bot], q)
res = r["frames/constraint_residual"][()]
print("largest decoded pin displacement %.2e m, reported %.2e m" % (np.abs(u).max(), res.max()))
if not (np.abs(u).max() < 2e-4 and res.max() < 2e-4 and abs(np.linalg.norm(u, axis=2).max() - res.max()) < 1e-3):
    raise SystemExit("check failed: np.abs(u).max() < 2e-4 and res.max() < 2e-4 and abs(np.linalg.norm(u, axis=2).max() - res.max()) < 1e-3")
PYEOF
ok

# 4. crom-diff: a result against itself is 0; --max-error sets the exit status
crom-diff full.h5 full.h5 -q | grep -q "relative displacement error 0 over 17 frames" || fail "self diff"; ok
rc=0; crom-diff red_all.h5 full.h5 --model pod.h5 -q --max-error 1e-12 >/dev/null 2>&1 || rc=$?
[ $rc -eq 1 ] || fail "--max-error should exit 1, got $rc"; ok
crom-diff red_all.h5 full.h5 --model pod.h5 --csv diff.csv >/dev/null
[ "$(wc -l <diff.csv)" -eq 18 ] || fail "diff csv rows"; ok

# 5. a schedule switch to a punched mesh: q continuous, energy finite, and
#    the punched body moves differently from the intact one
crom-remesh punch --sphere 0,0,0,0.3 -o punched.h5 box.h5
crom-cubature --model pod.h5 --scheme metis --count 40 -o cub_punched.h5 punched.h5
printf '# switch to the punched mesh\n8 %s\n' cub_punched.h5 >sched.txt
crom-reducedstep --cubature cub_metis.h5 --schedule sched.txt "${SC[@]}" -o red_sched.h5
crom-reducedstep --cubature cub_metis.h5 "${SC[@]}" -o red_intact.h5
$PY - red_sched.h5 red_intact.h5 <<'PYEOF' || fail "schedule switch"
import sys, h5py, numpy as np
s, i = (h5py.File(x) for x in sys.argv[1:])
q = s["frames/q"][()]; cub = s["frames/cubature"][()]
if not (list(cub[:8]) == [0] * 8 and np.all(cub[8:] == 1)):
    raise SystemExit(f"check failed: {cub!s}")
dq = np.linalg.norm(np.diff(q, axis=0), axis=1)
# the switch happens before step 8: the jump into frame 8 is like its neighbours
if not (dq[7] < 3 * max(dq[6], dq[8]) + 1e-12):
    raise SystemExit(f"check failed: {dq!s}")
if not (np.all(np.isfinite(s["frames/total_energy"][()]))):
    raise SystemExit("check failed: np.all(np.isfinite(s[\"frames/total_energy\"][()]))")
# identical before the switch, different after
if not (np.array_equal(q[:8], i["frames/q"][:8])):
    raise SystemExit("check failed: np.array_equal(q[:8], i[\"frames/q\"][:8])")
d = np.linalg.norm(q[-1] - i["frames/q"][-1]) / np.linalg.norm(i["frames/q"][-1])
print("punched vs intact at the end: relative difference in q %.3f" % d)
if not (d > 0.01):
    raise SystemExit("check failed: d > 0.01")
PYEOF
ok

# 6. gd solver (LiCROM §5) runs the same scenario
crom-reducedstep --cubature cub_metis.h5 --solver gd --max-iter 30 "${SC[@]}" -o red_gd.h5
crom-info --check red_gd.h5 >/dev/null || fail "gd run"; ok

# 7. decoded export of a latent run onto the mesh (and onto a finer mesh)
crom-export --format pvd --model pod.h5 --mesh box.h5 -q -o pvd red_optimized.h5
crom-mesh box --size 0.1 -o fine.h5
crom-export --format vtu --model pod.h5 --mesh fine.h5 -o fine.vtu red_optimized.h5
$PY -c "
import meshio, numpy as np
m = meshio.read('pvd/frame_00016.vtu'); f = meshio.read('fine.vtu')
if not (np.abs(m.point_data['displacement']).max() > 0.05 and np.abs(f.point_data['displacement']).max() > 0.05): raise SystemExit('check failed: decoded displacement too small')
" || fail "decoded export"; ok

# 7. the reduced step's work does not grow with the mesh (LiCROM §4; issue
#    18): one field laid on two meshes of the box, 40 METIS cubature tets
#    on each: every evaluation decodes the same 160 vertex positions; a
#    collision plane adds each surface vertex, the one part that grows
crom-fitfield --rank 4 --epochs 30 -q -o mlp.h5 <samples.h5
crom-mesh box --size 0.1 --region top='y>0.45' --region bottom='y<-0.45' -q -o box_fine.h5
for m in box box_fine; do
  crom-cubature -q --model mlp.h5 --scheme metis --count 40 -o cm_$m.h5 $m.h5
  crom-reducedstep --cubature cm_$m.h5 "${SC[@]}" --steps 4 --stats w_$m.csv -o /dev/null
  crom-reducedstep --cubature cm_$m.h5 "${SC[@]}" --steps 4 --plane 0,1,0,-0.6 --stats wp_$m.csv -o /dev/null
done
$PY - <<'PYEOF' || fail "reduced step work against the mesh"
import h5py, numpy as np
from collections import Counter
def surface(path):
    t = h5py.File(path)["tets"][()]
    faces = Counter(tuple(sorted(f)) for tet in t for f in ((tet[0], tet[1], tet[2]), (tet[0], tet[1], tet[3]),
                                                             (tet[0], tet[2], tet[3]), (tet[1], tet[2], tet[3])))
    return len({v for f, c in faces.items() if c == 1 for v in f})
for m in ["box", "box_fine"]:
    w = np.genfromtxt(f"w_{m}.csv", delimiter=",", names=True)["vertex_evals"]
    wp = np.genfromtxt(f"wp_{m}.csv", delimiter=",", names=True)["vertex_evals"]
    ns = surface(f"{m}.h5")
    print(f"{m}: {w[0]:.0f} vertex positions per evaluation, {wp[0]:.0f} with a plane ({ns} surface vertices)")
    if not (np.all(w == 160) and np.all(wp == 160 + ns)):
        raise SystemExit(f"{m}: vertex_evals {w} and {wp}")
PYEOF
ok

# 8. bad input
O=out; mkdir -p $O
crom-mesh sphere --size 0.3 --region top='y>0.3' -o sph.h5
crom-fullsim --steps 3 --gravity 0,0,0 --velocity 'top=0,1,0' -o fs.h5 sph.h5
crom-sample --points all -o s2.h5 fs.h5
crom-fitfield --basis pod --rank 2 -q -o other.h5 <s2.h5
crom-cubature --model other.h5 --scheme all -o cub_other.h5 box.h5
printf '4 cub_other.h5\n' >sched_other.txt
expect_error 65 "is a cubature of model [0-9a-f]+, cub_metis.h5 is of model" $O/x.h5 -- crom-reducedstep --cubature cub_metis.h5 --schedule sched_other.txt "${SC[@]}" -o $O/x.h5
printf '4 nosuch.h5\n' >sched_missing.txt
expect_error 66 "nosuch.h5: No such file" $O/x.h5 -- crom-reducedstep --cubature cub_metis.h5 --schedule sched_missing.txt "${SC[@]}" -o $O/x.h5
printf '6 cub_punched.h5\n4 cub_metis.h5\n' >sched_order.txt
expect_error 64 "step 4 is out of order" $O/x.h5 -- crom-reducedstep --cubature cub_metis.h5 --schedule sched_order.txt "${SC[@]}" -o $O/x.h5
printf '99 cub_punched.h5\n' >sched_late.txt
expect_error 64 "step 99 is beyond --steps 16" $O/x.h5 -- crom-reducedstep --cubature cub_metis.h5 --schedule sched_late.txt "${SC[@]}" -o $O/x.h5
$PY - cub_metis.h5 empty.h5 <<'PYEOF'
import sys, h5py, shutil, numpy as np
shutil.copy(sys.argv[1], sys.argv[2])
with h5py.File(sys.argv[2], "r+") as f:
    for k in ("elements", "weights", "volume"):
        del f[k]; f.create_dataset(k, shape=(0,), dtype="i4" if k == "elements" else "f8")
    del f["Dminv"]; f.create_dataset("Dminv", shape=(0, 3, 3), dtype="f8")
PYEOF
expect_error 65 "the cubature is empty" $O/x.h5 -- crom-reducedstep --cubature empty.h5 "${SC[@]}" -o $O/x.h5
expect_error 65 "is crom/mesh v1, expected crom/cubature" $O/x.h5 -- crom-reducedstep --cubature box.h5 "${SC[@]}" -o $O/x.h5
expect_error 64 "cubature CUB is required" $O/x.h5 -- crom-reducedstep "${SC[@]}" -o $O/x.h5
expect_error 64 "unknown region 'lid'" $O/x.h5 -- crom-reducedstep --cubature cub_metis.h5 --pin lid -o $O/x.h5
expect_error 65 "holds poses of model" $O/c.h5 -- crom-cubature --model other.h5 --scheme optimized --poses poses.h5 -o $O/c.h5 box.h5
expect_error 64 "optimized needs --poses" $O/c.h5 -- crom-cubature --model pod.h5 --scheme optimized -o $O/c.h5 box.h5
expect_error 65 "is crom/samples v1, expected a crom/model|expected crom/model" $O/c.h5 -- crom-cubature --model samples.h5 -o $O/c.h5 box.h5
expect_error 65 "--init .* is a state of model" $O/x.h5 -- crom-reducedstep --cubature cub_other.h5 --init poses.h5 "${SC[@]}" -o $O/x.h5
expect_error 65 "holds coordinates of model" - -- crom-diff red_all.h5 full.h5 --model other.h5
expect_error 64 "needs --model and --mesh" - -- crom-diff red_all.h5 red_all.h5
done_checks
