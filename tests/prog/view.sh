#!/usr/bin/env bash
# crom-view (issue 21 item 2): crom-live's frames served to a page on
# 127.0.0.1, the page's drags passed back as commands.
#   - a WebSocket client (tests/prog/view_client.py ws) gets the greeting,
#     the surface and frames; a drag of one vertex brings it within half its
#     distance of the cursor in 1.5 s, and the frame that first shows the
#     command is known (the stream's commands field); bad commands (unknown,
#     no such region or vertex, NaN, quit, an unoffered schedule, binary,
#     too long) get one 'error:' each and the frames go on; a page from
#     another origin is refused; a page that leaves mid-drag has its drag
#     released; an offered cubature (a punched mesh) switches the run and
#     the page gets its surface;
#   - headless Chromium (ChromeDriver) draws the body and a mouse drag on
#     the page pulls the vertex under the cursor after it; the screenshot
#     changes around the dragged point;
#   - only 127.0.0.1 listens; Ctrl-C (SIGINT) asks the run to quit and both
#     end with 0; a run that dies leaves crom-view with one line and a
#     non-zero exit; bad flags and bad stdin get one line.
# Under the sanitizers the browser part is skipped (Chromium under an ASan
# build only slows it; the server's code runs in the WebSocket part).
. "$CROM_TOP/tests/prog/common.bash"
cd "$TMP"
need() {
  if ! command -v chromium >/dev/null || ! command -v chromedriver >/dev/null || ! $PY -c 'import websockets, PIL' 2>/dev/null; then
    [ "${CI:-}" = true ] && fail "Chromium, ChromeDriver, python3-websockets or python3-pil missing (make deps installs them)"
    echo "view: skipped (no Chromium, ChromeDriver, python3-websockets or python3-pil: make deps)"; exit 0
  fi
}
need
SC=(--velocity 'top=0,-2,0@0:0.1' --pin bottom --gravity 0,-9.81,0 --dt 0.01 --steps 30)
crom-mesh box --size 0.15 --region top='y>0.45' --region bottom='y<-0.45' -q -o mesh.h5
crom-fullsim "${SC[@]}" -q -o full.h5 mesh.h5
crom-sample --points all full.h5 -o s.h5 2>/dev/null
crom-fitfield --basis pod --rank 6 -q -o pod.h5 s.h5
crom-cubature --model pod.h5 --scheme all -q -o cub.h5 mesh.h5
crom-remesh punch --sphere 0.5,0,0,0.3 -q -o punched.h5 mesh.h5
crom-cubature --model pod.h5 --scheme all -q -o cub-p.h5 punched.h5
RUNF=(--pin bottom --gravity 0,0,0 --youngs 2e5 --dt 0.01 --drag-stiffness 1e7)
RUN=(--cubature cub.h5 "${RUNF[@]}")
CUB=cub.h5
VID=$($PY -c "import h5py, numpy as np; X = h5py.File('mesh.h5')['vertices'][()]; print(int(np.argmax(X[:, 1] + 1e-3 * X[:, 0])))")

# start crom-live and crom-view joined by two FIFOs; PORT, LIVE, VIEW
start() {
  rm -f frames cmds view.err live.err; mkfifo frames cmds
  crom-live --cubature "$CUB" "${RUNF[@]}" --commands cmds >frames 2>live.err & LIVE=$!
  crom-view --cubature "$CUB" "$@" --port 0 -v <frames >cmds 2>view.err & VIEW=$!
  for _ in $(seq 200); do grep -q 'open http://127.0.0.1:' view.err 2>/dev/null && break; sleep 0.1; done
  PORT=$(grep -o '127\.0\.0\.1:[0-9]*' view.err | head -1 | cut -d: -f2)
  [ -n "$PORT" ] || fail "crom-view did not start: $(cat view.err)"
}
# end both with Ctrl-C to crom-view; both must exit 0
stop() {
  kill -INT $VIEW
  local rv=0 rl=0
  wait $VIEW || rv=$?
  wait $LIVE || rl=$?
  [ $rv -eq 0 ] && [ $rl -eq 0 ] || fail "Ctrl-C: crom-view exited $rv, crom-live $rl: $(cat view.err live.err)"
  grep -q 'the run ended after [0-9]* frames' view.err || fail "no closing line: $(cat view.err)"
  ok
}

# ---- a WebSocket client
start --offer cub-p.h5
# only the loopback interface listens (IPv4 127.0.0.1, no IPv6 socket)
hexport=$(printf '%04X' "$PORT")
grep -q " 0100007F:$hexport 00000000:0000 0A" /proc/net/tcp || fail "127.0.0.1:$PORT is not listening"
! grep -qE " [0-9A-F]{8}:$hexport 00000000:0000 0A" <(grep -v " 0100007F:$hexport " /proc/net/tcp) ||
  fail "another IPv4 address listens on $PORT"
! grep -qE ":$hexport [0-9A-F]{32}:0000 0A" /proc/net/tcp6 || fail "an IPv6 address listens on $PORT"; ok
timeout 60 $PY "$CROM_TOP/tests/prog/view_client.py" ws "$PORT" "$VID" 1e7 >ws.txt 2>&1 ||
  fail "WebSocket client: $(cat ws.txt)"
cat ws.txt; ok
grep -q "refused a WebSocket from a page of http://evil.example" view.err || fail "foreign origin not logged"; ok
[ "$(grep -c 'warning: page 1: ' view.err)" -eq 8 ] || fail "expected 8 refusals logged: $(cat view.err)"; ok
grep -q "page 1 went away (its drags released)" view.err || fail "drags of a page that left"; ok
# the page's HTTP: the page at /, 404 elsewhere
$PY - "$PORT" <<'EOF' || fail "HTTP"
import sys, urllib.request, urllib.error
p = sys.argv[1]
page = urllib.request.urlopen("http://127.0.0.1:%s/" % p).read().decode()
if "<canvas" not in page or "webgl2" not in page:
    sys.exit("/ is not the page")
try:
    urllib.request.urlopen("http://127.0.0.1:%s/etc/passwd" % p); sys.exit("served /etc/passwd")
except urllib.error.HTTPError as e:
    if e.code != 404:
        sys.exit("/etc/passwd: HTTP %d, expected 404" % e.code)
EOF
ok
stop

# ---- headless Chromium: the page draws, the mouse drags
if [ "${CROM_SANITIZE:-0}" != 1 ]; then
  start
  timeout 120 $PY "$CROM_TOP/tests/prog/view_client.py" browser "$PORT" "$TMP" >browser.txt 2>&1 ||
    fail "browser: $(cat browser.txt; tail -5 view.err)"
  cat browser.txt; ok
  grep -qE "page 1: drag #[0-9]+ " view.err && grep -qE "page 1: release #[0-9]+" view.err ||
    fail "the page's drag and release did not reach the run: $(cat view.err)"; ok
  grep -qE "page 1: frames=[0-9]+ drawn=[0-9]+ decode_ms=" view.err || fail "the page's report: $(cat view.err)"; ok
  stop
else
  echo "view: browser part skipped under the sanitizers"
fi

# ---- Ctrl-C to the run alone: it ends its stream, crom-view follows; both 0
start
sleep 0.3
kill -INT $LIVE
rl=0; wait $LIVE || rl=$?; rv=0; wait $VIEW || rv=$?
[ $rl -eq 0 ] && [ $rv -eq 0 ] || fail "SIGINT to crom-live: it exited $rl, crom-view $rv: $(cat live.err view.err)"
grep -q 'the run ended after [0-9]* frames' view.err || fail "no closing line: $(cat view.err)"; ok

# ---- a model of rank 130: a frame of 48 + 8 r = 1088 bytes (crom-view once
# built frames in a 1 KiB buffer)
crom-modes --pin bottom --count 130 -q -o modes130.h5 mesh.h5
crom-cubature --model modes130.h5 --scheme random --count 40 -q -o cub130.h5 mesh.h5
CUB=cub130.h5
start
timeout 60 $PY "$CROM_TOP/tests/prog/view_client.py" frames "$PORT" 130 >frames.txt 2>&1 || fail "rank 130: $(cat frames.txt)"
cat frames.txt; ok
stop
CUB=cub.h5

# ---- a run that dies: one line, non-zero
start
sleep 0.3
kill -9 $LIVE; wait $LIVE 2>/dev/null || true
rv=0; wait $VIEW || rv=$?
[ $rv -ne 0 ] || fail "crom-view exited 0 after the run died"
tail -1 view.err | grep -q "the frame stream ended without its end record" || fail "dead run: $(tail -1 view.err)"; ok

# ---- bad flags and bad input: one line each
expect_error 64 "--cubature CUB is required" - -- crom-view
expect_error 64 "--port" - -- crom-view --cubature cub.h5 --port 70000
expect_error 66 "nope.h5" - -- crom-view --cubature nope.h5
expect_error 64 "unexpected operand" - -- crom-view --cubature cub.h5 extra
crom-live "${RUN[@]}" --no-clock -q -o run.h5 </dev/null
rc=0; crom-view --cubature cub.h5 --port 0 <run.h5 >/dev/null 2>err.txt || rc=$?
[ $rc -ne 0 ] && [ "$(wc -l <err.txt)" -eq 1 ] && grep -q "an HDF5 file" err.txt || fail "HDF5 on stdin: $rc $(cat err.txt)"; ok
crom-fitfield --basis pod --rank 4 -q -o pod4.h5 s.h5
crom-cubature --model pod4.h5 --scheme all -q -o cub4.h5 mesh.h5
rc=0; crom-live --cubature cub4.h5 --no-clock -q </dev/null | crom-view --cubature cub.h5 --port 0 >/dev/null 2>err.txt || rc=$?
[ $rc -ne 0 ] && [ "$(wc -l <err.txt)" -eq 1 ] && grep -q "a run of model" err.txt || fail "another model's run: $rc $(cat err.txt)"; ok
expect_error 65 "belongs to model" - -- crom-view --cubature cub.h5 --offer cub4.h5
# a port in use
$PY -c "
import socket, sys, time
s = socket.socket(); s.bind(('127.0.0.1', 0)); s.listen(); print(s.getsockname()[1], flush=True); time.sleep(30)" >busy.txt &
BUSY=$!
for _ in $(seq 50); do [ -s busy.txt ] && break; sleep 0.1; done
rc=0; crom-live "${RUN[@]}" --no-clock -q </dev/null | crom-view --cubature cub.h5 --port "$(cat busy.txt)" >/dev/null 2>err.txt || rc=$?
kill $BUSY 2>/dev/null || true
[ $rc -ne 0 ] && [ "$(wc -l <err.txt)" -eq 1 ] && grep -q "cannot serve on 127.0.0.1" err.txt || fail "port in use: $rc $(cat err.txt)"; ok
done_checks
