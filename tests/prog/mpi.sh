#!/usr/bin/env bash
# mpi.sh — crom-fitfield trained data-parallel under Open MPI (issue 20):
#   - mpirun -n 2 crom-fitfield --shards 2 trains the model that one process
#     trains with --shards 2 and the same seed: network parameters equal to
#     round-off (relative 1e-5 of the float32 parameters), lsq on vertex
#     samples (shared points) and on interior samples with 3 shards on 2
#     ranks, and pointnet; under mpirun --shards defaults to the ranks. The
#     comparison can fail: another seed, or one shard, gives another model;
#   - rank 0 alone writes and reports, with the doubles allreduced per step
#     (the parameters plus 9); the model's history records the ranks;
#   - bad input: --shards 0, nan, or beyond the frames of a batch give one
#     line, exit 64 and no output; under mpirun every rank stops (none left
#     waiting), one message from crom-fitfield, no output: too many shards,
#     samples on stdin, a rank given other samples, a rank that cannot read
#     its file (that rank's message).
# A crom-fitfield built without MPI fails this test in CI (CI=true) and
# skips it elsewhere.
# asan: skip (SANITIZE=1 builds crom-fitfield without MPI; tests/unit/test_fit.c runs the sharded training under ASan, two threads standing for two ranks)
. "$CROM_TOP/tests/prog/common.bash"
MK="$PY $CROM_TOP/tests/data/mktraj.py"
cd "$TMP"

cannot() {
  if [ "${CI:-}" = true ]; then fail "cannot test MPI training in CI: $*"; fi
  echo "skipped: cannot test MPI training here: $*"
  exit 0
}
# (the help read whole first: grep -q would close the pipe early, and with
# pipefail crom-fitfield's SIGPIPE would read as "built without MPI")
help=$(crom-fitfield --help)
grep -q "built with MPI" <<<"$help" \
  || cannot "crom-fitfield was built without MPI (no mpicc when make ran, or MPI=0; make deps installs Open MPI)"
command -v mpirun >/dev/null 2>&1 || cannot "mpirun is not installed (make deps installs openmpi-bin)"
# Open MPI refuses root unless told; shared memory between the two ranks only
# (no network transports probed), without the cross-process copy that
# containers forbid; two ranks even on a one-core runner; never wait forever
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_btl=self,vader \
  OMPI_MCA_btl_vader_single_copy_mechanism=none OMPI_MCA_plm_rsh_agent=false
mpi2() { timeout 120 mpirun --oversubscribe -n 2 "$@"; }

crom-mesh box --size 0.2 -o box.h5 2>/dev/null
crom-mesh sphere --size 0.15 -o sph.h5 2>/dev/null
$MK box.h5 tb.h5 --frames 24 --modes 4 --rest --seed 1
$MK sph.h5 ts.h5 --frames 24 --modes 4 --seed 2
crom-sample --points 200 --seed 5 tb.h5 ts.h5 -o two.h5 2>/dev/null              # vertex samples, two meshes
crom-sample --mode interior --points 150 --seed 6 tb.h5 -o int.h5 2>/dev/null   # interior samples

# rel A B [DATASET]: |pA - pB| / |pA| of the float32 parameters
rel() { $PY -c "
import h5py, numpy as np, sys
a, b, k = sys.argv[1], sys.argv[2], sys.argv[3]
x, y = (h5py.File(f, 'r')[k][()].astype(np.float64) for f in (a, b))
print('%.3g' % (np.linalg.norm(x - y) / np.linalg.norm(x)))" "$1" "$2" "${3:-field/params}"; }
# small A B WHAT: A <= 1e-5 (round-off of float32 parameters after the steps)
small() { echo "$3: relative difference $1"; awk -v a="$1" 'BEGIN { exit !(a + 0 <= 1e-5) }' || fail "$3: $1 > 1e-5"; ok; }
big() { echo "$3: relative difference $1"; awk -v a="$1" -v b="$2" 'BEGIN { exit !(a + 0 > b + 0) }' || fail "$3: $1 <= $2"; ok; }

# ---- lsq on vertex samples: 2 ranks and one process, 2 shards
FIT=(--rank 4 --epochs 30 --lr 1e-2 --threads 1 --seed 3)
crom-fitfield "${FIT[@]}" --shards 2 -o serial.h5 two.h5 2>/dev/null
mpi2 crom-fitfield "${FIT[@]}" --shards 2 -o par.h5 two.h5 >out.txt 2>err.txt || fail "mpirun: $(cat err.txt)"
[ ! -s out.txt ] || fail "mpirun printed on stdout: $(head -3 out.txt)"; ok
small "$(rel serial.h5 par.h5)" 1e-5 "lsq, 2 shards: 2 ranks against one process"
# rank 0 alone reports: one summary, and the allreduce of each step
[ "$(grep -c 'relative reconstruction error' err.txt)" = 1 ] || fail "one summary expected: $(cat err.txt)"; ok
np=$($PY -c "import h5py; print(h5py.File('par.h5', 'r')['field/params'].shape[0])")
grep -qE "data parallel: 2 MPI ranks, 2 shards a step; each of the [0-9]+ steps allreduced $((np + 9)) doubles" err.txt \
  || fail "no allreduce report of $((np + 9)) doubles per step: $(cat err.txt)"; ok
$PY -c "import h5py, sys; h = h5py.File('par.h5', 'r').attrs['history']; sys.exit(0 if h.endswith('two.h5 # on 2 MPI ranks, --shards 2') else 'history: ' + h[-120:])" \
  || fail "the history does not record the ranks"; ok
crom-info --check par.h5 >/dev/null || fail "the model of 2 ranks is invalid"; ok
# under mpirun the shards are the ranks
mpi2 crom-fitfield "${FIT[@]}" -q -o par2.h5 two.h5 || fail "mpirun without --shards"
small "$(rel serial.h5 par2.h5)" 1e-5 "lsq, mpirun without --shards: against one process with 2 shards"
# the comparison means something: another seed, or one shard, is another model
crom-fitfield "${FIT[@]}" --shards 2 --seed 4 -q -o seed4.h5 two.h5
big "$(rel serial.h5 seed4.h5)" 0.1 "lsq, 2 shards: another seed"
crom-fitfield "${FIT[@]}" -q -o one.h5 two.h5
big "$(rel serial.h5 one.h5)" 1e-3 "lsq: 1 shard against 2"

# ---- interior samples (points of their own per frame), 3 shards on 2 ranks
FI=(--rank 4 --epochs 10 --lr 1e-2 --batch 12 --points-per-step 40 --threads 1 --shards 3)
crom-fitfield "${FI[@]}" -q -o iserial.h5 int.h5
mpi2 crom-fitfield "${FI[@]}" -q -o ipar.h5 int.h5 || fail "mpirun on interior samples"
small "$(rel iserial.h5 ipar.h5)" 1e-5 "lsq, interior samples, 3 shards: 2 ranks against one process"

# ---- pointnet: the encoder is trained on the ranks' frames too
FP=(--rank 4 --encoder pointnet --epochs 2 --encoder-points 50 --threads 1 --shards 2)
crom-fitfield "${FP[@]}" -q -o pserial.h5 two.h5
mpi2 crom-fitfield "${FP[@]}" -q -o ppar.h5 two.h5 || fail "mpirun with pointnet"
small "$(rel pserial.h5 ppar.h5)" 1e-5 "pointnet field, 2 shards: 2 ranks against one process"
small "$(rel pserial.h5 ppar.h5 encoder/params)" 1e-5 "pointnet encoder, 2 shards: 2 ranks against one process"

# ---- bad input, one process: one line, exit 64, no output
for v in 0 nan; do
  expect_error 64 "^crom-fitfield: --shards: " bad.h5 -- crom-fitfield --rank 4 --epochs 2 --shards "$v" -o bad.h5 two.h5
done
expect_error 64 "^crom-fitfield: --shards 17 exceeds the 16 frames of a batch \(--batch 16, 48 frames in the samples\)" \
  bad.h5 -- crom-fitfield --rank 4 --epochs 2 --shards 17 -o bad.h5 two.h5
expect_error 64 "^crom-fitfield: --shards applies to a neural field" bad.h5 -- \
  crom-fitfield --basis pod --rank 4 --shards 2 -o bad.h5 two.h5

# ---- bad input under mpirun: every rank stops with the exit code, one
# message from crom-fitfield (mpirun adds its own), no output file
# mpi_error CODE PATTERN -- mpirun arguments...
mpi_error() {
  local code=$1 pat=$2; shift 3
  local rc=0
  timeout 120 mpirun --oversubscribe "$@" >out.txt 2>err.txt </dev/null || rc=$?
  [ "$rc" -eq "$code" ] || fail "mpirun $* exited $rc, expected $code: $(cat err.txt)"
  [ "$(grep -c '^crom-fitfield: ' err.txt)" = 1 ] || fail "mpirun $*: one message expected: $(cat err.txt)"
  grep -qE "^crom-fitfield: $pat" err.txt || fail "mpirun $*: no /$pat/ in $(cat err.txt)"
  [ ! -e bad.h5 ] && ! ls -a | grep -q '\.tmp$' || fail "mpirun $* left an output file"
  ok
}
mpi_error 64 "--shards: 0 is out of range" -- -n 2 crom-fitfield --rank 4 --shards 0 -o bad.h5 two.h5
mpi_error 64 "--shards 17 exceeds the 16 frames of a batch" -- -n 2 crom-fitfield --rank 4 --shards 17 -o bad.h5 two.h5
mpi_error 64 "under MPI every rank reads the samples: give SAMPLES as a file" -- \
  -n 2 bash -c 'exec crom-fitfield --rank 4 --epochs 2 -o bad.h5 < two.h5'
mpi_error 64 "under MPI give the model a file, -o OUT" -- -n 2 crom-fitfield --rank 4 --epochs 2 two.h5
mpi_error 64 "2 MPI ranks train a neural field .* --basis pod runs in one process" -- \
  -n 2 crom-fitfield --basis pod --rank 4 -o bad.h5 two.h5
# ranks given different things (MPMD: one command per rank)
cp two.h5 other.h5 && crom-sample --points 200 --seed 7 tb.h5 ts.h5 -o other.h5 2>/dev/null
mpi_error 64 "the 2 processes were given different samples or training options" -- \
  -n 1 crom-fitfield --rank 4 --epochs 2 -o bad.h5 two.h5 : -n 1 crom-fitfield --rank 4 --epochs 2 -o bad.h5 other.h5
mpi_error 66 "missing.h5: No such file" -- \
  -n 1 crom-fitfield --rank 4 --epochs 2 -o bad.h5 two.h5 : -n 1 crom-fitfield --rank 4 --epochs 2 -o bad.h5 missing.h5
done_checks
