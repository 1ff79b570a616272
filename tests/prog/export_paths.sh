#!/usr/bin/env bash
# crom-export output paths: -o run.pvd writes run.pvd with its frames in
# run/ beside it (referenced relatively, so the pair can be moved), -o DIR/
# keeps the directory form (DIR/frame.pvd), -o run.xdmf writes run.xdmf and
# run.xdmf.h5 beside it and -o DIR/ the directory form; an old directory
# named run.pvd is not written over.
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
crom-mesh box --size 0.3 --region top='y>0.45' --region bottom='y<-0.45' -o box.h5
SC=(--velocity 'top=0,-2,0@0:0.04' --pin bottom --gravity 0,-9.81,0 --dt 0.01 --steps 5)
crom-fullsim "${SC[@]}" -q -o full.h5 box.h5

# 1. pvd: the file at the path given, frames beside it
crom-export -q -o out/run.pvd full.h5                                  # format from the extension
crom-fullsim "${SC[@]}" -q box.h5 | crom-export --format pvd -q -o piped.pvd   # a stream
crom-export --format pvd -q -o dirform/ full.h5
crom-export --format pvd -q -o plain full.h5                           # no extension: a directory, as before
[ -f out/run.pvd ] && [ -f out/run/run_00005.vtu ] || fail "-o out/run.pvd: out/run.pvd and out/run/run_*.vtu expected"; ok
[ -f piped.pvd ] && [ -f piped/piped_00000.vtu ] || fail "a stream to -o piped.pvd"; ok
[ -f dirform/frame.pvd ] && [ -f dirform/frame_00005.vtu ] || fail "-o dirform/: dirform/frame.pvd expected"; ok
[ -f plain/frame.pvd ] || fail "-o plain: plain/frame.pvd expected"; ok
mv out moved                                                           # relative references survive a move
$PY - <<'PYEOF' || fail "pvd collections refer to their frames relatively"
import os, sys, h5py, meshio, numpy as np, xml.etree.ElementTree as ET
f = h5py.File("full.h5"); U = f["frames/displacement"][()]; t = f["frames/time"][()]
for pvd, prefix in (("moved/run.pvd", "run/run_"), ("piped.pvd", "piped/piped_"),
                    ("dirform/frame.pvd", "frame_"), ("plain/frame.pvd", "frame_")):
    ds = ET.parse(pvd).getroot().findall(".//DataSet")
    if len(ds) != len(t):
        sys.exit("%s: %d datasets for %d frames" % (pvd, len(ds), len(t)))
    for k, d in enumerate(ds):
        name = d.get("file")
        if name != "%s%05d.vtu" % (prefix, k) or os.path.isabs(name):
            sys.exit("%s: frame %d is %s" % (pvd, k, name))
        m = meshio.read(os.path.join(os.path.dirname(pvd), name))
        if not np.array_equal(m.point_data["displacement"], U[k]):
            sys.exit("%s: frame %d displacement differs" % (pvd, k))
        if float(d.get("timestep")) != t[k]:
            sys.exit("%s: frame %d time %s, expected %r" % (pvd, k, d.get("timestep"), t[k]))
print("pvd: 4 layouts, %d frames each, read back exactly" % len(t))
PYEOF
ok
# a bare mesh as -o m.pvd: a collection of one dataset
crom-export -q -o m.pvd box.h5
grep -q 'file="m/m_00000.vtu"' m.pvd && [ -f m/m_00000.vtu ] || fail "bare mesh -o m.pvd"; ok

# 2. xdmf: -o run.xdmf writes run.xdmf + run.xdmf.h5; -o DIR/ a directory
crom-export --format xdmf -q -o sub/run.xdmf full.h5
crom-export --format xdmf -q -o xd.xdmf/ full.h5
[ -f sub/run.xdmf ] && [ -f sub/run.xdmf.h5 ] || fail "-o sub/run.xdmf"; ok
[ -f xd.xdmf/frame.xdmf ] && [ -f xd.xdmf/frame.xdmf.h5 ] || fail "-o xd.xdmf/: directory form"; ok
grep -q '>run.xdmf.h5:/displacement/00005<' sub/run.xdmf || fail "xdmf refers to its heavy data relatively"; ok

# 3. what is refused: an old directory named like the collection, --name
#    with a named collection, a collection with no name
mkdir -p old.pvd
expect_error 73 "old.pvd is a directory" - -- crom-export -o old.pvd full.h5
[ -z "$(ls old.pvd)" ] && [ ! -e old ] || fail "a refused -o old.pvd wrote something"; ok
expect_error 64 "--name names the files in an output directory" x.pvd -- crom-export -o x.pvd --name y full.h5
expect_error 64 "needs a name before .pvd" - -- crom-export -o sub/.pvd full.h5
done_checks
