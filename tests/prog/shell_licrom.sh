#!/usr/bin/env bash
# shell_licrom.sh — the LiCROM stages on a thin shell (issue 16, item 4):
# crom-sample keeps the shell's triangles and thickness in its sources,
# crom-fitfield --basis pod, crom-encode, crom-cubature (optimized, fitted to
# the encoded poses) and crom-reducedstep --model --mesh over it follow
# crom-fullsim on a clamped sheet, in the linear regime and at a large sag;
# and what is refused (interior samples of a shell).
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
crom-mesh sheet --dims 0.6,0.6,1 --size 0.04 --thickness 0.005 --region clamp='y<-0.26' -q -o t.h5
MAT=(--youngs 1e8 --poisson 0.3 --density 200)
for case in small large; do
  if [ $case = small ]; then G=("${MAT[@]}" --pin clamp --gravity 0,0,-0.2 --dt 0.02 --steps 60) r=4
  else G=("${MAT[@]}" --pin clamp --gravity 0,-3,-9.81 --dt 0.02 --steps 60) r=5; fi
  crom-fullsim "${G[@]}" -q -o full_$case.h5 t.h5
  crom-sample --points all -q -o s_$case.h5 full_$case.h5
  crom-info --check s_$case.h5 >/dev/null || fail "crom-info --check s_$case.h5"; ok
  crom-fitfield --basis pod --rank $r -q -o pod_$case.h5 s_$case.h5
  crom-encode --model pod_$case.h5 -q -o lat_$case.h5 full_$case.h5
  crom-cubature --model pod_$case.h5 --scheme optimized --count 100 --poses lat_$case.h5 "${MAT[@]:0:4}" \
    -q -o cub_$case.h5 t.h5
  crom-reducedstep --model pod_$case.h5 --mesh t.h5 --cubature cub_$case.h5 "${G[@]}" -q -o red_$case.h5
  crom-diff --csv d_$case.csv red_$case.h5 full_$case.h5 --model pod_$case.h5 --mesh t.h5 >/dev/null
done
$PY - <<'PYEOF' || fail "the LiCROM stages on a shell"
import h5py, numpy as np
def need(c, what):
    if not c:
        raise SystemExit("check failed: " + what)
s = h5py.File("s_large.h5")
src = s["sources/000"]
need("triangles" in src and "tets" not in src and src["triangles"].attrs["thickness"] == 0.005,
     "the samples keep the shell's triangles and thickness")
need(len(src["triangles"]) == len(h5py.File("t.h5")["triangles"]), "all of its triangles")
# measured: small 1.3e-4 at the end (worst frame 1.6e-3, the first), large
# 6.5e-3 (worst 1.2e-2) over cubatures of 12 and 22 elements
for case, bound, worst in (("small", 1e-3, 1e-2), ("large", 2e-2, 3e-2)):
    e = np.genfromtxt("d_%s.csv" % case, delimiter=",", names=True)["relative_error"]
    sag = np.abs(h5py.File("full_%s.h5" % case)["frames/displacement"][()]).max()
    k = len(h5py.File("cub_%s.h5" % case)["elements"])
    print("%s sag (%.3g m): POD over an optimized cubature of %d elements ends %.2e from crom-fullsim (worst %.2e)"
          % (case, sag, k, e[-1], e.max()))
    need(e[-1] < bound and e.max() < worst and k < 200,
         "%s: within %g of crom-fullsim at the end (%g at every frame) over a small cubature" % (case, bound, worst))
PYEOF
ok
expect_error 64 "--mode interior samples the inside of tets; full_small.h5 is a shell surface \(527 triangles\)" \
  x.h5 -- crom-sample --mode interior --points 50 -o x.h5 full_small.h5
done_checks
