#!/usr/bin/env bash
# crom-reducedstep --indicator (issue 18): the a-posteriori error indicator
# needs no full simulation, yet must rise with the true error (crom-diff
# against crom-fullsim). A POD basis of a sagging bar, run on the trained
# bar, on a rounded bar (an unseen similar shape), on a thinner bar (unseen,
# other proportions) and on the trained bar with a 4x softer material: the
# indicator ranks the runs as their true errors rank, stays within a small
# factor of them, and warns only where the subspace is out of its depth.
# asan: skip (full and reduced runs of four bars, 31 s under ASan; tests/unit/test_rom.c covers the indicator code there)
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
SC=(--pin clamp --gravity 0,-9.81,0 --youngs 2e5 --poisson 0.3 --dt 0.02 --steps 25)
crom-mesh box --dims 1,0.2,0.2 --size 0.05 --region clamp='x<-0.49' -q -o bar.h5
crom-mesh superquadric --dims 1,0.2,0.2 --exponent 4 --size 0.05 --region clamp='x<-0.45' -q -o round.h5
crom-mesh box --dims 1,0.12,0.2 --size 0.04 --region clamp='x<-0.49' -q -o thin.h5
crom-fullsim "${SC[@]}" -q -o full_trained.h5 bar.h5
crom-sample --points all -q -o samples.h5 full_trained.h5
crom-fitfield --basis pod --rank 4 -q -o pod.h5 <samples.h5

# run NAME MESH [scenario flags...]: the full and the reduced run, the true
# error, the indicator and its warning
run() {
  local n=$1 m=$2; shift 2
  local s=("${SC[@]}" "$@")
  [ -e "full_$n.h5" ] || crom-fullsim "${s[@]}" -q -o "full_$n.h5" "$m"
  crom-cubature -q --model pod.h5 --scheme all -o "cub_$n.h5" "$m"
  crom-reducedstep --cubature "cub_$n.h5" "${s[@]}" --indicator --indicator-model pod.h5 --stats "red_$n.csv" \
    -o "red_$n.h5" 2>"ind_$n.log" || fail "reduced run $n: $(cat "ind_$n.log")"
  crom-info --check "red_$n.h5" >/dev/null || fail "latent $n invalid"; ok
  crom-diff "red_$n.h5" "full_$n.h5" --model pod.h5 -q | sed -n 's/relative displacement error \([0-9.e+-]*\) over.*/\1/p' \
    >"err_$n.txt"
  sed -n 's/.*error indicator \([0-9.e+-]*\) (estimated.*/\1/p' "ind_$n.log" >"ind_$n.txt"
  [ -s "err_$n.txt" ] && [ -s "ind_$n.txt" ] || fail "run $n: no error or no indicator: $(cat "ind_$n.log")"
  echo "$n: true error $(cat "err_$n.txt"), indicator $(cat "ind_$n.txt")"
}
run trained bar.h5
run round round.h5
run thin thin.h5
run soft bar.h5 --youngs 5e4

# 1. the indicator ranks the runs as their true errors do (every pair whose
#    errors differ by more than 25%), and reads within 1-6 times the error;
#    the summary is sqrt(sum |e|^2 / sum |u|^2) of the stored frames and of
#    the --stats columns
$PY - <<'PYEOF' || fail "indicator against the true error"
import h5py, numpy as np
runs = ["trained", "round", "thin", "soft"]
err = {n: float(open(f"err_{n}.txt").read()) for n in runs}
ind = {n: float(open(f"ind_{n}.txt").read()) for n in runs}
bad = []
for a in runs:
    for b in runs:
        if err[a] > 1.25 * err[b] and not ind[a] > ind[b]:
            bad.append(f"{a} ({err[a]:.3g}, indicator {ind[a]:.3g}) vs {b} ({err[b]:.3g}, {ind[b]:.3g})")
    r = ind[a] / err[a]
    if not 1 <= r <= 6:
        bad.append(f"{a}: indicator {ind[a]:.3g} is {r:.2f} times the error {err[a]:.3g}")
    f = h5py.File(f"red_{a}.h5")
    e = f["frames/error_estimate"][()]; rel = f["frames/indicator"][()]
    u = np.where(rel > 0, e / np.where(rel > 0, rel, 1), 0)
    tot = np.sqrt((e ** 2).sum() / (u ** 2).sum())
    if abs(tot - ind[a]) > 6e-3 * ind[a]:
        bad.append(f"{a}: the stored frames give {tot:.4g}, the summary {ind[a]:.4g}")
    c = np.genfromtxt(f"red_{a}.csv", delimiter=",", names=True)
    tc = np.sqrt((c["error_estimate"] ** 2).sum() / (c["displacement_rms"] ** 2).sum())
    if abs(tc - tot) > 1e-5 * tot:
        bad.append(f"{a}: --stats gives {tc:.6g}, the frames {tot:.6g}")
    if not (e[0] == 0 and rel[0] == 0 and f.attrs["initial_error"].shape == (2,)):
        bad.append(f"{a}: frame 0 or initial_error")
    # the rounded bar is clamped over x < -0.45, where the basis (clamped at
    # x < -0.49) moves: bc_error says so
    miss = f["frames/bc_error"][()].max()
    if (miss > 1e-3) != (a == "round"):
        bad.append(f"{a}: the clamp missed by {miss:.3g} m")
if bad:
    raise SystemExit("; ".join(bad))
PYEOF
ok

# 2. --warn-above: one warning for the soft run, none for the trained one
grep -q "warning: the subspace is out of its depth: error indicator" ind_soft.log || fail "no warning for the soft run"; ok
! grep -q "warning" ind_trained.log || fail "the trained run warned: $(cat ind_trained.log)"; ok
crom-reducedstep --cubature cub_soft.h5 "${SC[@]}" --youngs 5e4 --indicator --indicator-model pod.h5 --warn-above 0 \
  -q -o /dev/null 2>quiet.log
[ ! -s quiet.log ] || fail "--warn-above 0 -q printed: $(cat quiet.log)"; ok
# --indicator-mesh: the same measure on a given mesh (here the cubature's own)
crom-reducedstep --cubature cub_soft.h5 "${SC[@]}" --youngs 5e4 --indicator --indicator-model pod.h5 \
  --indicator-mesh bar.h5 -o /dev/null 2>given.log
close "$(sed -n 's/.*error indicator \([0-9.e+-]*\) (estimated.*/\1/p' given.log)" "$(cat ind_soft.txt)" 0 \
  "--indicator-mesh of the cubature's mesh"

# a schedule switch to a punched bar: measured on each cubature's mesh in
# turn (the hole's new free surface carries no load: the estimate stays
# that of the intact run's order)
crom-remesh punch --sphere 0.2,0,0,0.08 -q -o punched.h5 bar.h5
crom-cubature -q --model pod.h5 --scheme all -o cub_punched.h5 punched.h5
echo "12 cub_punched.h5" >sched.txt
crom-reducedstep --cubature cub_trained.h5 --schedule sched.txt "${SC[@]}" --indicator --indicator-model pod.h5 \
  --stats sched.csv -o sched.h5 2>sched.log || fail "scheduled run: $(cat sched.log)"
$PY - <<'PYEOF' || fail "indicator across a schedule switch"
import numpy as np
c = np.genfromtxt("sched.csv", delimiter=",", names=True)
e = c["error_estimate"]
if not (np.all(np.isfinite(e)) and len(e) == 25 and e[11:].max() < 0.2 * c["displacement_rms"][11:].max()):
    raise SystemExit(f"estimates {e}")
PYEOF
ok

# 3. --model runs (the map path, here the same POD basis on its own mesh)
#    measure on the model's mesh: the same indicator as over every tet
crom-reducedstep --model pod.h5 --mesh bar.h5 "${SC[@]}" --indicator -o map.h5 2>map.log
close "$(sed -n 's/.*error indicator \([0-9.e+-]*\) (estimated.*/\1/p' map.log)" "$(cat ind_trained.txt)" \
  "$($PY -c "print(1e-3 * $(cat ind_trained.txt))")" "indicator over --model and over --cubature all"

# 4. bad input: one line, nothing written
O=out; mkdir -p $O
expect_error 64 "needs --indicator-model MODEL" $O/a.h5 -- \
  crom-reducedstep --cubature cub_trained.h5 "${SC[@]}" --indicator -o $O/a.h5
expect_error 64 "applies to --indicator" $O/a.h5 -- \
  crom-reducedstep --cubature cub_trained.h5 "${SC[@]}" --indicator-mesh bar.h5 -o $O/a.h5
expect_error 64 "measures on the map's own mesh" $O/a.h5 -- \
  crom-reducedstep --model pod.h5 --mesh bar.h5 "${SC[@]}" --indicator --indicator-model pod.h5 -o $O/a.h5
crom-fitfield --basis pod --rank 3 -q -o pod3.h5 <samples.h5
expect_error 64 "is not the cubature's model" $O/a.h5 -- \
  crom-reducedstep --cubature cub_trained.h5 "${SC[@]}" --indicator --indicator-mesh bar.h5 --indicator-model pod3.h5 -o $O/a.h5
crom-mesh box --dims 1,0.2,0.2 --size 0.1 -q -o noregion.h5
expect_error 64 "clamp" $O/a.h5 -- \
  crom-reducedstep --cubature cub_trained.h5 "${SC[@]}" --indicator --indicator-mesh noregion.h5 --indicator-model pod.h5 -o $O/a.h5
expect_error 64 "--warn-above must be a number >= 0" $O/a.h5 -- \
  crom-reducedstep --cubature cub_trained.h5 "${SC[@]}" --indicator --warn-above -1 -o $O/a.h5
done_checks
