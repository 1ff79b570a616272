#!/usr/bin/env bash
# Regression tests of issue 15 (defects 4, 6, 7 and part of 3): text output
# that cannot be written, non-finite frames, and files that `crom-info
# --check` must refuse because the programs refuse them. Each case must end
# with the documented exit status and one line on stderr naming the problem
# (run under ASan/UBSan by `make test SANITIZE=1`).
. "$CROM_TOP/tests/prog/common.bash"
O="$TMP/out"; mkdir -p "$O"
cd "$TMP"

# expect_full CODE PATTERN -- command...: like expect_error, with stdout on
# /dev/full (every write to it fails with ENOSPC).
expect_full() {
  local code=$1 pat=$2; shift 3
  local rc=0
  "$@" >/dev/full 2>"$TMP/stderr" </dev/null || rc=$?
  [ "$rc" -eq "$code" ] || fail "'$*' >/dev/full exited $rc, expected $code; stderr: $(cat "$TMP/stderr")"
  local lines; lines=$(wc -l <"$TMP/stderr")
  [ "$lines" -eq 1 ] || fail "'$*' >/dev/full printed $lines lines on stderr, expected one: $(cat "$TMP/stderr")"
  grep -qE -e "$pat" "$TMP/stderr" || fail "'$*' >/dev/full: message '$(cat "$TMP/stderr")' does not match /$pat/"
  ok
}

crom-mesh box --size 0.25 --region bottom='y<-0.4' -o m.h5
crom-fullsim --pin bottom --steps 3 --dt 0.01 -q -o run.h5 m.h5
crom-fullsim --pin bottom --steps 3 --dt 0.01 -q m.h5 >run.stream
crom-modes --pin bottom --count 3 -q -o modes.h5 m.h5

# ---- defect 4: a failed write to stdout is an I/O error (74), not success
full="cannot write to stdout: No space left on device\$"
n=0
for p in "$CROM_BINDIR"/crom-*; do
  [ -x "$p" ] || continue
  name=$(basename "$p")
  for flag in --help --help-man --version; do
    expect_full 74 "^$name: $full" -- "$p" $flag
    "$p" $flag >"$O/help.txt" || fail "$name $flag exits non-zero on a writable stdout"
  done
  n=$((n + 1))
done
[ "$n" -ge 13 ] || fail "only $n programs found in $CROM_BINDIR"
text_modes=(
  "crom-info m.h5"
  "crom-info --check run.h5"
  "crom-info --frames run.h5"
  "crom-info --frames run.stream"
  "crom-diff run.h5 run.h5"
  "crom-diff --csv - run.h5 run.h5 -q"
  "crom-metrics --samples 4 --mesh m.h5 modes.h5"
)
for c in "${text_modes[@]}"; do
  prog=${c%% *}
  # (a file output on stdout, as crom-diff --csv -, is named like the binary
  # outputs: "stdout: ...", tests/prog/faults.sh)
  expect_full 74 "^$prog: (cannot write to )?stdout: No space left on device\$" -- $c
  $c >"$O/text.txt" || fail "'$c' exits non-zero on a writable stdout"
  [ -s "$O/text.txt" ] || fail "'$c' printed nothing"
done
# through a pipe, and when --max-error is exceeded (exit 1 otherwise)
expect_full 74 "^crom-info: $full" -- bash -c "crom-info --frames - <run.stream"
crom-fullsim --pin bottom --steps 3 --dt 0.01 --gravity 0,-20,0 -q -o run2.h5 m.h5
rc=0; crom-diff --max-error 1e-9 run.h5 run2.h5 >/dev/null 2>&1 || rc=$?
[ "$rc" -eq 1 ] || fail "crom-diff --max-error on differing runs exited $rc, expected 1"
expect_full 74 "^crom-diff: $full" -- crom-diff -q --max-error 1e-9 run.h5 run2.h5

# ---- defect 6: a non-finite frame is bad data (65) for every reader of
# frames, with the same message (crom_result_check_frame)
crom-encode --model modes.h5 -q -o lat.h5 run.h5
crom-cubature --model modes.h5 --scheme optimized --poses lat.h5 -q -o cub.h5 m.h5
$PY - <<'PYEOF'
import shutil, h5py, numpy as np
shutil.copy("run.h5", "nan.h5")
with h5py.File("nan.h5", "r+") as f: f["frames/displacement"][1, 2, 0] = np.nan
shutil.copy("run.h5", "infv.h5")
with h5py.File("infv.h5", "r+") as f: f["frames/velocity"][2, 5, 1] = np.inf
shutil.copy("lat.h5", "latnan.h5")
with h5py.File("latnan.h5", "r+") as f: f["frames/q"][2, 1] = np.nan
PYEOF
nanu="nan.h5: frame 1 has a non-finite displacement at vertex 2"
expect_error 65 "^crom-export: $nanu\$" "$O/n.vtu" -- crom-export --format vtu -o "$O/n.vtu" nan.h5
expect_error 65 "^crom-diff: $nanu\$" "$O/n.csv" -- crom-diff --csv "$O/n.csv" nan.h5 run.h5
expect_error 65 "^crom-diff: $nanu\$" "$O/n.csv" -- crom-diff --csv "$O/n.csv" run.h5 nan.h5
expect_error 65 "^crom-sample: $nanu\$" "$O/s.h5" -- crom-sample --points 10 -o "$O/s.h5" nan.h5
expect_error 65 "^crom-encode: $nanu\$" - -- crom-encode --model modes.h5 -o "$O/l.h5" nan.h5
expect_error 65 "^crom-export: infv.h5: frame 2 has a non-finite velocity at vertex 5\$" "$O/v.vtu" -- \
  crom-export --format vtu -o "$O/v.vtu" infv.h5
nanq="latnan.h5: frame 2 has a non-finite q at index 1"
expect_error 65 "^crom-export: $nanq\$" "$O/q.vtu" -- crom-export --format vtu --model modes.h5 --mesh m.h5 \
  --youngs 1e6 --poisson 0.3 -o "$O/q.vtu" latnan.h5
expect_error 65 "^crom-cubature: $nanq\$" "$O/c.h5" -- crom-cubature --model modes.h5 --scheme optimized \
  --poses latnan.h5 -o "$O/c.h5" m.h5
expect_error 65 "^crom-reducedstep: $nanq\$" "$O/r.h5" -- crom-reducedstep --cubature cub.h5 --pin bottom \
  --steps 2 --init latnan.h5 --init-frame 2 -o "$O/r.h5"
crom-reducedstep --cubature cub.h5 --pin bottom --steps 2 --init latnan.h5 --init-frame 1 -q -o "$O/r.h5" \
  || fail "--init from a finite frame of a file with a NaN in another frame is refused"
# --check says the same
crom-info --check nan.h5 infv.h5 latnan.h5 >"$O/check.txt" 2>/dev/null && fail "--check passed NaN frames"
for m in "$nanu" "infv.h5: frame 2 has a non-finite velocity at vertex 5" "$nanq"; do
  grep -qE "^$m\$" "$O/check.txt" || fail "--check does not report '$m': $(cat "$O/check.txt")"; ok
done

# ---- defect 7: crom-info --check refuses what the programs refuse, with
# one line naming the dataset and the problem; the program says the same
crom-sample --points 20 -q -o s.h5 run.h5
crom-fitfield --rank 2 --epochs 3 -q -o mlp.h5 s.h5
mkdir -p bad
$PY - <<'PYEOF'
import shutil, h5py, numpy as np
def cp(src, dst, fn):
    shutil.copy(src, "bad/" + dst)
    with h5py.File("bad/" + dst, "r+") as f:
        fn(f)
def put(path, idx, val):
    def fn(f):
        a = f[path][()]; a[idx] = val; f[path][...] = a
    return fn
def degen(path):
    def fn(f):
        t = f[path][()]; t[5, 3] = t[5, 0]; f[path][...] = t
    return fn
def delattr(path, name):
    return lambda f: f[path].attrs.__delitem__(name)
cp("run.h5", "traj_tet_oob.h5", put("mesh/tets", (3, 2), 100000))
cp("cub.h5", "cub_tet_oob.h5", put("mesh/tets", (3, 2), 100000))
cp("cub.h5", "cub_tet_neg.h5", put("mesh/tets", (3, 2), -1))
cp("modes.h5", "model_tet_oob.h5", put("field/mesh/tets", (3, 2), 100000))
cp("s.h5", "samples_tet_oob.h5", put("sources/000/tets", (3, 2), 100000))
cp("cub.h5", "cub_tet_degen.h5", degen("mesh/tets"))
cp("modes.h5", "model_tet_degen.h5", degen("field/mesh/tets"))
cp("s.h5", "samples_tet_degen.h5", degen("sources/000/tets"))
cp("cub.h5", "cub_region_neg.h5", put("mesh/regions/bottom", -1, -1))
cp("cub.h5", "cub_region_big.h5", put("mesh/regions/bottom", -1, 1000000))
cp("cub.h5", "cub_elem_oob.h5", put("elements", 0, 5000))
cp("cub.h5", "cub_weight_neg.h5", put("weights", 0, -1.0))
cp("cub.h5", "cub_surface_oob.h5", put("surface", 0, 5000))
cp("s.h5", "samples_vertex_oob.h5", put("vertex", (1, 3), 5000))
cp("s.h5", "samples_vertex_neg.h5", put("vertex", (1, 3), -7))
cp("s.h5", "samples_source_oob.h5", put("frame_source", 2, 3))
cp("mlp.h5", "model_width_neg.h5", put("field/widths", 2, -1))
cp("mlp.h5", "model_width_big.h5", put("field/widths", 2, 2**31 - 1))
cp("m.h5", "mesh_no_units.h5", delattr("vertices", "units"))
cp("m.h5", "mesh_no_desc.h5", delattr("tets", "description"))
cp("run.h5", "traj_no_units.h5", delattr("frames/displacement", "units"))
cp("cub.h5", "cub_no_desc.h5", delattr("W", "description"))
cp("mlp.h5", "model_no_units.h5", delattr("field/params", "units"))
cp("s.h5", "samples_no_desc.h5", delattr("vertex", "description"))
PYEOF
# expect_check FILE PATTERN [PROGRAM ARGS...]: --check exits 65 with one
# line on stderr and a violation line "FILE: PATTERN" on stdout; the program
# (its output, if any, under $O) exits 65 with "PROG: FILE: PATTERN".
expect_check() {
  local f=bad/$1 pat=$2; shift 2
  local rc=0
  crom-info --check "$f" >"$TMP/check.out" 2>"$TMP/check.err" || rc=$?
  [ "$rc" -eq 65 ] || fail "crom-info --check $f exited $rc, expected 65: $(cat "$TMP/check.out")"
  [ "$(wc -l <"$TMP/check.err")" -eq 1 ] || fail "crom-info --check $f: $(cat "$TMP/check.err")"
  grep -qE "^$f: $pat\$" "$TMP/check.out" || fail "crom-info --check $f does not say /$pat/: $(cat "$TMP/check.out")"
  ok
  [ $# -eq 0 ] || expect_error 65 "^$1: $f: $pat\$" "$O/x.out" -- "$@" "$f"
}
cub=(crom-reducedstep --pin bottom --steps 2 -o "$O/x.out" --cubature)
mdl=(crom-metrics --samples 3 --mesh m.h5)
smp=(crom-fitfield --rank 2 --epochs 2 -o "$O/x.out")
exp=(crom-export --format vtu -o "$O/x.out")
tet_oob="tet 3 refers to vertex 100000, but there are 146 vertices"
degen="tet 5 has non-positive volume 0 m\^3 \(tets must be positively oriented\)"
expect_check traj_tet_oob.h5 "/mesh: $tet_oob" "${exp[@]}"
expect_check cub_tet_oob.h5 "/mesh: $tet_oob" "${cub[@]}"
expect_check cub_tet_neg.h5 "/mesh: tet 3 refers to vertex -1, but there are 146 vertices" "${cub[@]}"
expect_check model_tet_oob.h5 "field/mesh: $tet_oob" "${mdl[@]}"
expect_check samples_tet_oob.h5 "/sources/000: $tet_oob" "${smp[@]}"
expect_check cub_tet_degen.h5 "/mesh: $degen" "${cub[@]}"
expect_check model_tet_degen.h5 "field/mesh: $degen" "${mdl[@]}"
expect_check samples_tet_degen.h5 "/sources/000: $degen" "${smp[@]}"
expect_check cub_region_neg.h5 "/mesh: region 'bottom' refers to vertex -1, but there are 146 vertices" "${cub[@]}"
expect_check cub_region_big.h5 "/mesh: region 'bottom' refers to vertex 1000000, but there are 146 vertices" "${cub[@]}"
expect_check cub_elem_oob.h5 "/elements\[0\] = 5000 is not a tet of the mesh \(0..409\)" "${cub[@]}"
expect_check cub_weight_neg.h5 "/weights\[0\] = -1 is not a non-negative finite weight" "${cub[@]}"
expect_check cub_surface_oob.h5 "/surface\[0\] = 5000 is not a vertex of the mesh \(0..145\)" "${cub[@]}"
expect_check samples_vertex_oob.h5 "/vertex: frame 1 sample 3 names vertex 5000 of a 146-vertex mesh" "${smp[@]}"
expect_check samples_vertex_neg.h5 "/vertex: frame 1 sample 3 names vertex -7 of a 146-vertex mesh" "${smp[@]}"
expect_check samples_source_oob.h5 "/frame_source: frame 2 names source 3, but there are 1" "${smp[@]}"
expect_check model_width_neg.h5 "field/widths: network width\[2\] = -1 must be in 1..1048576" "${mdl[@]}"
expect_check model_width_big.h5 "field/widths: network width\[2\] = 2147483647 must be in 1..1048576" "${mdl[@]}"
expect_check mesh_no_units.h5 "/vertices has no string attribute 'units' \(expected 'm'\)"
expect_check mesh_no_desc.h5 "/tets has no description"
expect_check traj_no_units.h5 "/frames/displacement has no string attribute 'units' \(expected 'm'\)"
expect_check cub_no_desc.h5 "/W has no description"
expect_check model_no_units.h5 "/field/params has no string attribute 'units' \(expected '1'\)"
expect_check samples_no_desc.h5 "/vertex has no description"
# the good files pass
crom-info --check m.h5 run.h5 cub.h5 modes.h5 mlp.h5 s.h5 lat.h5 >/dev/null || fail "--check refuses good files"; ok

# ---- defect 3 (validation's share): a 15 KB mesh whose /vertices declares
# [1e8, 3] (chunked, never written) is refused before anything is allocated
# from it, in a bounded time and memory; a deflated dataset of a real size
# still passes
$PY - <<'PYEOF'
import h5py
src = h5py.File("m.h5", "r")
def copy(f, name, **kw):
    d = f.create_dataset(name, data=src[name][()], **kw)
    for k, v in src[name].attrs.items(): d.attrs[k] = v
for out in ("huge_vertices", "deflated"):
    with h5py.File("bad/%s.h5" % out, "w") as f:
        for k, v in src.attrs.items(): f.attrs[k] = v
        if out == "huge_vertices":
            d = f.create_dataset("vertices", shape=(100000000, 3), dtype="f8", chunks=(1024, 3))
            for k, v in src["vertices"].attrs.items(): d.attrs[k] = v
        else:
            copy(f, "vertices", compression="gzip", chunks=(16, 3))
        copy(f, "tets")
        for r in src["regions"]:
            copy(f, "regions/" + r)
PYEOF
[ "$(stat -c %s bad/huge_vertices.h5)" -lt 20000 ] || fail "the declared-huge mesh is not small"
# (peak memory measured, not limited with ulimit -v, which ASan cannot run under)
rc=0; $PY - "$TMP/rss" timeout 10 crom-info --check bad/huge_vertices.h5 >"$TMP/check.out" 2>"$TMP/check.err" \
  <<'PYEOF' || rc=$?
import resource, subprocess, sys
rc = subprocess.call(sys.argv[2:], stdin=subprocess.DEVNULL)
open(sys.argv[1], "w").write("%d\n" % resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
sys.exit(rc)
PYEOF
[ "$rc" -eq 65 ] || fail "--check on a mesh declaring 3e8 values exited $rc (in 10 s): $(cat "$TMP/check.err")"
rss=$(tail -n 1 "$TMP/rss")
[ "$rss" -lt 400000 ] || fail "--check on a mesh declaring 3e8 values peaked at $rss KB"
# (the contained check of every HDF5 input refuses it first; the validator's
# own bound stands behind it)
grep -qE "^bad/huge_vertices.h5: /vertices declared 300000000 values but the file stores only 0 bytes\$" "$TMP/check.out" \
  || grep -qE "huge_vertices.h5: corrupt HDF5 file: dataset 'vertices' declares 2400000000 bytes but the file stores 0\$" "$TMP/check.err" \
  || fail "--check does not name the oversized dataset: $(cat "$TMP/check.out" "$TMP/check.err")"
ok
crom-info --check bad/deflated.h5 >/dev/null || fail "--check refuses a deflated mesh"; ok

done_checks
