#!/usr/bin/env bash
# table.sh TITLE ROWS — the closing table of an experiment (LiCROM Table 1
# style) as markdown on stdout and CSV next to ROWS (ROWS.csv).
# ROWS has one line per run:  LABEL FULL_STATS REDUCED_STATS DIFF CUBATURE MODEL
#   FULL_STATS     crom-fullsim --stats CSV (or - when there is no full run)
#   REDUCED_STATS  crom-reducedstep --stats CSV (with --indicator: its
#                  error_estimate and displacement_rms give the indicator
#                  column, sqrt(sum e^2 / sum u^2), crom-diff's measure)
#   DIFF           crom-diff output (its last line is the summary)
#   CUBATURE       the crom/cubature used (or the first of a schedule)
#   MODEL          the crom/model
# Step costs are medians over steps (seconds in the CSVs, ms in the table).
set -euo pipefail
title=$1 rows=$2
median() { sort -g | awk '{a[NR]=$1} END {if (NR == 0) print "nan"; else if (NR%2) print a[(NR+1)/2]; else print (a[NR/2]+a[NR/2+1])/2}'; }
col() { awk -F, -v c="$2" 'NR==1 {for (i=1;i<=NF;i++) if ($i==c) k=i} NR>1 && k {print $k}' "$1"; }
attr() { crom-info "$1" | awk -v a="$2" '$1 == a {print $2; exit}'; }
echo "### $title"
echo
echo "| run | vertices | full step (ms) | reduced step (ms) | speedup | relative error | indicator | cubature tets | rank | training (s) |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
csv="$rows.csv"
echo "run,vertices,full_step_ms,reduced_step_ms,speedup,relative_error,indicator,cubature_tets,rank,training_s" >"$csv"
while read -r label full red diff cub model; do
  [ -n "$label" ] || continue
  nv=$(crom-info "$cub" | sed -n 's/^ *\([0-9]*\) vertices, .*/\1/p' | head -1)
  fs=nan
  [ "$full" != "-" ] && fs=$(col "$full" seconds | median)
  rs=$(col "$red" seconds | median)
  err=$(tail -n 1 "$diff" | sed -n 's/relative displacement error \([0-9.e+-]*\) over.*/\1/p')
  ind=$(paste -d, <(col "$red" error_estimate) <(col "$red" displacement_rms) |
        awk -F, '$1 != "" {e += $1 * $1; u += $2 * $2} END {print (u > 0 ? sqrt(e / u) : "nan")}')
  k=$(attr "$cub" count)
  r=$(attr "$cub" rank)
  tr=$(attr "$model" training_seconds); tr=${tr:-nan}
  awk -v l="$label" -v nv="$nv" -v fs="$fs" -v rs="$rs" -v e="${err:-nan}" -v ind="${ind:-nan}" -v k="$k" -v r="$r" -v tr="$tr" -v csv="$csv" 'BEGIN {
    sp = (fs == "nan" || rs + 0 == 0) ? "—" : sprintf("%.0f×", fs / rs)
    f = (fs == "nan") ? "—" : sprintf("%.1f", 1e3 * fs)
    printf "| %s | %s | %s | %.3f | %s | %s | %s | %s | %s | %s |\n", l, nv, f, 1e3 * rs, sp, (e == "nan" ? "—" : sprintf("%.4f", e)), (ind == "nan" ? "—" : sprintf("%.4f", ind)), k, r, (tr == "nan" ? "—" : sprintf("%.0f", tr))
    printf "%s,%s,%s,%.6f,%s,%s,%s,%s,%s,%s\n", l, nv, (fs == "nan" ? "" : 1e3 * fs), 1e3 * rs, (fs == "nan" ? "" : fs / rs), e, (ind == "nan" ? "" : ind), k, r, tr >> csv
  }'
done <"$rows"
echo
echo "Step costs are medians over the steps of each run on one core; the error is crom-diff's"
echo "mass-weighted relative displacement error over the run against crom-fullsim; the indicator"
echo "is crom-reducedstep --indicator's estimate of it, which needs no full run."
