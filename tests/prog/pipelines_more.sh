#!/usr/bin/env bash
# Small versions of pipelines/punching.mk, rolling.mk and tug.mk run end to
# end (tiny meshes, few steps, few epochs, small rank); their tables' numbers
# are checked against bounds (errors below, speedups above), their schedules
# against what happened, a second make reruns nothing, and a corrupt
# intermediate file stops make at that stage with the stage's one-line
# message and leaves no stale or half-made target behind.
#
# Bounds (relative displacement error over the run, crom-diff): the tiny
# versions land at 0.04-0.25 (build and build-san sizes); a broken solver,
# cubature, basis or schedule gives errors near 1 or non-finite values.
#   punching: each training mesh < 0.3, the punching run vs the intact block < 0.3
#   tug: training tugs < 0.2; new tug, unseen shape, swap vs the body < 0.4
#   rolling: training shapes < 0.25, the interpolated shape < 0.2, every
#            full run's reconstruction error in the basis < 0.1
#   every row: reduced step more than 2x faster than the full one
# asan: skip (three make pipelines of simulations and training, 170 s under ASan; their stages run under ASan in reduced.sh, remesh.sh, pipelines.sh and the export tests)
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
MK=(make --no-print-directory -j2 BINDIR="$CROM_BINDIR" SEED=1)
# the sanitizer build runs about 4 times slower: smaller still
if [[ "${CROM_BUILD:-}" == *build-san ]]; then
  TINY=(EPOCHS=150 RANK=8 COUNT=40 POINTS=200)
  PSIZE=0.17 PSTEPS=12 TSIZE=0.12 TSTEPS=16 RSIZE=0.18 RSTEPS=30 RPOINTS=150
else
  TINY=(EPOCHS=150 RANK=8 COUNT=40 POINTS=256)
  PSIZE=0.14 PSTEPS=16 TSIZE=0.1 TSTEPS=20 RSIZE=0.16 RSTEPS=36 RPOINTS=200
fi

# check_table CSV 'LABEL-REGEX MAX-ERROR' ...: every row matching a regex has
# a finite relative error below its bound; every row a speedup above 2, the
# requested rank and a cubature within the budget
check_table() {
  local csv=$1; shift
  $PY - "$csv" "${TINY[@]}" -- "$@" <<'PYEOF' || fail "table bounds of $csv"
import csv, math, re, sys
args = sys.argv[1:]; cut = args.index("--")
path, flags, bounds = args[0], dict(a.split("=") for a in args[1:cut]), args[cut + 1:]
rows = list(csv.DictReader(open(path)))
if not (rows):
    raise SystemExit("check failed: " + str("no rows"))
seen = set()
for r in rows:
    err, sp = float(r["relative_error"]), float(r["speedup"])
    print("%-40s error %.4f  speedup %.0fx  cubature %s  rank %s" % (r["run"], err, sp, r["cubature_tets"], r["rank"]))
    if not (math.isfinite(err)):
        raise SystemExit("check failed: " + str(r["run"] + ": error not finite"))
    if not (sp > 2):
        raise SystemExit("check failed: " + str(r["run"] + ": reduced step not faster than the full one"))
    if not (int(r["rank"]) == int(flags["RANK"])):
        raise SystemExit("check failed: " + str(r["run"] + ": rank"))
    if not (0 < int(r["cubature_tets"]) <= 4 * int(flags["COUNT"])):
        raise SystemExit("check failed: " + str(r["run"] + ": cubature count"))
    for b in bounds:
        pat, mx = b.rsplit(" ", 1)
        if re.fullmatch(pat, r["run"]):
            seen.add(pat)
            if not (err < float(mx)):
                raise SystemExit("check failed: " + str("%s: relative error %.4f above the bound %s" % (r["run"], err, mx)))
missing = [b for b in bounds if b.rsplit(" ", 1)[0] not in seen]
if not (not missing):
    raise SystemExit("check failed: " + str("no row for %s" % missing))
PYEOF
  ok
}

# nothing is rebuilt when nothing changed (stages are reused)
check_rerun() {
  "${MK[@]}" "$@" >rerun.log 2>&1 || fail "second make failed: $(tail -3 rerun.log)"
  ! grep -q '^crom-' rerun.log || fail "a second make reran stages: $(grep '^crom-' rerun.log | head -3)"
  ok
}

# 1. punching: two tunnels, punched during the run
P=(-f "$CROM_TOP/pipelines/punching.mk" OUT=pun SIZE=$PSIZE STEPS=$PSTEPS "${TINY[@]}"
   HOLES='-0.35,0.05,-1,-0.05,0.35,1 0.05,0.05,-1,0.35,0.35,1')
"${MK[@]}" "${P[@]}" >pun.log 2>&1 || fail "punching pipeline: $(tail -5 pun.log)"
grep -q 'punching-0-to-2(vs-intact-full)' pun.log || fail "punching: table not printed"; ok
for f in strip.png punch.pvd punch.xdmf punch.xdmf.h5 loss.plot.png error.plot.png cost.plot.png; do
  [ -s "pun/$f" ] || fail "punching: pun/$f missing"
done; ok
check_table pun/rows.txt.csv '[0-2]-holes\(trained\) 0.3' 'punching-0-to-2\(vs-intact-full\) 0.3'
# the run started intact and ended with both holes, on the schedule's steps
$PY - <<'PYEOF' || fail "punching schedule"
import h5py, numpy as np
c = h5py.File("pun/punch.h5")["frames/cubature"][()]
sched = [int(l.split()[0]) for l in open("pun/schedule.txt")]
if not (c[0] == 0 and c[-1] == 2 and np.all(np.diff(c) >= 0)):
    raise SystemExit(f"check failed: {c!s}")
if not ([int(np.argmax(c >= k)) for k in (1, 2)] == sched):
    raise SystemExit(f"check failed: {(c, sched)!s}")
PYEOF
ok
check_rerun "${P[@]}"

# 2. tug: two training tugs, a new one, a swap to a box half way
T=(-f "$CROM_TOP/pipelines/tug.mk" OUT=tug SIZE=$TSIZE STEPS=$TSTEPS "${TINY[@]}" LOADS='800,0,0 0,0,800' PULL=0.1)
"${MK[@]}" "${T[@]}" >tug.log 2>&1 || fail "tug pipeline: $(tail -5 tug.log)"
for f in strip.png swap.pvd swap.xdmf loss.plot.png error.plot.png cost.plot.png; do
  [ -s "tug/$f" ] || fail "tug: tug/$f missing"
done; ok
check_table tug/rows.txt.csv 'trained-tug-[12] 0.2' 'new-tug 0.4' 'unseen-shape\(new-tug\) 0.4' \
  "swap-at-step-$((TSTEPS / 2))\(vs-body-full\) 0.4"
$PY - $((TSTEPS / 2)) <<'PYEOF' || fail "tug swap"
import sys, h5py, numpy as np
s = int(sys.argv[1]); f = h5py.File("tug/swap.h5"); c = f["frames/cubature"][()]; q = f["frames/q"][()]
if not (np.all(c[:s] == 0) and np.all(c[s:] == 1)):
    raise SystemExit(f"check failed: {c!s}")
# the state carries over: q keeps moving smoothly through the swap
dq = np.linalg.norm(np.diff(q, axis=0), axis=1)
if not (dq[s - 1] < 3 * max(dq[s - 2], dq[s]) + 1e-12):
    raise SystemExit(f"check failed: {dq!s}")
# the swapped run's pvd holds the box after the swap
import meshio
a = meshio.read("tug/swap/swap_%05d.vtu" % (s - 1)); b = meshio.read("tug/swap/swap_%05d.vtu" % s)
o = h5py.File("tug/other.h5")["vertices"][()]; body = h5py.File("tug/body.h5")["vertices"][()]
if not (np.array_equal(a.points, body) and np.array_equal(b.points, o)):
    raise SystemExit("check failed: " + str("pvd frames on the wrong meshes"))

PYEOF
ok
check_rerun "${T[@]}"

# 3. rolling: a sphere and a rounded cube, one shape in between
R=(-f "$CROM_TOP/pipelines/rolling.mk" OUT=rol SIZE=$RSIZE STEPS=$RSTEPS "${TINY[@]}" POINTS=$RPOINTS TRAIN='2 5' TEST='3'
   PLANE=0,0.7071067811865476,0.7071067811865476,-0.63)   # a small gap: they roll soon
"${MK[@]}" "${R[@]}" >rol.log 2>&1 || fail "rolling pipeline: $(tail -5 rol.log)"
for f in strip-2.png strip-3.png red-3.pvd red-3.xdmf recon.md loss.plot.png error.plot.png cost.plot.png; do
  [ -s "rol/$f" ] || fail "rolling: rol/$f missing"
done; ok
check_table rol/rows.txt.csv 'trained-p[25] 0.25' 'interpolated-p3 0.2'
# the bodies really roll down the slope (the centroid moves down along it)
$PY - <<'PYEOF' || fail "rolling motion"
import h5py, numpy as np
f = h5py.File("rol/full-3.h5"); u = f["frames/displacement"][()]
d = u[-1].mean(0)
print("p3 centroid moved by", np.round(d, 3))
if not (d[1] < -0.05 and d[2] > 0.05):
    raise SystemExit(f"check failed: {d!s}")
PYEOF
ok
# the basis holds the training runs' motion, rigid rolling included
for s in 2 5 3; do
  e=$(grep -o 'error [0-9.e+-]*' rol/recon-$s.txt | head -1 | cut -d' ' -f2)
  echo "p$s: reconstruction error of its full run in the basis $e"
  close "$e" 0 0.1 "reconstruction error of the p$s run in the basis"
done
check_rerun "${R[@]}"

# 4. a corrupt intermediate stops make at its stage with that stage's
#    one-line message and leaves nothing half made: a model overwritten with
#    random bytes before the stages that read it have run
"${MK[@]}" "${T[@]}" OUT=bad bad/model.h5 >bad.log 2>&1 || fail "tug up to the model: $(tail -3 bad.log)"
sz=$(stat -c %s bad/model.h5)
head -c "$sz" /dev/urandom >bad/model.h5
rc=0
"${MK[@]}" "${T[@]}" OUT=bad -j1 bad/table.md >bad.log 2>&1 || rc=$?
[ $rc -eq 2 ] || fail "make on a corrupt model exited $rc, expected 2"; ok
[ "$(grep -c '^crom-[a-z]*: ' bad.log)" -eq 1 ] || fail "expected one stage message: $(grep '^crom-[a-z]*: ' bad.log)"; ok
grep -qE '^crom-(encode|cubature): .*bad/model.h5 is not a crom file' bad.log || fail "message: $(grep '^crom-' bad.log)"; ok
for f in bad/poses-* bad/cub-* bad/red-* bad/swap* bad/table.md bad/rows.txt; do
  [ ! -e "$f" ] || fail "a corrupt model left $f behind"
done
! ls -a bad | grep -q '\.tmp$' || fail "a temporary file was left in bad/"; ok
#    and a cubature of the punching schedule corrupted after a complete run:
#    the run that reads it fails, nothing downstream is remade from it, and
#    what is left is older than the corrupt file, so the next make redoes it
head -c "$(stat -c %s pun/cub-1.h5)" /dev/urandom >pun/cub-1.h5
rc=0
"${MK[@]}" "${P[@]}" -j1 pun/table.md >bad2.log 2>&1 || rc=$?
[ $rc -eq 2 ] || fail "make on a corrupt cubature exited $rc, expected 2"; ok
[ "$(grep -c '^crom-[a-z]*: ' bad2.log)" -eq 1 ] || fail "expected one stage message: $(grep '^crom-[a-z]*: ' bad2.log)"; ok
grep -qE '^crom-reducedstep: .*pun/cub-1.h5 is not a crom file' bad2.log || fail "message: $(grep '^crom-' bad2.log)"; ok
for f in pun/red-1.h5 pun/punch.h5 pun/diff-1.txt pun/diff-punch-vs-0.txt pun/rows.txt pun/table.md pun/strip.png; do
  [ ! -e "$f" ] || [ "$f" -ot pun/cub-1.h5 ] || fail "$f is newer than the corrupt cubature it depends on"
done
! ls -a pun | grep -q '\.tmp$' || fail "a temporary file was left in pun/"; ok
done_checks
