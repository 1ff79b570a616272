#!/usr/bin/env bash
# Rods with animated rest lengths (--rod, issue 19 item 4) through the
# programs: two blocks (a .geo of two boxes through crom-mesh import), one
# pinned and one tied to it by a rod whose rest length follows a sinusoid.
# crom-fullsim drives the free block at the rod's frequency, against
# resonance (ω = 20 rad/s over ω0 = 10: the block moves against the rest
# length); the scenario attribute keeps the rod and replays the same run;
# crom-reducedstep over a cubature and through --model (the nonlinear
# path) follow the full run in a POD basis of it to round-off; crom-live
# runs a rod too; the puppet experiment runs at a small size; bad rods are
# one line.
# asan: skip (full and reduced runs of driven blocks, 18 s under ASan; tests/unit/test_rod.c, test_rom.c and test_datafree.c cover the rod code there)
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
cat > two.geo <<'EOF'
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 0.1, 0.1, 0.1};
Box(2) = {0.4, 0, 0, 0.1, 0.1, 0.1};
EOF
crom-mesh import two.geo --size 0.05 --region anchor='x<0.2' --region block='x>0.2' -o two.h5
# ω = 2π/0.314159 = 20 rad/s; k = 100 N/m on the 1 kg block: ω0 = 10 rad/s
SC=(--youngs 1e8 --poisson 0.3 --gravity 0,0,0 --dt 0.005 --steps 800 --damping 2 --pin 'x<0.2'
    --rod 'x<0.2/x>0.2=100,rest,0.01,0.3141592653589793')
crom-fullsim "${SC[@]}" -q -o full.h5 two.h5
crom-info --check full.h5 >/dev/null || fail "crom-info --check full.h5"; ok
$PY - full.h5 <<'PYEOF' || fail "driven block"
import sys, h5py, numpy as np
f = h5py.File(sys.argv[1])
sc = f.attrs["scenario"]
sc = sc.decode() if isinstance(sc, bytes) else sc
if "--rod x<0.2/x>0.2=100,rest,0.01,0.31415926535897931,0\n" not in sc:
    raise SystemExit("scenario text: %r" % sc)
X = f["mesh/vertices"][()]
t = f["frames/time"][()]
u = f["frames/displacement"][()]
blk = X[:, 0] > 0.2
if np.abs(u[:, ~blk]).max() != 0:
    raise SystemExit("the pinned block moved")
ux = u[:, blk, 0].mean(axis=1)             # the block's stretch of the rod (equal masses per vertex not assumed: small)
late = t >= 2.0
w = 20.0
A = np.stack([np.sin(w * t[late]), np.cos(w * t[late])], axis=1)
(al, be), *_ = np.linalg.lstsq(A, ux[late] - ux[late].mean(), rcond=None)
amp, lag = np.hypot(al, be) / 0.01, np.arctan2(-be, al)
h, k, m, damp = 0.005, 100.0, 1.0, 2.0
zi = np.exp(-1j * w * h)
H = (k / m) / ((1 - zi) ** 2 / h ** 2 + damp * (1 - zi) / h + k / m)
print("driven block: amplitude %.4f (implicit Euler %.4f), lag %.3f rad (%.3f)" % (amp, abs(H), lag, -np.angle(H)))
if not (abs(amp - abs(H)) < 0.02 * abs(H) and abs(lag + np.angle(H)) < 0.03 and lag > np.pi / 2):
    raise SystemExit("not the driven oscillator's steady state")
PYEOF
ok
# the stored scenario replays the run
$PY -c "import h5py; s=h5py.File('full.h5').attrs['scenario']; open('sc.flags','w').write(s.decode() if isinstance(s, bytes) else s)"
crom-fullsim @sc.flags -q -o again.h5 two.h5
crom-diff full.h5 again.h5 2>&1 | grep -q "relative displacement error 0 " || fail "replay from the scenario attribute"; ok

# reduced: a POD basis of the run (rank 1: the block's translation)
crom-sample --points all -q -o s.h5 full.h5
crom-fitfield --basis pod --rank 1 -q -o pod.h5 s.h5
crom-cubature --model pod.h5 --scheme all -q -o cub.h5 two.h5
crom-reducedstep --cubature cub.h5 "${SC[@]}" -q -o red.h5
crom-reducedstep --model pod.h5 "${SC[@]}" -q -o nl.h5
for r in red nl; do
  e=$(crom-diff --model pod.h5 full.h5 $r.h5 2>&1 | sed -n 's/^relative displacement error \([^ ]*\) .*/\1/p')
  echo "$r: relative error $e against crom-fullsim"
  close "$e" 0 1e-8 "$r against the full run"
done
# crom-live: the same run from a script, no clock
printf 'step 800\nquit\n' | crom-live --cubature cub.h5 "${SC[@]}" --no-clock -q > live.h5
e=$(crom-diff --model pod.h5 --mesh two.h5 red.h5 live.h5 2>&1 | sed -n 's/^relative displacement error \([^ ]*\) .*/\1/p')
close "$e" 0 1e-12 "crom-live against crom-reducedstep"

# the puppet (pipelines/puppet.mk, Neural Modes §5) at a small size, free:
# six rods swing the arms and turn the torso; every subspace has the six
# rigid DoFs of --rigid-frame; modes with their derivatives follow the full
# run far better than the linear modes, whose arms lock (they swing less
# than half as far), and the frame turns the torso as the full run does
# (within half); a filmstrip per subspace. (Eigensolves and training: not
# under the sanitizers, like materials.sh's experiment.)
if [ "${CROM_SANITIZE:-0}" != 1 ]; then
  make -s -f "$CROM_TOP/pipelines/puppet.mk" OUT="$TMP/pup" SIZE=0.07 STEPS=24 TMINUTES=0.02 QUIET=-q \
    ROWS="modes mderiv neuralmodes nmcub" \
    BINDIR="$CROM_BINDIR" >pup.txt 2>pup.err || fail "puppet.mk: $(cat pup.err)"
  cat pup.txt
  [ "$(grep -c '^| [lmnt]' pup.txt)" -eq 4 ] || fail "puppet.mk: the table lacks rows"; ok
  $PY - pup.txt <<'PYEOF' || fail "puppet.mk: modal derivatives not better than the linear modes"
import sys
rows = {l.split("|")[1].strip(): l.split("|") for l in open(sys.argv[1]) if l.startswith("| ") and "subspace" not in l}
full = rows.pop("crom-fullsim")
err = {k: float(v[4]) for k, v in rows.items()}
swing = {k: float(v[6].split()[0]) for k, v in rows.items()}
turn = {k: float(v[7].strip().rstrip("°")) for k, v in list(rows.items()) + [("full", full)]}
print(err, swing, turn)
if not all(v[2].strip().endswith("+ 6") for v in rows.values()):
    raise SystemExit("every subspace should have the rigid frame")
if not (err["modes + modal derivatives"] < 0.6 * err["linear modes"] and
        swing["modes + modal derivatives"] > 2 * swing["linear modes"]):
    raise SystemExit("modal derivatives do not beat the locked linear modes")
if not (turn["full"] > 0 and abs(turn["modes + modal derivatives"] / turn["full"] - 1) < 0.5):
    raise SystemExit("the frame does not turn the torso as the full run does")
PYEOF
  ok
  for r in modes mderiv neuralmodes; do
    [ "$(head -c 8 "$TMP/pup/strip-$r.png" | od -An -tx1 | tr -d ' \n')" = 89504e470d0a1a0a ] || fail "strip-$r.png"; ok
  done
fi

# bad rods
O=$TMP/out.h5
expect_error 64 "--rod 'x<0.2': expected A/B=K,L0" $O -- crom-fullsim --rod 'x<0.2' -o $O two.h5
expect_error 64 "--rod: the stiffness must be positive" $O -- crom-fullsim --rod 'anchor/block=-1,rest' -o $O two.h5
expect_error 64 "--rod: the period must be positive" $O -- crom-reducedstep --cubature cub.h5 --rod 'x<0.2/x>0.2=1,rest,0.1,0' -o $O
expect_error 64 "nowhere" $O -- crom-fullsim --rod 'anchor/nowhere=1,rest' -o $O two.h5
expect_error 64 "nowhere" $O -- crom-reducedstep --cubature cub.h5 --rod 'x<0.2/nowhere=1,rest' -o $O
expect_error 64 "nowhere" $O -- crom-reducedstep --model pod.h5 --rod 'x<0.2/nowhere=1,rest' -o $O
expect_error 64 "--equilibria minimizes the elastic energy alone.*--rod" $O -- crom-fullsim --equilibria pod.h5 --grid 2 --rod 'anchor/block=1,rest' -o $O two.h5
done_checks
