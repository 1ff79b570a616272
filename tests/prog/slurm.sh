#!/usr/bin/env bash
# Pipelines on a Slurm cluster (issue 20): a one-node cluster from Debian's
# packages (munged, slurmctld, slurmd, a generated slurm.conf, all under a
# temporary directory, on ports of its own), the shapes experiment run through
# it with SUBMIT='srun ...' and two parallel jobs, and its outputs compared
# byte for byte with the same run made locally; then the same pipeline inside
# an sbatch allocation (the README's example), and the failures: a missing
# SUBMIT command, a job that fails, an unreachable controller.
# Skipped with a message where the daemons cannot run (not root, not
# installed) unless CI=true, where it must run.
# asan: skip (runs the shapes pipeline's programs as jobs: what it tests is pipelines/common.mk and submit.sh, not crom's code, whose stages run under ASan elsewhere)
. "$CROM_TOP/tests/prog/common.bash"

cannot() {
  if [ "${CI:-}" = true ]; then fail "cannot start a Slurm cluster in CI: $*"; fi
  echo "skipped: cannot start a Slurm cluster here: $*"
  exit 0
}
[ "$(id -u)" -eq 0 ] || cannot "not root (munged and slurmd run as root in this test)"
for c in munged slurmctld slurmd srun sbatch sinfo; do
  command -v $c >/dev/null 2>&1 || cannot "$c is not installed (make deps installs it)"
done

C="$TMP/cluster"
mkdir -p "$C/munge" "$C/spool/ctld" "$C/spool/d" "$C/log"
chmod 700 "$C/munge"
head -c 1024 /dev/urandom >"$C/munge/munge.key"
chmod 600 "$C/munge/munge.key"
HOST=$(hostname -s)
# two free ports for the controller and the node daemon
read -r PCTL PD < <($PY -c "
import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(('127.0.0.1', 0))
print(*[x.getsockname()[1] for x in s])")
cat >"$C/slurm.conf" <<EOF
ClusterName=cromtest
SlurmctldHost=$HOST
SlurmctldPort=$PCTL
SlurmdPort=$PD
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$C/munge/socket
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$C/spool/ctld
SlurmdSpoolDir=$C/spool/d
SlurmctldPidFile=$C/ctld.pid
SlurmdPidFile=$C/d.pid
SlurmctldLogFile=$C/log/ctld.log
SlurmdLogFile=$C/log/d.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MessageTimeout=5
NodeName=$HOST CPUs=2 RealMemory=2000 State=UNKNOWN
PartitionName=crom Nodes=$HOST Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$C/slurm.conf"

teardown() {
  for p in "$C/d.pid" "$C/ctld.pid"; do [ -s "$p" ] && kill "$(cat "$p")" 2>/dev/null || true; done
  [ -S "$C/munge/socket" ] && munged --stop --socket="$C/munge/socket" >/dev/null 2>&1 || true
  sleep 0.5
  rm -rf "$TMP"
}
trap teardown EXIT

munged --force --key-file="$C/munge/munge.key" --socket="$C/munge/socket" --pid-file="$C/munge/pid" \
  --log-file="$C/munge/log" --seed-file="$C/munge/seed" || cannot "munged did not start: $(tail -2 "$C/munge/log" 2>/dev/null)"
slurmctld -c -f "$C/slurm.conf" || cannot "slurmctld did not start: $(tail -2 "$C/log/ctld.log" 2>/dev/null)"
slurmd -f "$C/slurm.conf" || cannot "slurmd did not start: $(tail -2 "$C/log/d.log" 2>/dev/null)"
up=0
for _ in $(seq 1 60); do
  if sinfo -h -o '%t' 2>/dev/null | grep -qx idle; then up=1; break; fi
  sleep 0.5
done
[ $up = 1 ] || cannot "the node did not come up: $(sinfo 2>&1 | tail -1); $(tail -2 "$C/log/d.log" 2>/dev/null)"
out=$(srun -N1 -n1 -c1 echo job-ran 2>&1) || fail "srun of a trivial job: $out"
[ "$out" = job-ran ] || fail "srun printed '$out'"; ok
echo "cluster up: $HOST, controller port $PCTL"

MK="make --no-print-directory -f $CROM_TOP/pipelines/shapes.mk"
ARGS=(TRAIN="2 box" TEST="4" SIZE=0.2 STEPS=8 EPOCHS=150 RANK=6 COUNT=30 POINTS=80 QUIET=-q)
# the same output directory for both runs (the programs record their command
# lines, paths included), moved aside after each
O="$TMP/shapes"
$MK -j2 OUT="$O" "${ARGS[@]}" >"$TMP/local.log" 2>&1 || { tail -20 "$TMP/local.log"; fail "local shapes run"; }
mv "$O" "$TMP/local"
# every stage a job; the training stage asks for its own resources (one core
# here: the local run's bytes need the same thread count)
$MK -j2 OUT="$O" "${ARGS[@]}" SUBMIT='srun -N1 -n1 -c1 --job-name=crom' SUBMIT_FITFIELD='-c1 --mem=1000' \
  SUBMIT_FULLSIM='--mem=1000' >"$TMP/slurm.log" 2>&1 || { tail -20 "$TMP/slurm.log"; fail "shapes run through Slurm"; }
mv "$O" "$TMP/slurm"

# the jobs ran under Slurm: the controller counted one per line that runs a
# crom program (and none for the others: mkdir, tables), and two ran at once
# at some point (-j2)
njobs=$(grep -c 'sched: _slurm_rpc_allocate_resources JobId=' "$C/log/ctld.log" || true)
nprog=$(grep -cE '(^|[^[:alnum:]_.-])crom-[a-z]+ ' "$TMP/local.log" || true)
[ "$nprog" -ge 10 ] && [ "$njobs" -eq "$nprog" ] || fail "the controller allocated $njobs jobs for $nprog program lines"; ok
echo "jobs: $njobs allocated, $nprog program lines in the local log"
$PY - "$C/log/ctld.log" <<'PYEOF' || fail "no two jobs ran at the same time"
import re, sys
# _job_complete lines and allocations in order: count the running jobs
run = peak = 0
for l in open(sys.argv[1]):
    if "_slurm_rpc_allocate_resources JobId=" in l: run += 1; peak = max(peak, run)
    elif re.search(r"_job_complete: JobId=\d+ done", l): run -= 1
if peak < 2: raise SystemExit("peak %d" % peak)
print("at most %d jobs at once" % peak)
PYEOF
ok

# byte-identical results: every HDF5 file, picture, ParaView file and error
# report; the CSV statistics and tables hold wall times and are not compared
n=0
while IFS= read -r f; do
  case "$f" in *.csv|*/table.md|*/summary.txt|*/rows.txt) continue ;; esac
  [ -f "$TMP/slurm/$f" ] || fail "the Slurm run did not make $f"
  cmp -s "$TMP/local/$f" "$TMP/slurm/$f" || fail "$f differs between the local and the Slurm run"
  n=$((n + 1))
done < <(cd "$TMP/local" && find . -type f | sort)
[ $n -ge 30 ] || fail "only $n files compared"; ok
echo "local and Slurm runs: $n files identical (${SECONDS}s)"

# the README's sbatch form: make inside an allocation of two tasks, each stage
# a job step (srun within the allocation)
cat >"$TMP/job.sh" <<EOF
#!/bin/bash
#SBATCH --ntasks=2 --cpus-per-task=1
set -euo pipefail
$MK -j2 OUT="$O" ${ARGS[*]@Q} SUBMIT='srun -N1 -n1 -c1 --exclusive'
echo done >"$TMP/job.done"
EOF
# (sbatch --wait polls at growing intervals: watch the queue instead)
jid=$(cd "$TMP" && sbatch --parsable -o "$TMP/sbatch.out" "$TMP/job.sh") || fail "sbatch: $jid"
for _ in $(seq 1 600); do
  squeue -h -j "$jid" 2>/dev/null | grep -q . || break
  sleep 0.2
done
[ -s "$TMP/job.done" ] || { tail -20 "$TMP/sbatch.out"; fail "the sbatch job did not finish its make"; }
cmp -s "$TMP/local/model.h5" "$O/model.h5" || fail "the sbatch run's model differs from the local one"; ok
cmp -s "$TMP/local/red-4.h5" "$O/red-4.h5" || fail "the sbatch run's reduced run differs from the local one"; ok
echo "sbatch run: identical model and reduced run (${SECONDS}s)"

# failures. A job that fails fails its target; make reruns only what failed:
# break the model of the finished sbatch run, and the rerun redoes the stages
# after it only
m0=$(stat -c %Y "$O/full-2.h5"); sleep 1
head -c 4096 /dev/urandom >"$O/model.h5"; touch "$O/model.h5"; rm -f "$O/poses-box.h5"
rc=0; $MK OUT="$O" "${ARGS[@]}" SUBMIT='srun -N1 -n1 -c1' >"$TMP/fail.log" 2>&1 || rc=$?
[ $rc -ne 0 ] || fail "make succeeded on a corrupt model through Slurm"; ok
grep -q "crom-encode: .*model.h5 is not a crom file" "$TMP/fail.log" || fail "stage message: $(tail -3 "$TMP/fail.log")"; ok
grep -qE 'srun: error: .*(task 0: Exited with exit code|Exited with exit code)' "$TMP/fail.log" || fail "srun did not report the job's failure"; ok
[ ! -e "$O/poses-box.h5" ] || fail "a stale poses file was left behind"; ok
! ls -a "$O" | grep -q '\.tmp$' || fail "temporary files left behind"; ok
[ "$(stat -c %Y "$O/full-2.h5")" = "$m0" ] || fail "a full run that had not failed was redone"; ok

# a missing SUBMIT command: one clear line, make fails, no output
rm -rf "$O"
rc=0; $MK OUT="$O" "${ARGS[@]}" SUBMIT='no-such-srun -N1' >"$TMP/bad.log" 2>&1 || rc=$?
[ $rc -ne 0 ] || fail "make succeeded with a missing SUBMIT command"; ok
grep -q "SUBMIT='no-such-srun -N1': 'no-such-srun' is not a command on this machine" "$TMP/bad.log" \
  || fail "missing command message: $(tail -3 "$TMP/bad.log")"; ok
! find "$O" -name '*.h5' 2>/dev/null | grep -q . || fail "HDF5 files written with a missing SUBMIT command"; ok

# an unreachable controller: srun gives up with its own message and make fails
dead=$($PY -c "
import socket
s = socket.socket(); s.bind(('127.0.0.1', 0)); print(s.getsockname()[1])")
sed -e "s/^SlurmctldPort=.*/SlurmctldPort=$dead/" "$C/slurm.conf" >"$C/dead.conf"
rm -rf "$O"
rc=0; SLURM_CONF="$C/dead.conf" timeout 120 $MK OUT="$O" "${ARGS[@]}" SUBMIT='srun -N1 -n1 -c1' >"$TMP/dead.log" 2>&1 || rc=$?
[ $rc -ne 0 ] && [ $rc -ne 124 ] || fail "make with an unreachable controller: exit $rc"; ok
grep -qiE 'srun: error: .*(Unable to contact slurm controller|Unable to allocate resources|connect)' "$TMP/dead.log" \
  || fail "unreachable controller message: $(tail -3 "$TMP/dead.log")"; ok
! find "$O" -name '*.h5' 2>/dev/null | grep -q . || fail "HDF5 files written with no controller"; ok
echo "failures: missing command, failed job, unreachable controller (${SECONDS}s)"
done_checks
