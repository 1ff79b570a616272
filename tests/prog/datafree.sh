#!/usr/bin/env bash
# Data-free subspaces end to end: crom-fitfield --objective energy|neuralmodes
# (valid models that record what they were trained on, pins built in,
# reproducible bytes whatever --threads), crom-metrics (energy below the
# linear modes at the same displacements, no collapsed dimension),
# crom-reducedstep --model (valid latent runs that dissipate energy; over a
# cubature of the map's features it follows the run over every tet; a linear
# basis through --model is the cubature run), decoding with crom-export and
# crom-diff on the model's own mesh only; the continuous field
# (--objective field) on another mesh; neural modes sampled along a run
# (--latents) holding a sag outside their box; and bad input.
# asan: skip (minutes of training under ASan; tests/unit/test_datafree.c covers the same library code there)
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
crom-mesh box --dims 1,0.2,0.2 --size 0.1 --region clamp='x<-0.49' --region tip='x>0.49' -o bar.h5
MAT=(--youngs 1e6 --poisson 0.3 --density 1000)
TRAIN=(--steps 1000 --batch 16 --width 32)
crom-modes "${MAT[@]}" --pin clamp --count 3 -q -o modes.h5 bar.h5

# 1. an energy map of the clamped bar under gravity (Sharp et al.)
crom-fitfield --objective energy --mesh bar.h5 "${MAT[@]}" --pin clamp --rank 2 "${TRAIN[@]}" -o df.h5 2>df.log
cat df.log
crom-info --check df.h5 >/dev/null || fail "crom-info --check df.h5"; ok
grep -q "crom-fitfield: energy map, rank 2 on 110 vertices (12 pinned): 1000 steps" df.log || fail "summary line"; ok
$PY - df.h5 bar.h5 <<'PYEOF' || fail "energy model"
import sys, h5py, numpy as np
f, b = h5py.File(sys.argv[1]), h5py.File(sys.argv[2])
s = lambda v: v.decode() if isinstance(v, bytes) else v
if not (s(f.attrs["basis"]) == "energy" and f.attrs["rank"] == 2 and s(f.attrs["encoder"]) == "none"):
    raise SystemExit("check failed: s(f.attrs[\"basis\"]) == \"energy\" and f.attrs[\"rank\"] == 2 and s(f.attrs[\"encoder\"]) == \"none\"")
if not (s(f.attrs["activation"]) == "elu" and f.attrs["training_steps"] == 1000):
    raise SystemExit("check failed: s(f.attrs[\"activation\"]) == \"elu\" and f.attrs[\"training_steps\"] == 1000")
sc = s(f.attrs["scenario"])
if not ("--youngs 1000000" in sc and "--pin clamp" in sc and "--gravity 0,-9.81" in sc):
    raise SystemExit(f"check failed: {sc!s}")
if not (np.allclose(f.attrs["gravity"], [0, -9.81, 0]) and f.attrs["isometry_weight"] == 0.03):
    raise SystemExit("check failed: np.allclose(f.attrs[\"gravity\"], [0, -9.81, 0]) and f.attrs[\"isometry_weight\"] == 0.03")
if not (abs(f.attrs["sigma"] - 0.05 * np.sqrt(1 + 0.04 + 0.04)) < 1e-12):  # default: 5% of the diagonal
    raise SystemExit("check failed: abs(f.attrs[\"sigma\"] - 0.05 * np.sqrt(1 + 0.04 + 0.04)) < 1e-12")
if not (abs(f.attrs["mass"] - 40) < 1e-9):
    raise SystemExit("check failed: abs(f.attrs[\"mass\"] - 40) < 1e-9")
w = f["field/widths"][()]
if not (list(w) == [2, 32, 32, 32, 32, 32, 330]):
    raise SystemExit(f"check failed: {w!s}")
if not (np.array_equal(f["field/mesh/vertices"][()], b["vertices"][()])):
    raise SystemExit("check failed: np.array_equal(f[\"field/mesh/vertices\"][()], b[\"vertices\"][()])")
if not (np.array_equal(f["field/mesh/regions/clamp"][()], b["regions/clamp"][()])):
    raise SystemExit("check failed: np.array_equal(f[\"field/mesh/regions/clamp\"][()], b[\"regions/clamp\"][()])")
if not (len(f["training/objective"]) == 100 and "field/basis" not in f):
    raise SystemExit("check failed: len(f[\"training/objective\"]) == 100 and \"field/basis\" not in f")
# the last layer: pinned vertices' rows are exactly zero
p = f["field/params"][()]; n = 330; h = 32
Wl = p[-(n * h + n):-n].reshape(n, h); bl = p[-n:]
pin = b["regions/clamp"][()]
dofs = np.concatenate([3 * pin + c for c in range(3)])
if not (np.all(Wl[dofs] == 0) and np.all(bl[dofs] == 0)):
    raise SystemExit("check failed: np.all(Wl[dofs] == 0) and np.all(bl[dofs] == 0)")
obj = f["training/objective"][()]
print("energy map: objective %.4g -> %.4g over the run" % (obj[0], obj[-1]))
if not (obj[-1] < obj[0]):
    raise SystemExit("check failed: obj[-1] < obj[0]")
PYEOF
ok
# the same bytes again (the same command line: it is in the history), the
# same model with 2 threads, and with the mesh through a pipe
QUICK=(--objective energy "${MAT[@]}" --pin clamp --rank 2 --steps 40 --batch 8 --width 16)
crom-fitfield "${QUICK[@]}" --mesh bar.h5 -q >df1.h5
crom-fitfield "${QUICK[@]}" --mesh bar.h5 -q >df2.h5
crom-fitfield "${QUICK[@]}" --mesh - --threads 2 -q <bar.h5 >df3.h5
cmp -s df1.h5 df2.h5 || fail "same inputs and seed, different bytes"; ok
$PY -c "
import h5py, numpy as np
a, b = h5py.File('df1.h5'), h5py.File('df3.h5')
if not (a.attrs['model_id'] == b.attrs['model_id'] and np.array_equal(a['field/params'][()], b['field/params'][()])): raise SystemExit('check failed: model differs')" \
  || fail "--threads 2 or a piped mesh changed the model"; ok
crom-fitfield "${QUICK[@]}" --mesh bar.h5 --seed 2 -q >df4.h5
! cmp -s df1.h5 df4.h5 || fail "--seed has no effect"; ok

# metrics: samples of the energy map have much less elastic energy than the
# linear modes at the same RMS displacements (measured ratio 0.27), it is
# nearly isometric, and no dimension collapsed
crom-metrics --compare modes.h5 --samples 128 df.h5 >met_df.txt
cat met_df.txt
ratio=$(sed -n 's/^compare: .* ratio \([0-9.e+-]*\)$/\1/p' met_df.txt)
$PY -c "import sys; sys.exit(0 if 0 < $ratio < 0.5 else 1)" || fail "energy map vs linear modes: ratio $ratio"; ok
grep -q "^collapse: 0 of 2 dimensions below 0.01" met_df.txt || fail "energy map collapsed"; ok
med=$(sed -n 's/^isometry: .* median \([0-9.e+-]*\),.*/\1/p' met_df.txt)
close "$med" 1 0.1 "median isometry ratio of the energy map"
grep -q "material: E 1e+06 Pa, nu 0.3, rho 1000 kg/m^3 (recorded in the model); gravity 0,-9.81,0" met_df.txt \
  || fail "metrics material"; ok

# 2. Neural Modes on the 3 modes (Wang et al.)
crom-fitfield --objective neuralmodes --mesh bar.h5 --modes modes.h5 "${TRAIN[@]}" -o nm.h5 2>nm.log
cat nm.log
crom-info --check nm.h5 >/dev/null || fail "crom-info --check nm.h5"; ok
$PY - nm.h5 modes.h5 <<'PYEOF' || fail "neuralmodes model"
import sys, h5py, numpy as np
f, m = h5py.File(sys.argv[1]), h5py.File(sys.argv[2])
s = lambda v: v.decode() if isinstance(v, bytes) else v
if not (s(f.attrs["basis"]) == "neuralmodes" and f.attrs["rank"] == 3 and s(f.attrs["activation"]) == "gelu"):
    raise SystemExit("check failed: s(f.attrs[\"basis\"]) == \"neuralmodes\" and f.attrs[\"rank\"] == 3 and s(f.attrs[\"activation\"]) == \"gelu\"")
if not (s(f.attrs["modes_id"]) == s(m.attrs["model_id"])):
    raise SystemExit("check failed: s(f.attrs[\"modes_id\"]) == s(m.attrs[\"model_id\"])")
if not (np.array_equal(f["field/basis"][()], m["field/basis"][()])):
    raise SystemExit("check failed: np.array_equal(f[\"field/basis\"][()], m[\"field/basis\"][()])")
if not (np.array_equal(f["frequencies"][()], m["frequencies"][()])):
    raise SystemExit("check failed: np.array_equal(f[\"frequencies\"][()], m[\"frequencies\"][()])")
if not (f.attrs["youngs"] == 1e6 and f.attrs["poisson"] == 0.3):  # the material of the modes
    raise SystemExit("check failed: f.attrs[\"youngs\"] == 1e6 and f.attrs[\"poisson\"] == 0.3")
if not ("--pin clamp" in s(f.attrs["scenario"]) and "gravity" not in s(f.attrs["scenario"])):
    raise SystemExit("check failed: \"--pin clamp\" in s(f.attrs[\"scenario\"]) and \"gravity\" not in s(f.attrs[\"scenario\"])")
if not (abs(f.attrs["latent_box"] - 0.2 * np.sqrt(1.08)) < 1e-12):
    raise SystemExit("check failed: abs(f.attrs[\"latent_box\"] - 0.2 * np.sqrt(1.08)) < 1e-12")
if not (s(f.attrs["latent_box_scaling"]) == "frequency"):
    raise SystemExit("check failed: s(f.attrs[\"latent_box_scaling\"]) == \"frequency\"")
PYEOF
ok
# no collapsed dimension (Wang et al. §4.4): J = W + dy/dz at 0 with y
# M-orthogonal to W, so r J^T M J / tr stays far from 0 (measured 0.79 after
# these 300 steps; the paper's collapsed dimensions are 0.0)
crom-metrics --compare modes.h5 --samples 128 nm.h5 >met_nm.txt
cat met_nm.txt
grep -q "^samples: 128, q in the box .*A f_1/f_k for mode k (the training box)" met_nm.txt \
  || fail "crom-metrics does not sample neural modes from their training box"; ok
# a box scaling the readers do not know is refused, not taken for uniform
cp nm.h5 nm_badbox.h5
$PY -c "import h5py, sys; h5py.File(sys.argv[1], 'r+').attrs['latent_box_scaling'] = 'log'" nm_badbox.h5
expect_error 65 "unknown latent_box_scaling 'log' \(frequency or uniform\)" - -- crom-metrics --samples 8 nm_badbox.h5
low=$(sed -n 's/^collapse: 0 of 3 dimensions below 0.01 (smallest normalized eigenvalue \([0-9.e+-]*\);.*/\1/p' met_nm.txt)
[ -n "$low" ] || fail "neuralmodes collapsed: $(grep collapse met_nm.txt)"
$PY -c "import sys; sys.exit(0 if $low > 0.5 else 1)" || fail "smallest normalized Gram eigenvalue $low <= 0.5"; ok
# the linear modes themselves: M-orthonormal, all eigenvalues 1
crom-metrics --sphere 0.05 modes.h5 | grep -q "^gram_eigenvalues: 1 1 1$" || fail "modes Gram eigenvalues"; ok

# 3. latent dynamics: a clamped bar under gravity in both maps
SC=(--pin clamp --dt 0.01 --steps 30 --gravity 0,-9.81,0)
for m in df nm; do
  crom-reducedstep --model $m.h5 "${MAT[@]}" "${SC[@]}" -v -o run_$m.h5 2>run_$m.log
  cat run_$m.log
  crom-info --check run_$m.h5 >/dev/null || fail "latent $m invalid"; ok
  $PY - run_$m.h5 $m.h5 <<'PYEOF' || fail "run $m"
import sys, h5py, numpy as np
r, f = h5py.File(sys.argv[1]), h5py.File(sys.argv[2])
s = lambda v: v.decode() if isinstance(v, bytes) else v
if not (s(r.attrs["model_id"]) == s(f.attrs["model_id"]) and r.attrs["rank"] == f.attrs["rank"]):
    raise SystemExit("check failed: s(r.attrs[\"model_id\"]) == s(f.attrs[\"model_id\"]) and r.attrs[\"rank\"] == f.attrs[\"rank\"]")
if not (s(r.attrs["solver"]) == "gauss-newton"):
    raise SystemExit("check failed: s(r.attrs[\"solver\"]) == \"gauss-newton\"")
T = r["frames/total_energy"][()]; K = r["frames/kinetic_energy"][()]
scale = np.abs(r["frames/elastic_energy"][()]).max() + np.abs(r["frames/external_energy"][()]).max()
rise = np.diff(T).max()
print("%s: total energy %.4g -> %.4g J, largest rise %.3g J (scale %.4g J), largest kinetic energy %.4g J, %.2f iterations/step"
      % (sys.argv[1], T[0], T[-1], rise, scale, K.max(), r["frames/iterations"][1:].mean()))
if not (np.all(np.isfinite(r["frames/q"][()])) and K.max() > 1e-3 * scale):
    raise SystemExit("check failed: np.all(np.isfinite(r[\"frames/q\"][()])) and K.max() > 1e-3 * scale")
if not (rise <= 1e-6 * scale):
    raise SystemExit("check failed: rise <= 1e-6 * scale")
if not (r["frames/constraint_residual"][()].max() == 0):  # the pins are built into the map
    raise SystemExit("check failed: r[\"frames/constraint_residual\"][()].max() == 0")
PYEOF
  ok
done
# the same run streamed through a pipe
crom-reducedstep --model df.h5 "${MAT[@]}" "${SC[@]}" | crom-diff - run_df.h5 --model df.h5 -q \
  | grep -q "relative displacement error 0 over 31 frames" || fail "streamed run differs"; ok

# a cubature of the energy map (its features), no data: latent samples of
# its training distribution; the run over its tets follows the run over
# every tet
crom-cubature --model df.h5 --scheme optimized --count 60 --tol 0.002 -v -o dfcub.h5 2>dfcub.log
cat dfcub.log
crom-info --check dfcub.h5 >/dev/null || fail "map cubature invalid"; ok
grep -q "poses: 100 latent samples of the model's training distribution" dfcub.log || fail "map cubature poses"; ok
$PY - dfcub.h5 df.h5 <<'PYEOF' || fail "map cubature contents"
import sys, h5py
c, f = h5py.File(sys.argv[1]), h5py.File(sys.argv[2])
if not (c.attrs["model_id"] == f.attrs["model_id"] and c.attrs["map_rank"] == 2):
    raise SystemExit("check failed: c.attrs[\"model_id\"] == f.attrs[\"model_id\"] and c.attrs[\"map_rank\"] == 2")
if not (c.attrs["rank"] == 32 + 1 and c["W"].shape == (110, 3, 33)):  # features: last hidden layer + 1
    raise SystemExit("check failed: c.attrs[\"rank\"] == 32 + 1 and c[\"W\"].shape == (110, 3, 33)")
if not (0 < c.attrs["count"] < 254):
    raise SystemExit("check failed: 0 < c.attrs[\"count\"] < 254")
PYEOF
ok
crom-reducedstep --model df.h5 --cubature dfcub.h5 "${MAT[@]}" "${SC[@]}" --stats run_dfc.csv -q -o run_dfc.h5
e=$(crom-diff run_dfc.h5 run_df.h5 --model df.h5 -q | sed -n 's/relative displacement error \([0-9.e+-]*\) over.*/\1/p')
echo "energy map: cubature run vs every tet: relative displacement error $e"
close "$e" 0 0.05 "map cubature run vs every tet"
k=$(sed -n 2p run_dfc.csv | cut -d, -f6)
[ "$k" -lt 254 ] || fail "the cubature run integrated $k tets"; ok

# a linear basis through --model is the cubature run (same Newton steps)
crom-cubature --model modes.h5 --scheme all -q -o cub.h5 bar.h5
crom-reducedstep --cubature cub.h5 "${MAT[@]}" "${SC[@]}" --tol 1e-10 -q -o lin_cub.h5
crom-reducedstep --model modes.h5 --mesh bar.h5 "${MAT[@]}" "${SC[@]}" --tol 1e-10 -q -o lin_map.h5
e=$(crom-diff lin_map.h5 lin_cub.h5 --model modes.h5 --mesh bar.h5 -q | sed -n 's/relative displacement error \([0-9.e+-]*\) over.*/\1/p')
echo "modes through --model vs through a cubature of every tet: $e"
close "$e" 0 1e-9 "linear basis: --model vs --cubature"

# 4. decoding on the model's own mesh: export needs no --mesh, accepts the
#    same mesh, and a full run of the same mesh compares
crom-export --format vtu --model df.h5 -o df_last.vtu run_df.h5
crom-export --format vtu --model df.h5 --mesh bar.h5 -o df_last2.vtu run_df.h5
cmp -s df_last.vtu df_last2.vtu || fail "export with and without --mesh differ"; ok
$PY - df_last.vtu run_df.h5 df.h5 <<'PYEOF' || fail "decoded displacement"
import sys, meshio, h5py, numpy as np
v = meshio.read(sys.argv[1]); r = h5py.File(sys.argv[2]); f = h5py.File(sys.argv[3])
u = v.point_data["displacement"]; pin = f["field/mesh/regions/clamp"][()]
if not (np.abs(u[pin]).max() == 0 and np.abs(u).max() > 0.01):
    raise SystemExit("check failed: np.abs(u[pin]).max() == 0 and np.abs(u).max() > 0.01")
print("decoded last frame: tip displacement", u[np.argmax(v.points[:, 0])])
PYEOF
ok
crom-fullsim "${MAT[@]}" "${SC[@]}" -q -o full.h5 bar.h5
crom-diff run_nm.h5 full.h5 --model nm.h5 -q | grep -q "over 31 frames" || fail "diff against a full run"; ok

# 5. a continuous data-free field (--objective field): trained on bar.h5,
#    laid on a finer mesh of the same bar, cubature and latent run there,
#    exported and compared with a full run on that mesh
crom-mesh box --dims 1,0.2,0.2 --size 0.07 --region clamp='x<-0.49' -o fine.h5
crom-fitfield --objective field --mesh bar.h5 "${MAT[@]}" --pin clamp --rank 2 --steps 400 --batch 16 --width 32 \
  --features 8 --tets 127 -o fld.h5 2>fld.log
cat fld.log
crom-info --check fld.h5 >/dev/null || fail "crom-info --check fld.h5"; ok
$PY - fld.h5 <<'PYEOF' || fail "field model"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1])
s = lambda v: v.decode() if isinstance(v, bytes) else v
if not (s(f.attrs["basis"]) == "energy-field" and f.attrs["rank"] == 2 and f.attrs["cubature_tets"] == 127):
    raise SystemExit("check failed: s(f.attrs[\"basis\"]) == \"energy-field\" and f.attrs[\"rank\"] == 2 and f.attrs[\"cubature_tets\"] == 127")
if not (list(f["field/widths"][()]) == [3, 64, 64, 64, 24] and list(f["latent/widths"][()]) == [2, 32, 32, 32, 8]):
    raise SystemExit("check failed: list(f[\"field/widths\"][()]) == [3, 64, 64, 64, 24] and list(f[\"latent/widths\"][()]) == [2, 32, 32, 32, 8]")
t = f["latent/pin_triangles"][()]
if not (t.shape[1:] == (3, 3) and len(t) > 0 and np.all(t[:, :, 0] < -0.49)):  # the clamped face
    raise SystemExit("check failed: t.shape[1:] == (3, 3) and len(t) > 0 and np.all(t[:, :, 0] < -0.49)")
if not (f["latent/pin_length"][0] > 0 and "field/mesh" not in f):
    raise SystemExit("check failed: f[\"latent/pin_length\"][0] > 0 and \"field/mesh\" not in f")
PYEOF
ok
crom-metrics --mesh bar.h5 fld.h5 >met_fld.txt
crom-metrics --mesh fine.h5 fld.h5 >met_fld_fine.txt
cat met_fld.txt met_fld_fine.txt
e1=$(sed -n 's/^elastic_energy: mean \([0-9.e+-]*\) J.*/\1/p' met_fld.txt)
e2=$(sed -n 's/^elastic_energy: mean \([0-9.e+-]*\) J.*/\1/p' met_fld_fine.txt)
echo "continuous field: mean elastic energy of the same latent samples $e1 J (training mesh), $e2 J (finer mesh)"
close "$e2" "$e1" "$($PY -c "print(0.15 * $e1)")" "the field's energy on another mesh (15%)"
grep -q "^collapse: 0 of 2 dimensions" met_fld.txt || fail "field collapsed"; ok
crom-cubature --model fld.h5 --scheme optimized --count 80 -q -o fldcub.h5 fine.h5
crom-reducedstep --model fld.h5 --mesh fine.h5 --cubature fldcub.h5 "${MAT[@]}" "${SC[@]}" -v -o run_fld.h5 2>run_fld.log
cat run_fld.log
$PY - run_fld.h5 <<'PYEOF' || fail "field run"
import sys, h5py, numpy as np
r = h5py.File(sys.argv[1])
T = r["frames/total_energy"][()]; K = r["frames/kinetic_energy"][()]
scale = np.abs(r["frames/elastic_energy"][()]).max() + np.abs(r["frames/external_energy"][()]).max()
print("field on fine.h5: largest rise of the total energy %.3g J (scale %.4g J), largest kinetic energy %.4g J"
      % (np.diff(T).max(), scale, K.max()))
if not (K.max() > 1e-3 * scale and np.diff(T).max() <= 1e-6 * scale):
    raise SystemExit("check failed: K.max() > 1e-3 * scale and np.diff(T).max() <= 1e-6 * scale")
if not (r["frames/constraint_residual"][()].max() == 0):  # the mask holds the clamped face on this mesh too
    raise SystemExit("check failed: r[\"frames/constraint_residual\"][()].max() == 0")
PYEOF
ok
crom-export --format vtu --model fld.h5 --mesh fine.h5 -o fld_last.vtu run_fld.h5
$PY - fld_last.vtu <<'PYEOF' || fail "field export"
import sys, meshio, numpy as np
v = meshio.read(sys.argv[1]); u = v.point_data["displacement"]
clamp = v.points[:, 0] < -0.49
if not (np.abs(u[clamp]).max() == 0 and u[:, 1].min() < -0.005 and len(v.points) > 300):
    raise SystemExit("check failed: np.abs(u[clamp]).max() == 0 and u[:, 1].min() < -0.005 and len(v.points) > 300")
PYEOF
ok
crom-fullsim "${MAT[@]}" "${SC[@]}" -q -o full_fine.h5 fine.h5
crom-diff run_fld.h5 full_fine.h5 --model fld.h5 --mesh fine.h5 -q | tee diff_fld.txt | grep -q "over 31 frames" \
  || fail "diff of the field run"; ok
cat diff_fld.txt

# 6. rest is exact, and the first step from rest follows crom-fullsim: one
#    map of each kind at rank 8 (the linear modes need 8 here to follow the
#    first step within 10%: 45% at rank 4, 16% at 6, 7% at 8). With no load
#    a run stays at rest to round-off; under gravity the displacement after
#    the first step is within 10% of the full one (crom-diff, frame 1). The
#    energy map's collapse floor at rest (the default --tangent-weight 0.03)
#    keeps every latent direction moving at rest: 5.9-6.6% over seeds 1-3
#    (with the conformal isometry at rest it replaced, 14%)
crom-modes "${MAT[@]}" --pin clamp --count 8 -q -o modes8.h5 bar.h5
R8=(--rank 8 --steps 1000 --batch 16 --width 32)
crom-fitfield --objective energy --mesh bar.h5 "${MAT[@]}" --pin clamp "${R8[@]}" -q -o e8.h5
crom-fitfield --objective neuralmodes --mesh bar.h5 --modes modes8.h5 "${R8[@]}" -q -o n8.h5
crom-fitfield --objective field --mesh bar.h5 "${MAT[@]}" --pin clamp "${R8[@]}" --features 16 --tets 127 \
  --pin-length 0.1 -q -o f8.h5   # the default mask, twice the mean edge (0.2 m on this coarse bar), holds
                                 # the first 20% of the bar nearly still: 11% off (7% with 0.1 m)
crom-fullsim "${MAT[@]}" --pin clamp --dt 0.01 --steps 2 -q -o full_first.h5 bar.h5
crom-fullsim "${MAT[@]}" --pin clamp --dt 0.01 --steps 20 --gravity 0,0,0 -q -o full_rest.h5 bar.h5
for m in e8 n8 f8; do
  M=(--model $m.h5 --mesh bar.h5)
  crom-reducedstep "${M[@]}" "${MAT[@]}" --pin clamp --dt 0.01 --steps 20 --gravity 0,0,0 -q -o rest_$m.h5
  crom-diff rest_$m.h5 full_rest.h5 "${M[@]}" >rest_$m.txt
  worst=$(awk 'NR > 1 && $1 ~ /^[0-9]+$/ { if ($4 > w) w = $4 } END { printf "%.3g", w + 0 }' rest_$m.txt)
  echo "$m: no load, 20 steps: largest vertex displacement $worst m"
  $PY -c "import sys; sys.exit(0 if $worst < 1e-12 else 1)" || fail "$m moved $worst m with no load"; ok
  crom-reducedstep "${M[@]}" "${MAT[@]}" --pin clamp --dt 0.01 --steps 2 -q -o first_$m.h5
  e1=$(crom-diff first_$m.h5 full_first.h5 "${M[@]}" | awk '$1 == 1 { print $3 }')
  echo "$m: first step under gravity, relative displacement error $e1 against crom-fullsim"
  $PY -c "import sys; sys.exit(0 if $e1 < 0.1 else 1)" || fail "$m: first step $e1 off"; ok
done

# the collapse floor holds every direction of the rank-8 energy map at rest:
# crom-metrics counts none below 0.01 of the mean, and the smallest sits near
# the floor 0.03 (0.029 here; without the floor, --tangent-weight 0, this run
# leaves 2 of 8 below 0.01, the smallest at 7e-6)
crom-metrics --mesh bar.h5 --samples 16 e8.h5 >metrics_e8.txt
grep collapse metrics_e8.txt
small=$(sed -n 's/.*smallest normalized eigenvalue \([^;]*\);.*/\1/p' metrics_e8.txt)
grep -q '^collapse: 0 of 8 ' metrics_e8.txt || fail "the energy map collapsed: $(grep collapse metrics_e8.txt)"
$PY -c "import sys; sys.exit(0 if $small > 0.02 else 1)" || fail "smallest normalized Gram eigenvalue $small"; ok

# the static sag (the same load heavily damped to rest) at rank 4 with the
# default training (4000 steps): the linear modes miss it by 57% (they
# cannot rotate); the energy map and the neural modes must come within 25%
# (measured 14% and 2%; other seeds of the energy map: 19-22%)
ST=(--pin clamp --gravity 0,-9.81,0 --dt 0.02 --steps 100 --damping 30)
crom-fullsim "${MAT[@]}" "${ST[@]}" -q -o sfull.h5 bar.h5
crom-modes "${MAT[@]}" --pin clamp --count 4 -q -o modes4.h5 bar.h5
crom-fitfield --objective energy --mesh bar.h5 "${MAT[@]}" --pin clamp --rank 4 -q -o se4.h5
crom-fitfield --objective neuralmodes --mesh bar.h5 --modes modes4.h5 -q -o sn4.h5
for m in modes4 se4 sn4; do
  crom-reducedstep --model $m.h5 --mesh bar.h5 "${MAT[@]}" "${ST[@]}" -q -o sag_$m.h5
  e=$(crom-diff sag_$m.h5 sfull.h5 --model $m.h5 --mesh bar.h5 | awk '$1 == 100 { print $3 }')
  echo "$m: static sag error $e"
  if [ $m = modes4 ]; then
    $PY -c "import sys; sys.exit(0 if $e > 0.4 else 1)" || fail "the linear modes hold the sag ($e): no test"; ok
  else
    $PY -c "import sys; sys.exit(0 if $e < 0.25 else 1)" || fail "$m: static sag $e off"; ok
  fi
done

# sampling along a run (crom-fitfield --latents): a soft bar (E = 1e5, the
# tip falls 0.94 m) sags far outside the box neural modes train on. Seeded
# with modal derivatives and tangent-anchored, trained on the box alone the
# map ends 41% off (seeds 1-3); with every other sample drawn near the
# coordinates the untrained map's own run visited (no full simulation)
# 14-16%
SOFT=(--youngs 1e5 --poisson 0.45 --density 1000)
SST=(--pin clamp --gravity 0,-9.81,0 --dt 0.05 --steps 100 --damping 10)
NMD=(--objective neuralmodes --mesh bar.h5 --modes softm4.h5 --derivatives --tangent-anchor)
crom-fullsim "${SOFT[@]}" "${SST[@]}" -q -o softfull.h5 bar.h5
crom-modes "${SOFT[@]}" --pin clamp --count 4 -q -o softm4.h5 bar.h5
crom-fitfield "${NMD[@]}" --steps 0 -q -o soft0.h5
crom-reducedstep --model soft0.h5 "${SOFT[@]}" "${SST[@]}" -q -o softrun0.h5
crom-fitfield "${NMD[@]}" -q -o softbox.h5
crom-fitfield "${NMD[@]}" --latents softrun0.h5 -q -o softrun.h5
crom-info --check softrun.h5 >/dev/null || fail "crom-info --check softrun.h5"; ok
$PY - softrun.h5 softbox.h5 <<'PYEOF' || fail "sampled_along attribute"
import sys, h5py
a = h5py.File(sys.argv[1]).attrs["sampled_along"]
a = a.decode() if isinstance(a, bytes) else a
if a != "101 modal coordinates of softrun0.h5" or "sampled_along" in h5py.File(sys.argv[2]).attrs:
    raise SystemExit("sampled_along: %r" % a)
PYEOF
ok
for m in softbox softrun; do
  crom-reducedstep --model $m.h5 "${SOFT[@]}" "${SST[@]}" -q -o sag_$m.h5
done
eb=$(crom-diff sag_softbox.h5 softfull.h5 --model softbox.h5 --mesh bar.h5 | awk '$1 == 100 { print $3 }')
ev=$(crom-diff sag_softrun.h5 softfull.h5 --model softrun.h5 --mesh bar.h5 | awk '$1 == 100 { print $3 }')
echo "soft bar, static sag error: trained on the box $eb, sampled along the seed's run $ev"
$PY -c "import sys; b, v = $eb, $ev; sys.exit(0 if v < 0.25 and v < b / 2 else 1)" \
  || fail "sampling along the run holds the soft sag ($ev) within 25% and to half the box-trained error ($eb)"; ok

# the energy map refined along its own static run (--init-model --latents
# at rate 1e-4; issue 14): on the same soft bar the map of the default
# training (seed 1) ends 23% off, refined 2000 steps 15% (seeds 2, 3: 94% ->
# 46%, 21% -> 6%); on the 5K-vertex soft bar of the benchmarks, 1.1-5.1%
# static for five seeds (README)
EM=(--objective energy --mesh bar.h5 "${SOFT[@]}" --pin clamp --gravity 0,-9.81,0 --rank 4)
crom-fitfield "${EM[@]}" -q -o softem.h5
crom-reducedstep --model softem.h5 "${SOFT[@]}" "${SST[@]}" -q -o sag_softem.h5
crom-fitfield "${EM[@]}" --init-model softem.h5 --latents sag_softem.h5 --lr 1e-4 --steps 2000 -q -o softemref.h5
crom-reducedstep --model softemref.h5 "${SOFT[@]}" "${SST[@]}" -q -o sag_softemref.h5
e0=$(crom-diff sag_softem.h5 softfull.h5 --model softem.h5 --mesh bar.h5 | awk '$1 == 100 { print $3 }')
e1=$(crom-diff sag_softemref.h5 softfull.h5 --model softemref.h5 --mesh bar.h5 | awk '$1 == 100 { print $3 }')
echo "soft bar, energy map's static sag error: $e0, refined along its run $e1"
$PY -c "import sys; b, r = $e0, $e1; sys.exit(0 if r < 0.2 and r < 0.8 * b else 1)" \
  || fail "refining the energy map along its run takes the soft sag error to $e1 (from $e0): not below 20% and 0.8x"; ok

# 7. bad input: one line, the right status, no output left
O=out; mkdir -p $O
crom-mesh box --dims 1,0.2,0.2 --size 0.15 --region clamp='x<-0.49' -o other.h5
crom-mesh box --size 0.6 -o tiny.h5
nv=$($PY -c "import h5py; print(len(h5py.File('tiny.h5')['vertices']))")
crom-modes "${MAT[@]}" --count 3 -q -o modes_free.h5 bar.h5
crom-modes "${MAT[@]}" --pin clamp --count 3 -q -o modes_other.h5 other.h5
DF=(--objective energy --steps 2)
expect_error 64 "--rank 5000: a 5000-dimensional latent for a body with only $((3 * nv)) free degrees of freedom" $O/m.h5 -- crom-fitfield "${DF[@]}" --mesh tiny.h5 --gravity 0,0,0 --rank 5000 -o $O/m.h5
expect_error 64 "--objective neuralmodes needs the linear modes it builds on: --modes MODEL" $O/m.h5 -- crom-fitfield --objective neuralmodes --mesh bar.h5 -o $O/m.h5
expect_error 64 "--lambda: .* is not a finite number" $O/m.h5 -- crom-fitfield "${DF[@]}" --mesh bar.h5 --pin clamp --lambda nan -o $O/m.h5
expect_error 64 "--sigma: .* is not a finite number" $O/m.h5 -- crom-fitfield "${DF[@]}" --mesh bar.h5 --pin clamp --sigma inf -o $O/m.h5
expect_error 64 "--sigma.* (positive|> 0)" $O/m.h5 -- crom-fitfield "${DF[@]}" --mesh bar.h5 --pin clamp --sigma -1 -o $O/m.h5
expect_error 64 "--lambda must be >= 0, got -2" $O/m.h5 -- crom-fitfield "${DF[@]}" --mesh bar.h5 --pin clamp --lambda=-2 -o $O/m.h5
expect_error 64 "--tangent-floor 2: the collapse floor must be in \(0, 1\]" $O/m.h5 -- crom-fitfield "${DF[@]}" --mesh bar.h5 --pin clamp --tangent-floor 2 -o $O/m.h5
expect_error 65 "--modes modes_other.h5 was computed on another mesh \(.* vertices, .* tets\) than --mesh bar.h5" $O/m.h5 -- crom-fitfield --objective neuralmodes --mesh bar.h5 --modes modes_other.h5 -o $O/m.h5
expect_error 65 "--modes modes_free.h5 moves vertex [0-9]+, which is pinned here" $O/m.h5 -- crom-fitfield --objective neuralmodes --mesh bar.h5 --modes modes_free.h5 --pin clamp -o $O/m.h5
expect_error 65 "--modes df.h5 is a 'energy' model; neuralmodes builds on linear vibration modes" $O/m.h5 -- crom-fitfield --objective neuralmodes --mesh bar.h5 --modes df.h5 -o $O/m.h5
expect_error 64 "--rank 5: --modes modes.h5 has only 3 modes" $O/m.h5 -- crom-fitfield --objective neuralmodes --mesh bar.h5 --modes modes.h5 --rank 5 -o $O/m.h5
expect_error 64 "--latents applies to --objective neuralmodes" $O/m.h5 -- crom-fitfield --objective energy --mesh bar.h5 --latents softrun0.h5 -o $O/m.h5
expect_error 64 "--latents samples the energy along a run; --supervised fits equilibria: give one" $O/m.h5 -- crom-fitfield --objective neuralmodes --mesh bar.h5 --modes modes.h5 --latents softrun0.h5 --supervised softrun0.h5 -o $O/m.h5
expect_error 64 "softrun0.h5 has 4 latent coordinates, the model's rank is 3" $O/m.h5 -- crom-fitfield --objective neuralmodes --mesh bar.h5 --modes modes.h5 --latents softrun0.h5 -o $O/m.h5
expect_error 65 "--latents.*bar.h5.*crom/latent" $O/m.h5 -- crom-fitfield --objective neuralmodes --mesh bar.h5 --modes modes.h5 --latents bar.h5 -o $O/m.h5
expect_error 64 "--batch 1: sampling along a run \(--latents\) draws every other sample near it" $O/m.h5 -- crom-fitfield --objective neuralmodes --mesh bar.h5 --modes softm4.h5 --latents softrun0.h5 --batch 1 -o $O/m.h5
expect_error 64 "a free body under gravity has no lowest energy" $O/m.h5 -- crom-fitfield "${DF[@]}" --mesh bar.h5 -o $O/m.h5
expect_error 64 "--objective energy needs the mesh it maps: --mesh MESH" $O/m.h5 -- crom-fitfield --objective energy -o $O/m.h5
expect_error 64 "--objective energy learns from no samples" $O/m.h5 -- crom-fitfield "${DF[@]}" --mesh bar.h5 -o $O/m.h5 bar.h5
expect_error 64 "--epochs applies to --objective samples, not energy \(use --steps\)" $O/m.h5 -- crom-fitfield "${DF[@]}" --mesh bar.h5 --epochs 3 -o $O/m.h5
expect_error 64 "--mesh applies to a data-free subspace" $O/m.h5 -- crom-fitfield --mesh bar.h5 -o $O/m.h5
expect_error 64 "--pin applies to a data-free subspace" $O/m.h5 -- crom-fitfield --pin clamp -o $O/m.h5
expect_error 64 "unknown region 'lid'" $O/m.h5 -- crom-fitfield "${DF[@]}" --mesh bar.h5 --pin lid -o $O/m.h5
expect_error 65 "is crom/model v1, expected crom/mesh" $O/m.h5 -- crom-fitfield "${DF[@]}" --mesh df.h5 -o $O/m.h5
expect_error 65 "--cubature cub.h5 is not a cubature of this map" $O/x.h5 -- crom-reducedstep --model df.h5 --cubature cub.h5 -o $O/x.h5
expect_error 65 "dfcub.h5 is a cubature of a nonlinear map .*: run it with --model MODEL --cubature dfcub.h5" $O/x.h5 -- crom-reducedstep --cubature dfcub.h5 -o $O/x.h5
expect_error 64 "--solver gd needs a cubature" $O/x.h5 -- crom-reducedstep --model df.h5 --solver gd -o $O/x.h5
expect_error 65 "decodes only onto its own mesh \(110 vertices, 254 tets\); the given mesh has" $O/x.h5 -- crom-reducedstep --model df.h5 --mesh other.h5 -o $O/x.h5
expect_error 64 "unknown region 'lid'" $O/x.h5 -- crom-reducedstep --model df.h5 --pin lid -o $O/x.h5
expect_error 65 "--init .* is a state of model" $O/x.h5 -- crom-reducedstep --model df.h5 --init run_nm.h5 "${MAT[@]}" -o $O/x.h5
expect_error 65 "decodes only onto its own mesh" $O/x.vtu -- crom-export --format vtu --model df.h5 --mesh other.h5 -o $O/x.vtu run_df.h5
expect_error 65 "decodes only onto its own mesh" $O/c.h5 -- crom-cubature --model df.h5 -o $O/c.h5 other.h5
expect_error 64 "--compare df.h5 is a nonlinear map \('energy'\); the comparison needs a linear basis" - -- crom-metrics --compare df.h5 nm.h5
expect_error 65 "decodes only onto its own mesh" - -- crom-metrics --mesh other.h5 df.h5
expect_error 64 "is a neural field x\(X, q\): give the mesh to lay it on" $O/x.h5 -- crom-reducedstep --model fld.h5 -o $O/x.h5
expect_error 64 "--pin-length.*(positive|> 0)" $O/m.h5 -- crom-fitfield --objective field --mesh bar.h5 --pin clamp --pin-length 0 -o $O/m.h5
expect_error 64 "--features" $O/m.h5 -- crom-fitfield --objective field --mesh bar.h5 --pin clamp --features 0 -o $O/m.h5
expect_error 64 "--pin-length applies to a data-free subspace" $O/m.h5 -- crom-fitfield --pin-length 1 -o $O/m.h5
expect_error 65 "--cubature fldcub.h5 is not a cubature of this map" $O/x.h5 -- crom-reducedstep --model fld.h5 --mesh bar.h5 --cubature fldcub.h5 -o $O/x.h5
expect_error 65 "continuous nonlinear map .* not a basis field" - -- crom-encode --model fld.h5 full_fine.h5
# damaged files: the field's pin mask and latent network, a map cubature's rank
cp fld.h5 fld_len.h5; cp fld.h5 fld_lat.h5; cp dfcub.h5 dfcub_bad.h5
$PY - <<'PYEOF'
import h5py
with h5py.File("fld_len.h5", "r+") as f:
    f["latent/pin_length"][0] = -1.0
with h5py.File("fld_lat.h5", "r+") as f:
    del f["latent/params"]
with h5py.File("dfcub_bad.h5", "r+") as f:
    f.attrs["map_rank"] = 0
PYEOF
expect_error 65 "fld_len.h5: latent/pin_length must be one positive length" $O/x.h5 -- crom-reducedstep --model fld_len.h5 --mesh fine.h5 -o $O/x.h5
expect_error 65 "fld_lat.h5: .*latent/params" $O/x.h5 -- crom-reducedstep --model fld_lat.h5 --mesh fine.h5 -o $O/x.h5
expect_error 65 "map_rank 0 is out of range" $O/x.h5 -- crom-reducedstep --model df.h5 --cubature dfcub_bad.h5 -o $O/x.h5
done_checks
