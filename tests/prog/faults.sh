#!/usr/bin/env bash
# faults.sh — what the programs do when the system fails under them: a full
# disk (a 1 MiB tmpfs, and /dev/full), a device error (EIO, through an
# LD_PRELOAD shim on HDF5's writes), a reader that goes away (closed pipe),
# SIGTERM/SIGINT/SIGHUP mid-run, an output directory that cannot be written,
# and an input truncated, rewritten or replaced while it is read (issue 15).
# Each failure must give its exit code (74 I/O, 73 cannot create, 65 bad
# data, 128+signal), exactly one line on stderr naming the cause, and no
# output that looks complete (none at all, or one crom-info --check rejects).
source "$(dirname "$0")/common.bash"
cd "$TMP"
NOSPC='No space left on device'

crom-mesh box --size 0.1 -o mesh.h5
crom-mesh box --size 0.05 -o m5.h5
crom-fullsim --steps 15 --pin 'y>0.45' -o traj.h5 m5.h5
crom-sample --points all traj.h5 -o samples.h5
crom-fitfield --basis pod --rank 4 -o pod.h5 samples.h5 2>/dev/null

# no_output DIR: DIR holds no file but the ones given after it (no partial
# output, no temporary file)
no_output() {
  local d=$1; shift
  local left; left=$(ls -A "$d" | grep -vxF -f <(printf '%s\n' "$@" "") || true)
  [ -z "$left" ] || fail "left behind in $d: $left"
  ok
}

# ---------------------------------------------------------- a full disk
FULL=$TMP/full
mkdir -p "$FULL"
if mount -t tmpfs -o size=1m crom-faults "$FULL" 2>/dev/null; then
  trap 'umount "$FULL" 2>/dev/null || true; rm -rf "$TMP"' EXIT
  # the disk fills while the output is written: every program that writes a
  # large file, through HDF5 or stdio
  expect_error 74 "^crom-mesh: $FULL/m.h5: $NOSPC\$" "$FULL/m.h5" -- crom-mesh box --size 0.04 -o "$FULL/m.h5"
  expect_error 74 "^crom-fullsim: $FULL/t.h5: $NOSPC\$" "$FULL/t.h5" -- \
    crom-fullsim --steps 200 --pin 'y>0.45' -o "$FULL/t.h5" mesh.h5
  expect_error 74 "^crom-fullsim: $FULL/t.h5: $NOSPC\$" "$FULL/t.h5" -- \
    crom-fullsim --steps 30 --pin 'y>0.45' --stream -o "$FULL/t.h5" m5.h5
  expect_error 74 "^crom-sample: $FULL/s.h5: $NOSPC\$" "$FULL/s.h5" -- crom-sample --points all traj.h5 -o "$FULL/s.h5"
  expect_error 74 "^crom-fitfield: $FULL/pod.h5: $NOSPC\$" "$FULL/pod.h5" -- \
    crom-fitfield --basis pod --rank 4 -o "$FULL/pod.h5" samples.h5
  expect_error 74 "^crom-export: $FULL/run.xdmf.h5: $NOSPC\$" "$FULL/run.xdmf" -- \
    crom-export --format xdmf -o "$FULL/run.xdmf" traj.h5
  expect_error 74 "^crom-export: $FULL/run.vtu: $NOSPC\$" "$FULL/run.vtu" -- crom-export --format vtu -o "$FULL/run.vtu" traj.h5
  expect_error 74 "^crom-export: $FULL/run.msh: $NOSPC\$" "$FULL/run.msh" -- crom-export --format msh -o "$FULL/run.msh" traj.h5
  # a directory of VTUs: the frame that does not fit is named; nothing
  # complete-looking stays (no .pvd, no partial frame)
  expect_error 74 "^crom-export: $FULL/run/run_[0-9]+\.vtu: $NOSPC\$" "$FULL/run.pvd" -- \
    crom-export --format pvd -o "$FULL/run.pvd" traj.h5
  [ ! -e "$FULL/run" ] || [ -z "$(ls -A "$FULL/run" | grep -v '^run_[0-9]*\.vtu$' || true)" ] \
    || fail "pvd export left $(ls -A "$FULL/run")"; ok
  rm -rf "$FULL/run"
  no_output "$FULL"
  # the disk is already full: HDF5 cannot even create the file; small
  # outputs (PNG, OBJ) fail too
  dd if=/dev/zero of="$FULL/fill" bs=4k 2>/dev/null || true
  expect_error 74 "^crom-mesh: $FULL/m.h5: $NOSPC\$" "$FULL/m.h5" -- crom-mesh box --size 0.1 -o "$FULL/m.h5"
  expect_error 74 "^crom-export: $FULL/run.png: $NOSPC\$" "$FULL/run.png" -- crom-export --format png -o "$FULL/run.png" traj.h5
  expect_error 74 "^crom-export: $FULL/x.obj: $NOSPC\$" "$FULL/x.obj" -- crom-export --format obj -o "$FULL/x.obj" traj.h5
  no_output "$FULL" fill
  rm -f "$FULL/fill"
  # the same run with room for it succeeds (the failures above were the disk's)
  crom-mesh box --size 0.1 -o "$FULL/m.h5" && crom-info --check "$FULL/m.h5" >/dev/null \
    || fail "crom-mesh on the emptied tmpfs failed"; ok
  rm -f "$FULL/m.h5"
  # a read-only file system: the output cannot be created (73)
  mount -o remount,ro "$FULL"
  expect_error 73 "^crom-mesh: cannot create $FULL/m.h5: Read-only file system\$" "$FULL/m.h5" -- \
    crom-mesh box --size 0.1 -o "$FULL/m.h5"
  expect_error 73 "^crom-export: cannot create $FULL/x.vtu: Read-only file system\$" "$FULL/x.vtu" -- \
    crom-export --format vtu -o "$FULL/x.vtu" mesh.h5
  umount "$FULL"
else
  echo "skipped: cannot mount tmpfs (the ENOSPC cases on a file system; /dev/full still runs)"
fi

# --------------------------------------------------------------- /dev/full
# as a named output (written in place) and as stdout (an HDF5 image or a
# frame stream)
expect_error 74 "^crom-mesh: /dev/full: $NOSPC\$" - -- crom-mesh box --size 0.1 -o /dev/full
expect_error 74 "^crom-mesh: stdout: $NOSPC\$" - -- sh -c 'crom-mesh box --size 0.1 > /dev/full'
expect_error 74 "^crom-fullsim: stdout: $NOSPC\$" - -- sh -c 'crom-fullsim --steps 3 mesh.h5 > /dev/full'
expect_error 74 "^crom-fullsim: /dev/full: $NOSPC\$" - -- crom-fullsim --steps 3 -o /dev/full mesh.h5
expect_error 74 "^crom-sample: stdout: $NOSPC\$" - -- sh -c 'crom-sample --points all traj.h5 > /dev/full'
expect_error 74 "^crom-encode: stdout: $NOSPC\$" - -- sh -c 'crom-encode --quiet --model pod.h5 traj.h5 > /dev/full'
expect_error 74 "^crom-export: /dev/full: $NOSPC\$" - -- crom-export --format vtu -o /dev/full traj.h5
expect_error 74 "^crom-export: /dev/full: $NOSPC\$" - -- crom-export --format png -o /dev/full traj.h5

# -------------------------------------------------------------- a device error
# HDF5's writes to the output fail with EIO after the first 64 KiB; the
# failure persists, so closing the file fails too (the handle must not be
# closed again at exit: that was a SIGSEGV)
SHIM=$TMP/eio.so
if cc -shared -fPIC -O1 -o "$SHIM" "$CROM_TOP/tests/prog/eio_shim.c" -ldl 2>/dev/null; then
  mkdir -p eio
  eio() { env LD_PRELOAD="$SHIM" CROM_EIO_MATCH="$TMP/eio/" CROM_EIO_AFTER=65536 \
            ASAN_OPTIONS="${ASAN_OPTIONS:-}:verify_asan_link_order=0" "$@"; }
  expect_error 74 "^crom-mesh: $TMP/eio/m.h5: Input/output error\$" "$TMP/eio/m.h5" -- eio crom-mesh box --size 0.06 -o "$TMP/eio/m.h5"
  expect_error 74 "^crom-fullsim: $TMP/eio/t.h5: Input/output error\$" "$TMP/eio/t.h5" -- \
    eio crom-fullsim --steps 30 --pin 'y>0.45' -o "$TMP/eio/t.h5" m5.h5
  expect_error 74 "^crom-sample: $TMP/eio/s.h5: Input/output error\$" "$TMP/eio/s.h5" -- \
    eio crom-sample --points all traj.h5 -o "$TMP/eio/s.h5"
  no_output eio
  # a device error while READING an input (opened by HDF5 by name here,
  # CROM_IO_IMAGE_MAX=0): exit 74 with the system's error, not "corrupt
  # file" (the contained check in the child reports the errno it met)
  cp m5.h5 eio/in.h5
  eior() { env LD_PRELOAD="$SHIM" CROM_EIO_MATCH="$TMP/eio/" CROM_EIO_READ=1 CROM_EIO_AFTER=$1 CROM_IO_IMAGE_MAX=0 \
             ASAN_OPTIONS="${ASAN_OPTIONS:-}:verify_asan_link_order=0" "${@:2}"; }
  for after in 0 4096; do
    expect_error 74 "^crom-info: $TMP/eio/in.h5: Input/output error\$" - -- eior $after crom-info "$TMP/eio/in.h5"
    expect_error 74 "^crom-info: $TMP/eio/in.h5: Input/output error\$" - -- eior $after crom-info --check "$TMP/eio/in.h5"
    expect_error 74 "^crom-fullsim: $TMP/eio/in.h5: Input/output error\$" "$TMP/r.h5" -- \
      eior $after crom-fullsim --steps 2 -o "$TMP/r.h5" "$TMP/eio/in.h5"
  done
else
  echo "skipped: no C compiler for the EIO shim"
fi

# ------------------------------------------------------------ a closed pipe
# the reader stops after 100 bytes: the writer dies of SIGPIPE (141) or
# stops with a quiet 74; no crash, at most one line on stderr
for cmd in "crom-fullsim --steps 40 --pin y>0.45 mesh.h5" "crom-mesh box --size 0.06" \
           "crom-sample --points all traj.h5" "crom-export --format vtu -o - traj.h5"; do
  set +o pipefail
  $cmd 2>pipe.err | head -c 100 >/dev/null
  rc=${PIPESTATUS[0]}
  set -o pipefail
  [ "$rc" = 141 ] || [ "$rc" = 74 ] || fail "'$cmd | head -c 100' exited $rc: $(cat pipe.err)"
  [ "$(wc -l <pipe.err)" -le 1 ] || fail "'$cmd | head -c 100' printed: $(cat pipe.err)"
  [ "$rc" = 141 ] || grep -q 'Broken pipe' pipe.err || fail "'$cmd | head': $(cat pipe.err)"
  ok
done

# -------------------------------------------------------------- signals
# a long run is stopped once its temporary file exists: 128+signal, nothing
# printed, no output and no temporary file left
for sig in TERM INT HUP; do
  mkdir -p "sig$sig"
  # (python starts it: a background job of a script would ignore SIGINT)
  rc=$($PY - "$sig" "$TMP/sig$sig" <<'EOF'
import glob, os, signal, subprocess, sys, time
sig, d = getattr(signal, "SIG" + sys.argv[1]), sys.argv[2]
p = subprocess.Popen(["crom-fullsim", "--steps", "100000", "--pin", "y>0.45", "-o", d + "/t.h5", "mesh.h5"],
                     stderr=open(d + "/err", "w"), restore_signals=True)
t0 = time.time()
while not glob.glob(d + "/.t.h5.*.tmp"):
    if p.poll() is not None or time.time() - t0 > 60:
        sys.exit("crom-fullsim ended or never made its temporary file")
    time.sleep(0.02)
time.sleep(0.3)
p.send_signal(sig)
print(p.wait())
EOF
) || fail "signal $sig: could not run"
  want=$((128 + $(kill -l "$sig")))
  # Popen reports a death by signal as -N
  [ "$rc" = "-$((want - 128))" ] || [ "$rc" = "$want" ] || fail "SIG$sig: crom-fullsim exited $rc, expected $want"
  [ ! -s "sig$sig/err" ] || fail "SIG$sig: crom-fullsim printed $(cat "sig$sig/err")"
  no_output "sig$sig" err
done

# ------------------------------------------------ an unwritable directory
expect_error 73 "^crom-mesh: cannot create nodir/m.h5: No such file or directory\$" - -- crom-mesh box --size 0.1 -o nodir/m.h5
expect_error 73 "^crom-export: cannot create mesh.h5/x.vtu: Not a directory\$" - -- crom-export --format vtu -o mesh.h5/x.vtu mesh.h5
if [ "$(id -u)" != 0 ]; then   # (root writes anywhere: the read-only tmpfs above stands in for it)
  mkdir -p ro && chmod 555 ro
  expect_error 73 "^crom-fullsim: cannot create ro/t.h5: Permission denied\$" ro/t.h5 -- crom-fullsim --steps 2 -o ro/t.h5 mesh.h5
  expect_error 73 "^crom-export: cannot create ro/x.png: Permission denied\$" ro/x.png -- crom-export --format png -o ro/x.png mesh.h5
  chmod 755 ro
fi

# ------------------------------------- an input that changes while it is read
# crom-encode reads a trajectory frame by frame while writing a stream to a
# pipe of one page that nobody reads yet: it blocks on its header, after the
# input is open and before any frame is read; then the input is changed and
# the pipe drained.
crom-encode --quiet --model pod.h5 traj.h5 -o ref.h5
during_read() {   # during_read ACTION: prints "rc<TAB>stderr"
  $PY - "$1" <<'EOF'
import fcntl, os, shutil, subprocess, sys, time
action = sys.argv[1]
shutil.copy("traj.h5", "in.h5")
r, w = os.pipe()
fcntl.fcntl(w, fcntl.F_SETPIPE_SZ, 4096)
p = subprocess.Popen(["crom-encode", "--quiet", "--model", "pod.h5", "in.h5"], stdout=w, stderr=subprocess.PIPE)
os.close(w)
t0 = time.time()
while True:   # blocked writing its stream header: the input is open, no frame read
    st = open("/proc/%d/stat" % p.pid).read().rsplit(")", 1)[1].split()[0]
    if st == "S" and any(os.path.realpath("/proc/%d/fd/%s" % (p.pid, f)).endswith("/in.h5")
                         for f in os.listdir("/proc/%d/fd" % p.pid)):
        time.sleep(0.2)
        break
    if p.poll() is not None or time.time() - t0 > 60:
        sys.exit("crom-encode never blocked with in.h5 open")
    time.sleep(0.02)
size = os.path.getsize("in.h5")
if action == "truncate":
    os.truncate("in.h5", size // 2)
elif action == "rewrite":   # the same bytes written again in place (mtime changes)
    data = open("traj.h5", "rb").read()
    with open("in.h5", "r+b") as f:
        f.write(data)
elif action == "replace":   # another file renamed over it
    shutil.copy("mesh.h5", "new.h5")
    os.rename("new.h5", "in.h5")
out = open("out.stream", "wb")
while True:
    b = os.read(r, 65536)
    if not b:
        break
    out.write(b)
out.close()
err = p.stderr.read().decode()
print("%d\t%s" % (p.wait(), err.strip()))
EOF
}
# a file read by name (CROM_IO_IMAGE_MAX=0; by default only files over 64 MB
# are): truncated or rewritten in place mid-read is exit 65
export CROM_IO_IMAGE_MAX=0
res=$(during_read truncate)
[ "${res%%$'\t'*}" = 65 ] || fail "input truncated mid-read: crom-encode gave '$res', expected 65"; ok
[ "${res#*$'\t'}" = "crom-encode: in.h5: changed or truncated while being read" ] || fail "truncated: '$res'"; ok
! crom-info --check out.stream >/dev/null 2>&1 || fail "truncated: the output stream looks complete"; ok
res=$(during_read rewrite)
[ "$res" = $'65\tcrom-encode: in.h5: changed or truncated while being read' ] || fail "input rewritten mid-read: '$res'"; ok
unset CROM_IO_IMAGE_MAX
# a file of up to 64 MB is read whole at open: truncating or rewriting it
# afterwards cannot touch the run, which gives the undisturbed result
for act in truncate rewrite; do
  res=$(during_read $act)
  [ "${res%%$'\t'*}" = 0 ] || fail "input ${act}d mid-read (read at open): '$res'"; ok
  crom-diff --quiet --model pod.h5 --mesh m5.h5 --max-error 1e-300 out.stream ref.h5 >diff.out 2>&1 \
    || fail "${act}d mid-read: output differs: $(cat diff.out)"; ok
done
# replaced by rename: the open file is still the old one, read whole and
# consistently: the same latent trajectory as an undisturbed run
res=$(during_read replace)
[ "${res%%$'\t'*}" = 0 ] || fail "input replaced mid-read: '$res'"; ok
crom-diff --quiet --model pod.h5 --mesh m5.h5 --max-error 1e-300 out.stream ref.h5 >diff.out 2>&1 \
  || fail "replaced mid-read: output differs: $(cat diff.out)"; ok
grep -q " over 16 frames" diff.out || fail "replaced mid-read: not every frame compared: $(cat diff.out)"; ok

done_checks
