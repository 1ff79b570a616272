#!/usr/bin/env bash
# submit.sh — the recipe shell of the experiment Makefiles when SUBMIT is set
# (pipelines/common.mk): every recipe line that runs a crom program becomes
# one job of the cluster's scheduler, run by the command in SUBMIT, e.g.
#
#   make -f pipelines/shapes.mk -j64 SUBMIT='srun -N1 -n1 -c1' SUBMIT_FULLSIM='--mem=8G'
#
# make calls it as it calls bash: `submit.sh -euo pipefail -c LINE`. A line
# that names a crom program (crom-fullsim, crom-fitfield, ...) runs as
#
#   $CROM_SUBMIT $CROM_SUBMIT_<PROGRAM>... /bin/bash -euo pipefail -c LINE
#
# on a node that sees the same directories (a shared file system), with the
# per-program options of every program the line names appended (srun takes
# the last of a repeated option, so SUBMIT_FITFIELD='-c4' overrides SUBMIT's
# -c1 for training). Inside the job CROM_THREADS is the job's cores
# (SLURM_CPUS_PER_TASK), so a program given no --threads uses them. Other
# lines (mkdir, tables, pictures' glue) run here, as without SUBMIT. The
# line's exit status is the job's (srun returns the task's), so a failed job
# fails its make target, and make deletes what the target had written
# (.DELETE_ON_ERROR in common.mk); the programs themselves write -o files
# under a temporary name and rename them when complete.
set -u
flags=()
while [ $# -gt 0 ] && [ "$1" != "-c" ]; do flags+=("$1"); shift; done
if [ $# -lt 2 ]; then
  echo "crom: submit.sh: expected '-c LINE' as make's recipe shell" >&2
  exit 2
fi
line=$2
progs=$(grep -oE '(^|[^[:alnum:]_./-])crom-[a-z]+' <<<"$line" | grep -oE 'crom-[a-z]+' | sort -u)
if [ -z "$progs" ]; then
  exec /bin/bash "${flags[@]}" -c "$line"
fi
read -r -a cmd <<<"${CROM_SUBMIT:-}"
if [ ${#cmd[@]} -eq 0 ]; then
  echo "crom: submit.sh: CROM_SUBMIT is empty (set SUBMIT on make's command line)" >&2
  exit 2
fi
if ! command -v "${cmd[0]}" >/dev/null 2>&1; then
  echo "crom: SUBMIT='${CROM_SUBMIT}': '${cmd[0]}' is not a command on this machine" >&2
  exit 127
fi
for p in $progs; do
  v="CROM_SUBMIT_$(tr 'a-z-' 'A-Z_' <<<"${p#crom-}")"
  read -r -a extra <<<"${!v:-}"
  cmd+=("${extra[@]}")
done
# the job's cores become the default thread count of the crom programs
job='if [ -n "${SLURM_CPUS_PER_TASK:-}" ]; then export CROM_THREADS=$SLURM_CPUS_PER_TASK; fi
'"$line"
exec "${cmd[@]}" /bin/bash "${flags[@]}" -c "$job"
