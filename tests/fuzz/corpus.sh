#!/usr/bin/env bash
# corpus.sh — the seed corpus of the fuzz harnesses, made by the programs at
# tiny sizes: a coarse mesh, a few full-simulation steps (as a file and as a
# stream through a pipe), samples, a POD model and its latent, linear modes,
# a data-free skinning model, a run with a rigid frame, cubatures, surfaces
# written by crom-export plus a few by hand, point clouds, and the flag lines
# of pipelines/*.mk.
# Usage: tests/fuzz/corpus.sh BINDIR OUTDIR   (OUTDIR/NAME/ per harness)
# Remade only when a program is newer than OUTDIR/.done.
set -euo pipefail
BINDIR=$(cd "$1" && pwd)
OUT=$2
TOP=$(cd "$(dirname "$0")/../.." && pwd)
export PATH="$BINDIR:$PATH" OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 SOURCE_DATE_EPOCH=1700000000
if [ -f "$OUT/.done" ] && [ -z "$(find "$BINDIR" -name 'crom-*' -newer "$OUT/.done" | head -1)" ] &&
  [ ! "$0" -nt "$OUT/.done" ]; then
  exit 0
fi
rm -rf "$OUT"
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
W=$(mktemp -d "${TMPDIR:-/tmp}/crom-corpus.XXXXXX")
trap 'rm -rf "$W"' EXIT
cd "$W"
for d in flags atfile stl obj cloud live frames stream mesh traj samples model cubature check; do mkdir -p "$OUT/$d"; done

# ---- HDF5 files of each kind, at tiny sizes
SC=(--velocity 'top=0,-2,0@0:0.1' --pin bottom --gravity 0,0,0 --dt 0.01 --steps 3)
crom-mesh box --dims 1,0.4,0.4 --size 0.25 --region top='y>0.15' --region bottom='y<-0.15' --region clamp='x<-0.45' -q -o box.h5
crom-mesh sphere --radius 0.5 --size 0.3 --region top='y>0.3' --region bottom='y<-0.3' -q -o sphere.h5
crom-fullsim "${SC[@]}" -q -o run.h5 box.h5
crom-fullsim "${SC[@]}" -q box.h5 | cat > run.stream          # a stream, through a pipe
crom-fullsim "${SC[@]}" --steps 1 -q -o run1.h5 sphere.h5
crom-sample --points 20 run.h5 -o samples.h5 -q
crom-sample --points all run.h5 -o samples_all.h5 -q
crom-sample --mode interior --points 10 run.h5 run1.h5 -o samples_two.h5 -q
crom-fitfield --basis pod --rank 3 -q -o pod.h5 samples_all.h5
crom-fitfield --rank 2 --epochs 5 -q -o mlp.h5 samples.h5
crom-encode --model pod.h5 -q -o latent.h5 run.h5
crom-encode --model pod.h5 -q run.h5 | cat > latent.stream
crom-modes --youngs 1e6 --pin clamp --count 4 -q -o modes.h5 box.h5
crom-fitfield --objective skinning --weights eigen --handles 2 --mesh box.h5 --youngs 1e6 --pin clamp -q -o skin.h5
crom-cubature --model pod.h5 --scheme random --count 4 -q -o cub.h5 box.h5
crom-cubature --model modes.h5 --scheme all -q -o cub_modes.h5 box.h5
crom-mesh sheet --dims 0.4,0.4,1 --size 0.2 --thickness 0.01 --region top='y>0.15' -q -o sheet.h5
crom-fullsim --pin top --gravity 0,-9.81,1 --steps 2 -q -o sheetrun.h5 sheet.h5
# a shell's models (modes with their derivatives; a neural-modes map with a
# quadratic part, untrained and narrow) and its cubature of triangles and hinges
crom-modes --youngs 1e6 --pin 'y>-0.1' --count 2 --derivatives -q -o sheetmodes.h5 sheet.h5
crom-fitfield --objective neuralmodes --derivatives --mesh sheet.h5 --modes sheetmodes.h5 --rank 2 --steps 0 \
  --width 4 --depth 2 -q -o sheetnm.h5
crom-cubature --model sheetmodes.h5 --scheme all -q -o sheetcub.h5 sheet.h5
# rigid-body scenes (rings with rotations and collision pairs; sliders), a
# scene's run and an energy map of one
crom-scene chain --links 2 -q -o minichain.h5
crom-scene stewart -q -o stewart.h5
crom-fullsim --steps 2 -q -o scenerun.h5 minichain.h5
crom-fitfield --objective energy --mesh minichain.h5 --rank 2 --steps 2 --width 4 --depth 2 -q -o scenemap.h5
# energy maps with a seed state (field/seed) and with a pin condition
# (field/lifts, the conditions attribute)
crom-fitfield --objective energy --mesh box.h5 --pin top --pin bottom --seed-state run.h5 --rank 2 --steps 2 \
  --width 4 --depth 2 -q -o seedmap.h5
crom-fitfield --objective energy --mesh box.h5 --pin bottom --condition 'pin:bottom:y=-0.01:0.01' --rank 2 --steps 2 \
  --width 4 --depth 2 -q -o pinmap.h5
# a run in the modes plus a rigid frame (rigid_frame, q = [q | θ | t]), as a
# file and as a stream
crom-reducedstep --model modes.h5 --rigid-frame --youngs 1e6 --initial-velocity 0.1,0,0 --spin 0,0,1 --steps 2 -q \
  -o framerun.h5
crom-reducedstep --model modes.h5 --rigid-frame --youngs 1e6 --spin 0,0,1 --steps 2 -q | cat > framerun.stream
cp box.h5 sphere.h5 run.h5 run1.h5 cub.h5 sheet.h5 sheetrun.h5 minichain.h5 stewart.h5 scenerun.h5 "$OUT/mesh/"
cp run.h5 run1.h5 sheetrun.h5 scenerun.h5 "$OUT/traj/"
cp samples.h5 samples_all.h5 samples_two.h5 "$OUT/samples/"
cp pod.h5 mlp.h5 modes.h5 skin.h5 sheetmodes.h5 sheetnm.h5 scenemap.h5 seedmap.h5 pinmap.h5 "$OUT/model/"
cp cub.h5 cub_modes.h5 sheetcub.h5 "$OUT/cubature/"
cp box.h5 run.h5 samples.h5 pod.h5 latent.h5 modes.h5 cub.h5 sheet.h5 sheetrun.h5 sheetnm.h5 sheetcub.h5 stewart.h5 \
  scenerun.h5 scenemap.h5 seedmap.h5 pinmap.h5 framerun.h5 "$OUT/check/"
cp run.stream latent.stream framerun.stream "$OUT/stream/"

# ---- frame records after the fuzz_frames header (crom/latent: time, q[3],
# qdot[3] = 7 doubles): complete, incomplete, cut short, no end record
/usr/bin/python3 - "$OUT/frames" <<'PY'
import struct, sys
d = sys.argv[1]
def frame(i, vals):
    return b"FRME" + struct.pack("<IQQ", 0, i, 8 * len(vals)) + struct.pack("<%dd" % len(vals), *vals)
def end(status, n):
    return b"ENDS" + struct.pack("<IQ", status, n)
f = [frame(i, [0.01 * i] + [0.1 * i, -0.2, 0.3] + [1.0, 0.0, -1.0]) for i in range(3)]
seeds = {"complete3": b"".join(f) + end(0, 3), "incomplete2": b"".join(f[:2]) + end(1, 2),
         "empty": end(0, 0), "cut": b"".join(f)[:100], "noend": b"".join(f)}
for k, v in seeds.items():
    open("%s/%s" % (d, k), "wb").write(v)
PY

# ---- surfaces: written by crom-export, and by hand
crom-export --format stl -o box.stl box.h5 2>/dev/null || true
crom-export --format obj -o box.obj box.h5 2>/dev/null || true
crom-export --format stl -o sphere.stl sphere.h5 2>/dev/null || true
crom-export --format obj -o sphere.obj sphere.h5 2>/dev/null || true
for f in box.stl sphere.stl; do [ -s "$f" ] && cp "$f" "$OUT/stl/"; done
for f in box.obj sphere.obj; do [ -s "$f" ] && cp "$f" "$OUT/obj/"; done
/usr/bin/python3 - "$OUT" <<'PY'
import struct, sys
out = sys.argv[1]
V = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
T = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
def normal(t):
    a, b, c = (V[i] for i in t)
    u = [b[k] - a[k] for k in range(3)]; w = [c[k] - a[k] for k in range(3)]
    return (u[1]*w[2]-u[2]*w[1], u[2]*w[0]-u[0]*w[2], u[0]*w[1]-u[1]*w[0])
s = "solid tet\n"
for t in T:
    s += " facet normal %g %g %g\n  outer loop\n" % normal(t)
    for i in t:
        s += "   vertex %g %g %g\n" % V[i]
    s += "  endloop\n endfacet\n"
s += "endsolid tet\n"
open(out + "/stl/tet_ascii.stl", "w").write(s)
b = b"crom fuzz seed: binary tet".ljust(80, b" ") + struct.pack("<I", len(T))
for t in T:
    b += struct.pack("<3f", *normal(t)) + b"".join(struct.pack("<3f", *V[i]) for i in t) + b"\0\0"
open(out + "/stl/tet_binary.stl", "wb").write(b)
o = "# tet\n" + "".join("v %g %g %g\n" % v for v in V) + "vn 0 0 1\nvt 0 0\n"
o += "".join("f %d %d %d\n" % tuple(i + 1 for i in t) for t in T)
open(out + "/obj/tet.obj", "w").write(o)
o2 = "o quad\n" + "".join("v %g %g %g\n" % v for v in V)
o2 += "f 1/1/1 3/1/1 2/1/1\nf -4//1 -3//1 -1//1\nf 1 4 3\nf 2 3 4 1\n"
open(out + "/obj/slashes.obj", "w").write(o2)
open(out + "/live/session.txt", "w").write(
    "# a live session\ndrag top 0,0.6,0 2e5\nstep 20\ndrag #17 0.1,0.5,-0.2\nrelease top\nrelease\n"
    "force top 0,-40,0\nforce 'y>0.4' 0,0,0\npin bottom\nunpin bottom\nschedule cub.h5\ncondition youngs=1e6\nquit\n")
open(out + "/live/page.txt", "w").write(  # a page's messages to crom-view (the harness offers cut.h5)
    "drag #2 0.25,0.75,0.1\ndrag #2 0.3,0.700000001,0.1 1e7\nrelease #2\nschedule cut.h5\nforce y>0.5 0,-1,0\n")
open(out + "/live/bad.txt", "w").write("bogus\ndrag top nan,0,0\nstep -1\nforce top 1,2\ndrag\n\t \n")
open(out + "/cloud/points.xyz", "w").write(
    "# x y z volume\n0 0 0 0.001\n0.1, 0.2, 0.3, 0.002\n-1e-3 2.5 1e2 1e-9 # comment\n\n")
PY

# ---- flag lines: the scenario and stage flags of pipelines/*.mk (make
# variables filled with plausible values), one argument per line for
# fuzz_flags, as a flag file for fuzz_atfile
/usr/bin/python3 - "$TOP/pipelines" "$OUT" <<'PY'
import glob, os, re, shlex, sys
pipes, out = sys.argv[1], sys.argv[2]
vals = {"YOUNGS": "1e6", "DF_YOUNGS": "1e6", "DT": "0.01", "STEPS": "40", "DF_STEPS": "20", "PUSH": "0,-5,0@0:0.2",
        "PLANE": "0.7,0.7,0,-0.6", "MU": "0.5", "SEED": "1", "RANK": "20", "DF_RANK": "4", "BASIS": "mlp",
        "ENCODER": "lsq", "EPOCHS": "100", "MINUTES": "0.5", "DF_TRAIN_STEPS": "100", "DF_MINUTES": "0.2",
        "CUBATURE": "optimized", "COUNT": "300", "SOLVER": "newton", "OUT": "runs/x", "QUIET": "-q"}
lines = set()
for mk in sorted(glob.glob(pipes + "/*.mk")):
    text = open(mk).read().replace("\\\n", " ")
    for line in text.splitlines():
        if "--" not in line:
            continue
        line = re.sub(r"\$\(if [^)]*\)[^)]*\)", "", line)
        line = re.sub(r"\$\((\w+)\)", lambda m: vals.get(m.group(1), "1"), line)
        line = line.split("=", 1)[1] if re.match(r"\s*[A-Z_]+\s*[:?]?=", line) else line
        try:
            words = [w for w in shlex.split(line, comments=True) if not w.startswith("$")]
        except ValueError:
            continue
        words = [w for w in words if "$" not in w and "<" != w and ">" != w]
        if any(w.startswith("--") for w in words):
            lines.add(tuple(words))
for i, words in enumerate(sorted(lines)):
    open("%s/flags/mk%03d" % (out, i), "w").write("\n".join(words) + "\n")
    open("%s/atfile/mk%03d" % (out, i), "w").write(" ".join(shlex.quote(w) for w in words) + "\n")
open(out + "/atfile/comments", "w").write(
    "# a scenario\n--youngs 1e6   # soft\n--pin 'y<-0.45' --velocity \"top=0,-2,0@0:0.1\"\n--plane 0,1,0,-1,0.5\n")
PY
touch "$OUT/.done"
echo "fuzz corpus: $(find "$OUT" -type f ! -name .done | wc -l) seeds in $OUT" >&2
