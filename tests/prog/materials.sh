#!/usr/bin/env bash
# Regions of other materials (issue 19 item 1: --youngs REGION=E,
# --poisson REGION=NU) through the programs:
#   - crom-fullsim: a bar clamped at one end and pulled at the other, its far
#     half four times stiffer, stretches as two springs in series (on a gmsh
#     mesh whose interface is not a mesh plane: within what one element of
#     the soft material more allows; tests/unit/test_sim.c has the exact
#     interface, 0.5%), and less than the soft bar; the scenario attribute
#     keeps the regions;
#   - crom-reducedstep over a cubature of every tet, in the subspace of the
#     heterogeneous run's own POD basis, follows that run (relative error
#     below 1%), while the same reduced run without the region misses it by
#     far more (so the reduced path does use the region); crom-live the same;
#   - crom-export leaves out the cell fields that need one material;
#   - a region of another density sags the bar further, and the reduced run
#     in that run's subspace follows it (and misses it without the region);
#   - crom-modes: the two-material bar's frequencies lie between the soft and
#     the stiff bar's, one material by region is the uniform bar;
#   - the data-free maps of one mesh (energy, neural modes) train with them
#     and record them, and the energy map's reduced run responds less with
#     the stiff half than without;
#   - the Fig. 8 experiment (pipelines/hetero.mk) runs at a small size;
#   - the continuous objectives (skinning eigenmodes, fields) take them too;
#   - bad regions, bad values, and what takes one material (crom-fitfield on
#     samples, crom-metrics) refuse with one line.
# asan: skip (full, reduced and live runs of bars, 27 s under ASan; tests/unit/test_sim.c and test_fem.c cover the materials code there)
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
crom-mesh box --dims 1,0.1,0.1 --size 0.04 --region clamp='x<-0.499' --region tip='x>0.499' -q -o bar.h5
BASE=(--poisson 0 --youngs 1e7 --density 1000 --gravity 0,0,0 --pin clamp --force tip=100,0,0@0: --damping 20 --dt 0.01 --steps 150)
HET=(--youngs 'x>0=4e7')
crom-fullsim "${BASE[@]}" -q -o soft.h5 bar.h5
crom-fullsim "${BASE[@]}" "${HET[@]}" -q -o het.h5 bar.h5
# the tip's mean x-displacement at the last frame
tip() { $PY -c "
import h5py, numpy as np, sys
f = h5py.File(sys.argv[1], 'r'); X = f['mesh/vertices'][()]; u = f['frames/displacement'][-1]
print('%.6e' % u[X[:, 0] > 0.499, 0].mean())" "$1"; }
us=$(tip soft.h5); uh=$(tip het.h5)
# springs in series: F L1 / (E1 A) + F L2 / (E2 A) with A = 0.01 m^2
echo "tip: soft $us m (one spring 1.0e-3), two materials $uh m (series 6.25e-4)"
close "$us" 1.0e-3 3e-5 "the soft bar's extension"
# the tets that cross x = 0 are soft (not all four corners in x > 0): the soft
# half is longer by at most one element, h = 0.04 m, u(L) in
# [6.25e-4, 6.25e-4 + h (1e-3 - 2.5e-4)] = [6.25e-4, 6.55e-4]
awk -v u="$uh" 'BEGIN { exit !(u >= 6.2e-4 && u <= 6.55e-4) }' || fail "two materials: u(L) = $uh, not in [6.2e-4, 6.55e-4]"; ok
$PY -c "import h5py, sys; s = h5py.File('het.h5')['/'].attrs['scenario']; s = s.decode() if isinstance(s, bytes) else s; \
sys.exit(0 if '--youngs x>0=40000000' in s else 'scenario: ' + s)" || fail "the scenario attribute lost the region"; ok

# crom-export: cell fields of one material would misstate the stiff half's stress: left out, and said so
crom-export --format vtu -o het.vtu het.h5 2>export.err
! grep -q von_mises_stress het.vtu && grep -q "regions of other materials" export.err ||
  fail "crom-export on a run of two materials: $(cat export.err)"; ok

# ---- reduced: the heterogeneous run's own subspace, every tet
crom-sample --points all het.h5 -o s.h5 2>/dev/null
crom-fitfield --basis pod --rank 6 -q -o pod.h5 s.h5
crom-cubature --model pod.h5 --scheme all -q -o cub.h5 bar.h5
crom-reducedstep --cubature cub.h5 "${BASE[@]}" "${HET[@]}" -q -o red.h5
crom-reducedstep --cubature cub.h5 "${BASE[@]}" -q -o red1.h5
e=$(crom-diff red.h5 het.h5 --model pod.h5 | awk '/relative displacement error/ {print $4; exit}')
e1=$(crom-diff red1.h5 het.h5 --model pod.h5 | awk '/relative displacement error/ {print $4; exit}')
echo "reduced against full: $e with the region, $e1 without"
awk -v e="$e" -v e1="$e1" 'BEGIN { exit !(e + 0 < 0.01 && e1 + 0 > 10 * (e + 0)) }' ||
  fail "reduced run with regions: error $e (without them $e1)"; ok
printf 'step 150\n' | crom-live --cubature cub.h5 "${BASE[@]}" "${HET[@]}" --no-clock -q -o live.h5
$PY -c "
import h5py, numpy as np, sys
a, b = (h5py.File(f, 'r')['frames/q'][()] for f in ('live.h5', 'red.h5'))
sys.exit(0 if a.shape == b.shape and np.abs(a - b).max() <= 1e-12 * np.abs(b).max() else 'live differs')" ||
  fail "crom-live with regions differs from crom-reducedstep"; ok

# a region of another density (--density REGION=RHO): the far half four times
# as dense sags the clamped bar further under gravity; the reduced run in
# that run's POD subspace follows it (its reduced mass and gravity load
# summed from the vertices' masses), and misses it without the region
GBASE=(--poisson 0 --youngs 1e7 --density 1000 --gravity 0,-9.81,0 --pin clamp --damping 20 --dt 0.01 --steps 120)
DEN=(--density 'x>0=4000')
crom-fullsim "${GBASE[@]}" -q -o g1.h5 bar.h5
crom-fullsim "${GBASE[@]}" "${DEN[@]}" -q -o gd.h5 bar.h5
crom-sample --points all gd.h5 -o sd.h5 2>/dev/null
crom-fitfield --basis pod --rank 6 -q -o podd.h5 sd.h5
crom-cubature --model podd.h5 --scheme all -q -o cubd.h5 bar.h5
crom-reducedstep --cubature cubd.h5 "${GBASE[@]}" "${DEN[@]}" -q -o redd.h5
crom-reducedstep --cubature cubd.h5 "${GBASE[@]}" -q -o redd1.h5
e=$(crom-diff redd.h5 gd.h5 --model podd.h5 | awk '/relative displacement error/ {print $4; exit}')
e1=$(crom-diff redd1.h5 gd.h5 --model podd.h5 | awk '/relative displacement error/ {print $4; exit}')
$PY - <<'EOF2' || fail "the denser half does not sag the bar further"
import h5py
t = {}
for k in ("g1", "gd"):
    f = h5py.File(k + ".h5", "r")
    X = f["mesh/vertices"][()]
    t[k] = f["frames/displacement"][-1][X[:, 0] > 0.499, 1].mean()
print("tip sag: one density %.4g m, far half 4x as dense %.4g m" % (t["g1"], t["gd"]))
if not t["gd"] < 1.5 * t["g1"] < 0:
    raise SystemExit(str(t))
EOF2
ok
echo "reduced against full (two densities): $e with the region, $e1 without"
awk -v e="$e" -v e1="$e1" 'BEGIN { exit !(e + 0 < 0.01 && e1 + 0 > 10 * (e + 0)) }' ||
  fail "reduced run with a density region: error $e (without it $e1)"; ok

# (the modes and the data-free maps, like the experiment below, do not run
# under the sanitizers: minutes of ASan in eigensolves and training whose
# library paths test_sim and test_fem run there with regions)
if [ "${CROM_SANITIZE:-0}" != 1 ]; then
# ---- crom-modes: the clamped bar's first frequencies lie between those of the
# soft and the stiff bar; the soft material given by region to every tet is
# the soft bar to round-off; modal derivatives take the regions too
M=(--poisson 0 --density 1000 --pin clamp --count 3)
crom-modes "${M[@]}" --youngs 1e7 -q -o m1.h5 bar.h5
crom-modes "${M[@]}" --youngs 4e7 -q -o m4.h5 bar.h5
crom-modes "${M[@]}" --youngs 1e7 "${HET[@]}" -q -o mh.h5 bar.h5
crom-modes "${M[@]}" --youngs 4e7 --youngs 'x>-1=1e7' -q -o ma.h5 bar.h5
crom-modes "${M[@]}" --youngs 1e7 "${HET[@]}" --derivatives -q -o md.h5 bar.h5
$PY - <<'EOF2' || fail "crom-modes with regions"
import h5py, numpy as np, sys
f = {k: h5py.File(k + ".h5", "r")["frequencies"][()] for k in ("m1", "m4", "mh", "ma")}
print("first frequencies (Hz): soft %s, two materials %s, stiff %s" % (f["m1"][:3], f["mh"][:3], f["m4"][:3]))
if not (np.all(f["m1"] < f["mh"]) and np.all(f["mh"] < f["m4"])):
    sys.exit("two materials: not between the soft and the stiff bar")
if np.abs(f["ma"] - f["m1"]).max() > 1e-9 * f["m1"].max():
    sys.exit("the soft material by region differs from the soft bar: %s %s" % (f["ma"], f["m1"]))
EOF2
ok

# ---- data-free maps of the body (energy; neural modes over the modes above):
# they train with the regions and record them; the energy map's reduced run
# (crom_nlsim) with the stiff half responds less than without it
crom-fitfield --objective energy --mesh bar.h5 --poisson 0 --youngs 1e7 "${HET[@]}" --pin clamp --rank 4 --steps 300 \
  -q -o map.h5
crom-fitfield --objective neuralmodes --mesh bar.h5 --modes mh.h5 --poisson 0 --youngs 1e7 "${HET[@]}" --pin clamp \
  --rank 3 --steps 100 -q -o nm.h5
for f in map nm; do
  $PY -c "import h5py, sys; s = h5py.File('$f.h5')['/'].attrs['scenario']; s = s.decode() if isinstance(s, bytes) else s; \
sys.exit(0 if '--youngs x>0=40000000' in s else 'scenario: ' + s)" || fail "$f.h5 does not record the region"
done; ok
NL=(--poisson 0 --youngs 1e7 --density 1000 --gravity 0,0,0 --pin clamp --force tip=100,0,0@0: --damping 20 --dt 0.01 --steps 100)
crom-reducedstep --model map.h5 --mesh bar.h5 "${NL[@]}" "${HET[@]}" -q -o nlh.h5
crom-reducedstep --model map.h5 --mesh bar.h5 "${NL[@]}" -q -o nl1.h5
$PY -c "
import h5py, numpy as np, sys
a, b = (np.linalg.norm(h5py.File(f, 'r')['frames/q'][-1]) for f in ('nlh.h5', 'nl1.h5'))
print('energy map, reduced: |q| %.4g with the stiff half, %.4g without' % (a, b))
sys.exit(0 if a < 0.9 * b else 'the stiff half did not stiffen the reduced run')" || fail "crom_nlsim with regions"; ok
fi

# ---- the continuous objectives: the skinning eigenvalues of the two-material
# bar lie between the soft and the stiff bar's (49.3K, 55.5K, 197K 1/s^2 for
# the lowest), and a trained field records the region
crom-fitfield --objective skinning --weights eigen --mesh bar.h5 --poisson 0 --youngs 1e7 "${HET[@]}" --pin clamp \
  --handles 3 -q -o skh.h5
crom-fitfield --objective skinning --weights eigen --mesh bar.h5 --poisson 0 --youngs 1e7 --pin clamp --handles 3 -q -o sk1.h5
crom-fitfield --objective skinning --weights eigen --mesh bar.h5 --poisson 0 --youngs 4e7 --pin clamp --handles 3 -q -o sk4.h5
$PY - <<'EOF2' || fail "skinning eigenmodes with regions"
import h5py, numpy as np, sys
e = {k: h5py.File(k + ".h5", "r")["skin/eigenvalues"][()] for k in ("sk1", "skh", "sk4")}
print("skinning eigenvalues (1/s^2): soft %s, two materials %s, stiff %s" % (e["sk1"], e["skh"], e["sk4"]))
s = h5py.File("skh.h5", "r").attrs["scenario"]
s = s.decode() if isinstance(s, bytes) else s
if not (np.all(e["sk1"] < e["skh"]) and np.all(e["skh"] < e["sk4"]) and "--youngs x>0=40000000" in s):
    sys.exit("not between; scenario %r" % s)
EOF2
ok
crom-fitfield --objective field --mesh bar.h5 --poisson 0 --youngs 1e7 "${HET[@]}" --pin clamp --rank 2 --steps 20 \
  --features 4 --tets 32 -q -o fh.h5
$PY -c "import h5py, sys; s = h5py.File('fh.h5')['/'].attrs['scenario']; s = s.decode() if isinstance(s, bytes) else s; \
sys.exit(0 if '--youngs x>0=40000000' in s else 'scenario: ' + s)" || fail "fh.h5 does not record the region"; ok

# ---- the experiment (pipelines/hetero.mk, Sharp Fig. 8) at a small size:
# every subspace's reduced run comes to rest (the maps' too: crom_nlsim with
# regions) and the table has its four rows; modal derivatives hold the
# large static deflection better than the linear modes they extend. Not
# under the sanitizers (training; its programs run above).
if [ "${CROM_SANITIZE:-0}" != 1 ]; then
  make -s -f "$CROM_TOP/pipelines/hetero.mk" OUT="$TMP/het" SIZE=0.1 R=4 DMODES=2 TMINUTES=0.03 QUIET=-q \
    BINDIR="$CROM_BINDIR" >het.txt 2>het.err || fail "hetero.mk: $(cat het.err)"
  cat het.txt
  [ "$(grep -c '^| [lmdn]' het.txt)" -eq 4 ] || fail "hetero.mk: the table lacks rows"
  $PY - het.txt <<'EOF2' || fail "hetero.mk: modal derivatives not better than the modes"
import sys
rows = {l.split("|")[1].strip(): float(l.split("|")[4]) for l in open(sys.argv[1])
        if l.startswith("| ") and "---" not in l and "subspace" not in l}
sys.exit(0 if rows["modes + modal derivatives"] < rows["linear modes"] else str(rows))
EOF2
  ok
fi

# ---- bad input
expect_error 64 "region 'nowhere'|unknown region" - -- crom-fullsim "${BASE[@]}" --youngs nowhere=1e7 -o x.h5 bar.h5
expect_error 64 "--youngs x>0=: a positive modulus" - -- crom-fullsim "${BASE[@]}" --youngs 'x>0=-1' -o x.h5 bar.h5
expect_error 64 "--poisson x>0=: must be in" - -- crom-fullsim "${BASE[@]}" --poisson 'x>0=0.5' -o x.h5 bar.h5
expect_error 64 "holds no whole tet" - -- crom-fullsim "${BASE[@]}" --youngs 'tip=2e7' -o x.h5 bar.h5
expect_error 64 "crom-fitfield on samples takes one material" - -- crom-fitfield --youngs 'x>0=2e7' --rank 2 -o x.h5 s.h5
crom-mesh sheet --size 0.1 -q -o sheet.h5
expect_error 64 "for tet meshes" - -- crom-fullsim --youngs 'x>0=2e7' --steps 1 -o x.h5 sheet.h5
done_checks
