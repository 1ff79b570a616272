#!/usr/bin/env bash
# times.sh — frame times are exact multiples of the time step (issue 12):
# after 1000 steps of 0.001 s, frame k of crom-fullsim, of crom-reducedstep
# over a cubature and of crom-reducedstep --model is at (double)k * 0.001
# (a running sum of 0.001 drifts: 1000 of them add up to 1.0000000000000007).
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
crom-mesh box --size 0.5 --region clamp='x<-0.49' -o box.h5
SC=(--pin clamp --gravity 0,-9.81,0 --dt 0.001 --steps 1000 --every 10)
crom-fullsim "${SC[@]}" -q -o full.h5 box.h5
crom-sample --points all -o samples.h5 full.h5
crom-fitfield --basis pod --rank 3 -q -o pod.h5 <samples.h5
crom-cubature --model pod.h5 --scheme all -q -o cub.h5 box.h5
crom-reducedstep --cubature cub.h5 "${SC[@]}" -q -o red.h5
crom-modes --pin clamp --count 3 -q -o modes.h5 box.h5
crom-reducedstep --model modes.h5 --mesh box.h5 "${SC[@]}" -q -o map.h5
$PY - full.h5 red.h5 map.h5 <<'PYEOF' || fail "frame times"
import sys, h5py
def times(path):
    f = h5py.File(path, "r")
    g = f["frames"] if "frames" in f else f
    return g["time"][:], g["step"][:]
bad = []
for p in sys.argv[1:]:
    t, step = times(p)
    if len(t) != 101:
        bad.append(f"{p}: {len(t)} frames, expected 101")
    for k in range(len(t)):
        want = float(int(step[k])) * 0.001
        if t[k] != want:
            bad.append(f"{p}: frame {k} (step {int(step[k])}) at {t[k]!r}, expected {want!r}")
            break
    if t[-1] != 1.0:
        bad.append(f"{p}: last frame at {t[-1]!r}, expected 1.0")
if bad:
    print("\n".join(bad)); sys.exit(1)
PYEOF
ok
done_checks
