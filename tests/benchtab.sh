#!/usr/bin/env bash
# benchtab.sh fullsim|sheets DIR SIZE... — the full-space timing table
# (medians over steps) from crom-fullsim --stats CSV files, as markdown on
# stdout and as DIR/fullsim.csv (DIR/sheets.csv: the thin-shell runs).
set -euo pipefail
kind=$1 dir=$2; shift 2
median() { sort -g | awk '{a[NR]=$1} END {if (NR%2) print a[(NR+1)/2]; else print (a[NR/2]+a[NR/2+1])/2}'; }
col() { awk -F, -v c="$2" 'NR>1 {print $c}' "$1"; }
case $kind in
fullsim|sheets)
  # fullsim: DIR/mesh-SIZE.h5 and DIR/fullsim-SIZE.csv (tets); sheets: DIR/sheet-SIZE.h5 and
  # DIR/sheetsim-SIZE.csv (triangles of a shell)
  if [ "$kind" = sheets ]; then mesh=sheet run=sheetsim el=triangles; else mesh=mesh run=fullsim el=tets; fi
  echo "| vertices | $el | steps | median s/step | mean s/step | assembly | factorization | solves | line search | Newton/step | CG/step | factorizations |"
  echo "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
  echo "vertices,$el,steps,median_step_s,mean_step_s,assembly_s,factorization_s,solves_s,line_search_s,newton_per_step,cg_per_step,factorizations" > "$dir/$kind.csv"
  for s in "$@"; do
    f="$dir/$run-$s.csv"
    info=$(crom-info "$dir/$mesh-$s.h5" | sed -n "s/^ *\([0-9]*\) vertices, \([0-9]*\) $el.*/\1 \2/p")
    read -r nv nt <<<"$info"
    n=$(($(wc -l <"$f") - 1))
    row=("$nv" "$nt" "$n" "$(col "$f" 6 | median)" "$(col "$f" 6 | awk '{s+=$1} END {print s/NR}')")
    for c in 7 8 9 10 2 3 4; do row+=("$(col "$f" $c | median)"); done
    printf '| %s | %s | %s | %.3f | %.3f | %.3f | %.3f | %.3f | %.3f | %s | %s | %s |\n' "${row[@]}"
    (IFS=,; echo "${row[*]}") >> "$dir/$kind.csv"
  done
  echo
  echo "Medians over the steps of each run on one core; the split columns are medians"
  echo "too. Factorizations happen in few steps (the factor is reused as CG"
  echo "preconditioner), so their median is usually 0: the mean column includes them."
  ;;
esac
