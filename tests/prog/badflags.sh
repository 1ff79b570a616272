#!/usr/bin/env bash
# Every numeric flag of every program, given a value no flag can mean (nan,
# 1e308, hexadecimal 0x10, the empty string) and the
# out-of-range values of issue 15 (--youngs 1e308, --dt 1e308, --tol 1e308,
# --exponent 0, a region given twice): each must exit 64 with one line on
# stderr naming the flag, and leave no output file (issue 15, defect 8).
. "$CROM_TOP/tests/prog/common.bash"
O="$TMP/out"; mkdir -p "$O"
cd "$TMP"

crom-mesh box --size 0.25 --region bottom='y<-0.4' --region top='y>0.4' -o m.h5
crom-fullsim --pin bottom --steps 3 --dt 0.01 -q -o run.h5 m.h5
crom-modes --pin bottom --count 3 -q -o modes.h5 m.h5
crom-encode --model modes.h5 -q -o lat.h5 run.h5
crom-cubature --model modes.h5 --scheme optimized --poses lat.h5 -q -o cub.h5 m.h5
crom-sample --points 20 -q -o s.h5 run.h5

OUT="$O/out.h5"
# values no flag accepts, substituted for X in a flag's template: one of each
# way a value is refused (not finite, out of every range, not decimal,
# empty); tests/unit/test_parse.c covers the parsers value by value (inf, a
# leading blank, trailing junk, ...) and every flag reaches one of them
BAD=(nan 1e308 0x10 "")
# each flag gets PER of them, taken in turn across the flags, so that every
# kind of bad value reaches every program; under ASan (CI's second pass) one
# per flag, since each ASan start is slow (two values took 160 s)
PER=2
case "$CROM_BUILD" in *-san) PER=1 ;; esac
turn=0
# try PROG FLAG TEMPLATE BASE...: the flag with each of its bad values put in
# TEMPLATE (X marks the spot) must be refused with exit 64
try() {
  local flag=$2 tpl=$3 prog=$1; shift 3
  local v k
  for ((k = 0; k < PER; k++)); do
    v=${BAD[turn % ${#BAD[@]}]}; turn=$((turn + 1))
    expect_error 64 "^$prog: .*--?${flag#--}" "$OUT" -- timeout 60 "$prog" "$@" "$flag" "${tpl//X/$v}"
  done
}
# once PROG FLAG VALUE PATTERN BASE...: one value, its own message
once() {
  local prog=$1 flag=$2 val=$3 pat=$4; shift 4
  expect_error 64 "^$prog: .*$pat" "$OUT" -- timeout 60 "$prog" "$@" "$flag" "$val"
}

# ---- the scenario, in every program that takes it
SC=(--youngs X --poisson X --density X --dt X --steps X --every X --gravity X,0,0 --gravity 0,X,0
    --velocity top=X,0,0 --velocity top=0,0,0@X:1 --force top=0,X,0 --plane 0,1,0,X --plane 0,1,0,0,X
    --sphere X,0,0,1 --sphere 0,0,0,X --sphere 0,0,0,1,X
    --damping X --contact-stiffness X --friction-eps X --tol X --max-iter X --initial-velocity X,0,0
    --spin 0,0,X --rod top/bottom=X,rest --rod top/bottom=1,rest,X,1)
for ((i = 0; i < ${#SC[@]}; i += 2)); do
  try crom-fullsim "${SC[i]}" "${SC[i + 1]}" -o "$OUT" m.h5
  try crom-reducedstep "${SC[i]}" "${SC[i + 1]}" --cubature cub.h5 -o "$OUT"
done
for f in --youngs --poisson --density; do
  try crom-modes $f X -o "$OUT" m.h5
  try crom-metrics $f X --samples 3 --mesh m.h5 modes.h5
done
try crom-fitfield --youngs X --objective energy --mesh m.h5 --rank 2 --steps 2 -o "$OUT"
try crom-fitfield --condition 'gravity:y=X:1' --objective energy --mesh m.h5 --rank 2 --steps 2 -o "$OUT"
try crom-fitfield --condition 'ratio:top=1:X' --objective energy --mesh m.h5 --rank 2 --steps 2 -o "$OUT"

# the out-of-range values of issue 15, each with the flag and its range named
once crom-fullsim --youngs 1e308 "--youngs: 1e308 is out of range" -o "$OUT" m.h5
once crom-fullsim --youngs 1e14 "--youngs must be a positive modulus in Pa, got 1e\+14 \(allowed \(0, 1e13\]\)" -o "$OUT" m.h5
once crom-reducedstep --dt 1e308 "--dt: 1e308 is out of range" --cubature cub.h5 -o "$OUT"
once crom-reducedstep --dt 1e4 "--dt must be in \[1e-9, 1e3\] s, got 10000" --cubature cub.h5 -o "$OUT"
once crom-fullsim --dt 1e-12 "--dt must be in \[1e-9, 1e3\] s" -o "$OUT" m.h5
once crom-fullsim --dt 0x10 "--dt: '0x10' is not a decimal number" -o "$OUT" m.h5
once crom-fullsim --tol 1e308 "--tol: 1e308 is out of range" -o "$OUT" m.h5
once crom-fullsim --tol 0.5 "--tol must be in \[1e-16, 0.1\]" -o "$OUT" m.h5
once crom-fullsim --density 1e7 "--density must be positive, got 1e\+07" -o "$OUT" m.h5
once crom-fullsim --gravity 0,-1e6,0 "--gravity: \|g\| must be at most" -o "$OUT" m.h5
once crom-fullsim --seed 0x10 "--seed: '0x10' is not a non-negative decimal integer" -o "$OUT" m.h5
once crom-fullsim --steps 0x10 "--steps: '0x10' is not an integer" -o "$OUT" m.h5
once crom-fullsim --pin bottom "--pin: region 'bottom' is already pinned" --pin bottom -o "$OUT" m.h5
once crom-fullsim --velocity top=0,1,0 "--velocity: region 'top' is already moved by --velocity" \
  --velocity top=0,-1,0@0:0.01 -o "$OUT" m.h5
once crom-fullsim --velocity bottom=0,1,0 "--velocity: region 'bottom' is already pinned" --pin bottom -o "$OUT" m.h5
# different regions that share vertices: full and reduced simulation say so alike
once crom-fullsim --velocity 'x<0=0,1,0' "--velocity 'y>0.3' and --velocity 'x<0' share vertex [0-9]+ \(at .*\): each vertex follows one condition" \
  --velocity 'y>0.3=1,0,0' -o "$OUT" m.h5
once crom-fullsim --velocity 'y>0.3=1,0,0' "--pin 'x<0' and --velocity 'y>0.3' share vertex" --pin 'x<0' -o "$OUT" m.h5
once crom-reducedstep --velocity 'y>0.3=1,0,0' "--pin 'x<0' and --velocity 'y>0.3' share vertex" --pin 'x<0' \
  --cubature cub.h5 -o "$OUT"
once crom-mesh --exponent 0 "--exponent must be in \[1, 200\], got 0" superquadric -o "$OUT"
once crom-mesh --region top='y<0' "--region: region 'top' is given twice" box --region top='y>0' -o "$OUT"

# ---- each program's own numeric flags
for f in --size --radius --height --exponent --timeout; do try crom-mesh $f X sphere -o "$OUT"; done
try crom-mesh --dims X,1,1 box -o "$OUT"
for f in --count --max-poses --tol --candidates --youngs --poisson --crack-offset; do
  try crom-cubature $f X --model modes.h5 --scheme optimized --poses lat.h5 -o "$OUT" m.h5
done
try crom-diff --max-error X run.h5 run.h5
for f in --frame --every --columns --range --youngs --poisson; do
  try crom-export $f X --format vtu -o "$O/out.vtu" run.h5
done
try crom-export --panel Xx64 --format png -o "$O/out.png" run.h5
try crom-export --panel 64xX --format png -o "$O/out.png" run.h5
for v in 64x64junk +64x64 64x+64 0x40x64 640X480 x64 64x 99999999999999999999x64; do
  once crom-export --panel "$v" "--panel: '.*' is not WxH with 32..4096 pixels" --format png -o "$O/out.png" run.h5
done
for f in --rank --epochs --minutes --lr --batch --points-per-step --encoder-points --width --depth --tikhonov \
         --sample-points --handles --coordinate-tol --steps --sigma --lambda --tangent-weight --tangent-floor --box --resample \
         --features --tets --pin-length --ortho-weight; do
  try crom-fitfield $f X --rank 2 --epochs 2 -o "$OUT" s.h5
done
for f in --samples --sphere --box --normal --sigma --pairs-of --collapse-threshold; do
  try crom-metrics $f X --mesh m.h5 modes.h5
done
for f in --count --shift --tol --rigid-tol; do try crom-modes $f X -o "$OUT" m.h5; done
for f in --between --fps --youngs --density; do try crom-keyframe $f X --model modes.h5 --key 0,0,0 --key 1,0,0 -o "$OUT"; done
try crom-keyframe --key X,0,0 --model modes.h5 --key 1,0,0 -o "$OUT"
for f in --init-frame --bc-stiffness --bc-threshold; do
  try crom-reducedstep $f X --cubature cub.h5 --steps 2 -o "$OUT"
done
for f in --stages --stage; do try crom-remesh $f X cut --segment 0,-1,0,1 -o "$OUT" m.h5; done
try crom-remesh --segment X,-1,0,1 cut -o "$OUT" m.h5
try crom-remesh --sphere 0,0,0,X punch -o "$OUT" m.h5
try crom-remesh --times X refine -o "$OUT" m.h5
for f in --points --every; do try crom-sample $f X -o "$OUT" run.h5; done
for f in --links --length --radius --density --joint-weight --ortho-weight; do try crom-scene $f X chain -o "$OUT"; done
try crom-scene --angle X pendulum -o "$OUT"
for f in --ring-radius --contact-weight; do try crom-scene $f X chain -o "$OUT"; done
once crom-scene --angle 200 "--angle" pendulum -o "$OUT"
for p in crom-info crom-encode; do
  expect_error 64 "^$p: --seed: '0x10' is not a non-negative decimal integer" - -- $p --seed 0x10 m.h5
  expect_error 64 "^$p: --threads: '1e308' is not an integer" - -- $p --threads 1e308 m.h5
done

done_checks
