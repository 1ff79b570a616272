#!/usr/bin/env bash
# plot.sh — PNG plots of crom results with gnuplot (Debian's gnuplot-nox).
#
#   plot.sh loss  OUT.png MODEL [TITLE]
#       training loss per epoch of a crom/model (/training/loss, log scale;
#       the wall time from /training/seconds in the title)
#   plot.sh error OUT.png TITLE CSV[=LABEL]...
#       relative displacement error over time from crom-diff --csv files,
#       one line each (LABEL defaults to the file name), log scale
#   plot.sh cost  OUT.png TABLE_CSV [TITLE]
#       full vs reduced step cost (ms, log scale) per run, from the CSV that
#       pipelines/table.sh writes next to its rows (rows.txt.csv)
#
# The PNG appears only when complete (written beside OUT, then renamed).
# Data are extracted with h5dump (hdf5-tools) and awk; nothing else needed.
set -euo pipefail
me=plot.sh
die() { echo "$me: $*" >&2; exit "${2:-65}"; }
[ $# -ge 3 ] || die "usage: plot.sh loss|error|cost OUT.png ... (see the header of pipelines/plot.sh)" 64
kind=$1 out=$2
shift 2
command -v gnuplot >/dev/null || die "gnuplot is not installed (apt-get install gnuplot-nox)" 69
term="pngcairo size 800,500 font 'sans,10'"
gnuplot -e "set terminal pngcairo" 2>/dev/null </dev/null || term="png size 800,500"

work=$(mktemp -d "${TMPDIR:-/tmp}/crom-plot.XXXXXX")
tmp="$(dirname "$out")/.$(basename "$out").$$.tmp"
trap 'rm -rf "$work" "$tmp"' EXIT
# gnuplot string literal: single quotes doubled
q() { printf "'%s'" "${1//\'/\'\'}"; }

# one column of a dataset of an HDF5 file, one number per line
h5col() {
  h5dump -y -w 1 -m '%.10g' -d "$2" -o "$work/raw" "$1" >/dev/null 2>&1 \
    || die "$1: cannot read $2 (not a crom/model with a training log?)"
  tr -d ' ,' <"$work/raw" | sed '/^$/d'
}

case $kind in
loss)
  model=$1 title=${2:-"training loss: $(basename "$model")"}
  h5col "$model" /training/loss >"$work/loss"
  h5col "$model" /training/seconds >"$work/sec"
  paste "$work/loss" "$work/sec" | awk '{print NR, $1, $2}' >"$work/data"
  [ -s "$work/data" ] || die "$model: empty training log"
  secs=$(tail -n 1 "$work/data" | awk '{printf "%.1f", $3}')
  gnuplot <<EOF || die "gnuplot failed on $model" 70
set terminal $term
set output $(q "$tmp")
set title $(q "$title ($secs s)")
set xlabel 'epoch'
set ylabel 'loss (mean squared displacement error, m^2)'
set logscale y
set format y '%.0e'
set grid
plot $(q "$work/data") using 1:2 with lines lw 2 title 'loss'
EOF
  ;;
error)
  title=$1
  shift
  [ $# -ge 1 ] || die "error: give at least one crom-diff --csv file" 64
  plots=()
  i=0
  for spec in "$@"; do
    f=${spec%%=*} label=$(basename "$f" .csv)
    [ "$spec" != "$f" ] && label=${spec#*=}
    [ -r "$f" ] || die "$f: cannot read" 66
    head -n 1 "$f" | grep -q '^frame,time,relative_error' || die "$f: not a crom-diff --csv file"
    awk -F, 'NR > 1 {print $2, $3}' "$f" >"$work/e$i"
    [ -s "$work/e$i" ] || die "$f: no frames"
    plots+=("$(q "$work/e$i") using 1:2 with lines lw 2 title $(q "$label")")
    i=$((i + 1))
  done
  gnuplot <<EOF || die "gnuplot failed" 70
set terminal $term
set output $(q "$tmp")
set title $(q "$title")
set xlabel 'time (s)'
set ylabel 'relative displacement error (per frame)'
set logscale y
set format y '%g'
set grid
set key bottom right
plot $(IFS=,; echo "${plots[*]}")
EOF
  ;;
cost)
  csv=$1 title=${2:-"step cost: $(basename "$(cd "$(dirname "$csv")" && pwd)")"}
  [ -r "$csv" ] || die "$csv: cannot read" 66
  head -n 1 "$csv" | grep -q '^run,vertices,full_step_ms,reduced_step_ms' || die "$csv: not a table.sh CSV"
  # run, full ms (or 0 when there is none), reduced ms
  awk -F, 'NR > 1 {print "\"" $1 "\"", ($3 == "" ? "NaN" : $3), $4}' "$csv" >"$work/data"
  [ -s "$work/data" ] || die "$csv: no rows"
  gnuplot <<EOF || die "gnuplot failed on $csv" 70
set terminal $term
set output $(q "$tmp")
set title $(q "$title")
set ylabel 'step cost (ms, median)'
set logscale y
set style data histograms
set style histogram clustered gap 1
set style fill solid 0.8 border -1
set boxwidth 0.9
set grid ytics
set xtics rotate by -25
set key top right
plot $(q "$work/data") using 2:xtic(1) title 'full (crom-fullsim)', '' using 3 title 'reduced (crom-reducedstep)'
EOF
  ;;
*) die "unknown plot '$kind': loss, error or cost" 64 ;;
esac
[ -s "$tmp" ] || die "gnuplot wrote nothing" 70
mv -f "$tmp" "$out"
