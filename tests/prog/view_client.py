"""Clients of crom-view for tests/prog/view.sh (and pipelines/bench.mk).

  view_client.py ws PORT VID K           a WebSocket client: greeting, surface,
                                         frames; drags vertex VID (spring K
                                         N/m) and checks
                                         it follows; bad commands; a foreign
                                         origin; leaves mid-drag
  view_client.py frames PORT R           a model of rank R: greeting, surface
                                         and frames of 48 + 8 R bytes
  view_client.py browser PORT OUTDIR     headless Chromium through ChromeDriver
                                         (WebDriver over HTTP): the page draws
                                         the body, a mouse drag pulls it;
                                         screenshots before and during
  view_client.py load PORT SECONDS       a page (Chromium) drags the body round
                                         a circle for SECONDS and reports what
                                         it measured (bench)

Each prints 'name: value' lines and exits non-zero with a message on failure.
"""
import asyncio, base64, json, math, os, socket, struct, subprocess, sys, time, urllib.request


def fail(msg):
    sys.exit("view_client: " + msg)


def parse_surface(b):
    index, ns, nt, r = struct.unpack_from("<4I", b, 4)
    o = 44
    X = struct.unpack_from("<%df" % (3 * ns), b, o); o += 12 * ns
    W = struct.unpack_from("<%df" % (3 * r * ns), b, o); o += 12 * r * ns
    tri = struct.unpack_from("<%dI" % (3 * nt), b, o); o += 12 * nt
    vid = struct.unpack_from("<%di" % ns, b, o); o += 4 * ns
    if o != len(b):
        fail("surface message of %d bytes, %d expected" % (len(b), o))
    return dict(index=index, ns=ns, nt=nt, r=r, X=X, W=W, tri=tri, vid=vid)


def parse_frame(b):
    r, cub, late = struct.unpack_from("<3I", b, 4)
    step, t, wall = struct.unpack_from("<3d", b, 16)
    q = struct.unpack_from("<%dd" % r, b, 40)
    (commands,) = struct.unpack_from("<d", b, 40 + 8 * r)
    return dict(r=r, cubature=cub, late=late, step=step, time=t, q=q, commands=commands)


def decode(s, q, i):
    r = s["r"]
    return [s["X"][3 * i + d] + sum(s["W"][(3 * i + d) * r + k] * q[k] for k in range(r)) for d in range(3)]


async def new_surface(ws, seconds=3, want=10):
    """After a switch: the surface that comes, and how many frames on it (up to want)."""
    t0, surf, after = time.time(), None, 0
    while time.time() - t0 < seconds and after < want:
        m = await ws.recv()
        if isinstance(m, str):
            continue
        if m[:4] == b"SURF":
            surf = parse_surface(m)
        elif surf and parse_frame(m)["cubature"] == surf["index"]:
            after += 1
    return surf, after


async def ws_test(port, vid, k):
    import websockets
    url = "ws://127.0.0.1:%d/" % port
    # a page of another origin is refused
    try:
        async with websockets.connect(url, subprotocols=["crom"], origin="http://evil.example") as ws:
            await ws.recv()
        fail("a WebSocket from another origin was accepted")
    except (websockets.exceptions.InvalidHandshake, OSError) as e:
        print("foreign origin: refused (%s)" % type(e).__name__)
    async with websockets.connect(url, subprotocols=["crom"], max_size=None,
                                  origin="http://127.0.0.1:%d" % port) as ws:
        hello = json.loads(await ws.recv())
        s = parse_surface(await ws.recv())
        print("greeting: rank %d, %d vertices; surface: %d vertices, %d triangles" %
              (hello["rank"], hello["vertices"], s["ns"], s["nt"]))
        if s["r"] != hello["rank"] or s["ns"] < 4 or s["nt"] < 4:
            fail("greeting and surface disagree")
        i = s["vid"].index(vid)

        async def frames(seconds):
            out, texts, t0 = [], [], time.time()
            while time.time() - t0 < seconds:
                m = await ws.recv()
                (texts if isinstance(m, str) else out).append(m)
            return [parse_frame(f) for f in out], texts

        f0, _ = await frames(0.3)
        if not f0:
            fail("no frames")
        x0 = decode(s, f0[-1]["q"], i)
        target = [x0[0] + 0.02, x0[1] - 0.06, x0[2]]  # (down and aside: within what compression modes can do)
        await ws.send("drag #%d %.6f,%.6f,%.6f %g" % (vid, *target, k))
        fs, texts = await frames(1.5)
        oks = [t for t in texts if t.startswith("ok ")]
        if not oks:
            fail("no 'ok N' for the drag: %s" % texts)
        n = int(oks[0][3:])
        shown = [f for f in fs if f["commands"] >= n]
        if not shown:
            fail("no frame shows command %d" % n)
        x1 = decode(s, fs[-1]["q"], i)
        d0, d1 = math.dist(x0, target), math.dist(x1, target)
        print("drag: %d frames in 1.5 s; vertex %d from %.4f m to %.4f m of the cursor" % (len(fs), vid, d0, d1))
        if not d1 < 0.5 * d0:
            fail("the dragged vertex did not follow (%.4f -> %.4f m)" % (d0, d1))
        # bad commands: one 'error: ...' each, frames go on
        bad = ["bogus 1", "drag nowhere 0,0,0", "drag #%d nan,0,0" % vid, "drag #99999999 0,0,0", "quit",
               "schedule /etc/passwd", "x" * 5000]
        for b in bad:
            await ws.send(b)
        await ws.send(b"\x00\x01binary")
        fs2, texts = await frames(1.0)
        errs = [t for t in texts if t.startswith("error: ")]
        print("bad commands: %d sent, %d refused; %d frames after them" % (len(bad) + 1, len(errs), len(fs2)))
        for e in errs:
            print("  " + e)
        if len(errs) != len(bad) + 1 or not fs2:
            fail("bad commands: %s" % texts)
        # leave mid-drag: the server releases it (the next page sees the body go back)
        await ws.send("drag #%d %.6f,%.6f,%.6f %g" % (vid, *target, k))
        await frames(0.3)
    async with websockets.connect(url, subprotocols=["crom"], max_size=None) as ws:
        await ws.recv()
        s = parse_surface(await ws.recv())
        await asyncio.sleep(1.5)
        fs = []
        t0 = time.time()
        while time.time() - t0 < 0.3:
            m = await ws.recv()
            if not isinstance(m, str):
                fs.append(parse_frame(m))
        x2 = decode(s, fs[-1]["q"], i)
        d2 = math.dist(x2, x0)
        print("after the first page left mid-drag: vertex %d is %.4f m from where it started (%.4f m from the cursor)"
              % (vid, d2, math.dist(x2, target)))
        if not d2 < 0.5 * math.dist(x0, target):
            fail("the drag of a page that went away was not released")
        if len(hello["offers"]) < 2:
            return
        # switch the run to an offered cubature: the page gets its surface, then its frames
        await ws.send("schedule " + hello["offers"][1])
        s2, after = await new_surface(ws)
        if not s2 or after < 10:
            fail("schedule: no new surface or no frames on it")
        print("schedule %s: surface %d (%d vertices, %d triangles, was %d, %d), %d frames on it" %
              (hello["offers"][1], s2["index"], s2["ns"], s2["nt"], s["ns"], s["nt"], after))
        if s2["index"] != 1 or s2["nt"] == s["nt"]:
            fail("schedule: the surface did not change")
        # and back to the first: the run loads it again as its third cubature, the page's index is 0
        await ws.send("schedule " + hello["offers"][0])
        s3, after = await new_surface(ws)
        if not s3 or after < 10 or s3["index"] != 0 or s3["nt"] != s["nt"]:
            fail("schedule back to the first cubature: %s, %d frames" % (s3 and s3["index"], after))
        print("schedule %s: back on surface 0, %d frames on it" % (hello["offers"][0], after))


async def frames_test(port, r):
    """greeting, surface and 20 frames of a rank-r model, each 48 + 8 r bytes"""
    import websockets
    async with websockets.connect("ws://127.0.0.1:%d/" % port, subprotocols=["crom"], max_size=None) as ws:
        hello = json.loads(await ws.recv())
        s = parse_surface(await ws.recv())
        sizes = set()
        for _ in range(20):
            m = await ws.recv()
            if isinstance(m, str):
                continue
            f = parse_frame(m)
            if f["r"] != r or len(m) != 48 + 8 * r:
                fail("a frame of rank %d and %d bytes, expected %d and %d" % (f["r"], len(m), r, 48 + 8 * r))
            sizes.add(len(m))
        print("rank %d: greeting says %d, surface %d rows, frames of %s bytes" % (r, hello["rank"], s["r"], sorted(sizes)))
        if hello["rank"] != r or s["r"] != r:
            fail("rank %d expected" % r)


# ---------------------------------------------------------------- WebDriver

class Browser:
    def __init__(self, width=640, height=480):
        s = socket.socket(); s.bind(("127.0.0.1", 0)); self.port = s.getsockname()[1]; s.close()
        self.proc = subprocess.Popen(["chromedriver", "--port=%d" % self.port], stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL)
        for _ in range(100):
            try:
                self.call("GET", "/status")
                break
            except OSError:
                time.sleep(0.1)
        caps = {"capabilities": {"alwaysMatch": {"browserName": "chrome", "goog:chromeOptions": {
            "binary": os.environ.get("CHROMIUM", "/usr/bin/chromium"),
            "args": ["--headless=new", "--no-sandbox", "--disable-dev-shm-usage", "--use-angle=swiftshader",
                     "--enable-unsafe-swiftshader", "--window-size=%d,%d" % (width, height)]}}}}
        self.sid = self.call("POST", "/session", caps)["sessionId"]

    def call(self, method, path, body=None):
        req = urllib.request.Request("http://127.0.0.1:%d%s" % (self.port, path), method=method,
                                     data=None if body is None else json.dumps(body).encode(),
                                     headers={"Content-Type": "application/json"})
        with urllib.request.urlopen(req, timeout=60) as r:
            return json.loads(r.read())["value"] if method != "GET" or path != "/status" else None

    def s(self, method, path, body=None):
        return self.call(method, "/session/%s%s" % (self.sid, path), body)

    def js(self, script):
        return self.s("POST", "/execute/sync", {"script": script, "args": []})

    def wait(self, script, seconds=20):
        t0 = time.time()
        while time.time() - t0 < seconds:
            v = self.js(script)
            if v:
                return v
            time.sleep(0.1)
        fail("timed out waiting for: " + script)

    def pointer(self, steps):
        self.s("POST", "/actions", {"actions": [{"type": "pointer", "id": "mouse", "parameters": {"pointerType": "mouse"},
                                                 "actions": steps}]})

    def screenshot(self, path):
        with open(path, "wb") as f:
            f.write(base64.b64decode(self.s("GET", "/screenshot")))

    def close(self):
        try:
            self.s("DELETE", "")
        finally:
            self.proc.terminate()
            self.proc.wait()


TOP_VERTEX = """const s = cromView.surface(); let b = 0;
for (let i = 1; i < s.ns; i++) if (cromView.position(i)[1] > cromView.position(b)[1]) b = i;
return [b, s.vid[b], ...cromView.screenOf(b)];"""


def browser_test(port, outdir):
    from PIL import Image, ImageChops
    b = Browser()
    try:
        b.s("POST", "/url", {"url": "http://127.0.0.1:%d/" % port})
        b.wait("return window.cromView && cromView.frames > 5 && cromView.drawn > 5")
        print("page: state %s, %s frames, %s drawn" % tuple(b.js("return [cromView.state, cromView.frames, cromView.drawn]")))
        i, vid, x, y, _ = b.js(TOP_VERTEX)
        x, y = int(round(x)), int(round(y))
        time.sleep(0.5)
        rest = os.path.join(outdir, "rest.png"); b.screenshot(rest)
        # press on the top vertex and push the cursor down and aside, holding
        b.pointer([{"type": "pointerMove", "x": x, "y": y, "origin": "viewport", "duration": 0},
                   {"type": "pointerDown", "button": 0},
                   {"type": "pointerMove", "x": x + 15, "y": y + 50, "origin": "viewport", "duration": 300}])
        picked = b.wait("return cromView.picked && cromView.picked.pos && cromView.picked")
        d0 = math.dist(picked["anchor"], picked["target"])
        time.sleep(1.5)
        picked = b.js("return cromView.picked")
        d1 = math.dist(picked["pos"], picked["target"])
        print("mouse drag: vertex #%d, the cursor's point %.4f m from where it was pressed; the vertex %.4f m from it "
              "after 1.5 s" % (picked["vid"], d0, d1))
        if not d1 < 0.5 * d0:
            fail("the vertex under the mouse did not follow the cursor")
        dragged = os.path.join(outdir, "dragged.png"); b.screenshot(dragged)
        b.pointer([{"type": "pointerUp", "button": 0}])
        b.wait("return cromView.picked === null")
        A, B = Image.open(rest).convert("RGB"), Image.open(dragged).convert("RGB")
        bg = A.getpixel((A.width - 3, A.height - 3))
        body = sum(1 for p in A.getdata() if max(abs(p[k] - bg[k]) for k in range(3)) > 30)
        print("screenshot at rest: %dx%d, %d pixels of body (%.1f%%)" % (A.width, A.height, body,
                                                                        100.0 * body / (A.width * A.height)))
        if body < 0.01 * A.width * A.height:
            fail("the screenshot does not show the body")
        box = (max(0, x - 80), max(0, y - 60), min(A.width, x + 100), min(A.height, y + 120))
        diff = ImageChops.difference(A.crop(box), B.crop(box))
        changed = sum(1 for p in diff.getdata() if max(p) > 30)
        print("around the dragged point (%d x %d px): %d pixels changed by the drag" %
              (box[2] - box[0], box[3] - box[1], changed))
        if changed < 200:
            fail("the drag does not show in the screenshot")
        stats = b.js("return [cromView.frames, cromView.drawn, cromView.errors.length]")
        print("page: %d frames, %d drawn, %d errors" % tuple(stats))
    finally:
        b.close()


def load_test(port, seconds):
    b = Browser()
    try:
        b.s("POST", "/url", {"url": "http://127.0.0.1:%d/" % port})
        b.wait("return window.cromView && cromView.frames > 5 && cromView.drawn > 5", 60)
        i, vid, x, y, _ = b.js(TOP_VERTEX)
        steps = [{"type": "pointerMove", "x": int(x), "y": int(y), "origin": "viewport", "duration": 0},
                 {"type": "pointerDown", "button": 0}]
        n = int(seconds * 10)
        for k in range(n):  # one turn a second, 10 moves a second
            a = 2 * math.pi * k / 10
            steps.append({"type": "pointerMove", "x": int(x + 30 * math.sin(a)), "y": int(y - 30 + 30 * math.cos(a)),
                          "origin": "viewport", "duration": 100})
        steps.append({"type": "pointerUp", "button": 0})
        count = "return [cromView.frames, cromView.drawn, cromView.decodeMs.length, cromView.latencyMs.length]"
        f0, d0, k0, l0 = b.js(count)
        t0 = time.time()
        b.pointer(steps)  # (returns when the moves are done)
        dt = time.time() - t0
        f1, d1, k1, l1 = b.js(count)
        # the page's clock is coarse (0.1 ms): the decode time is a mean
        dec, lat = b.js("const a = cromView.decodeMs.slice(-%d), l = cromView.latencyMs.slice(-%d).sort((x, y) => x - y);"
                        "return [a.reduce((x, y) => x + y, 0) / Math.max(a.length, 1), l.length ? l[l.length >> 1] : 0]"
                        % (max(k1 - k0, 1), max(l1 - l0, 1)))
        print("page: %.1f frames/s received, %.1f drawn/s over %.1f s; decode %.4f ms (mean of %d); command to frame "
              "%.3f ms (median of %d)" % ((f1 - f0) / dt, (d1 - d0) / dt, dt, dec, k1 - k0, lat, l1 - l0))
    finally:
        b.close()


if __name__ == "__main__":
    mode, port = sys.argv[1], int(sys.argv[2])
    if mode == "ws":
        asyncio.run(ws_test(port, int(sys.argv[3]), float(sys.argv[4])))
    elif mode == "frames":
        asyncio.run(frames_test(port, int(sys.argv[3])))
    elif mode == "browser":
        browser_test(port, sys.argv[3])
    elif mode == "load":
        load_test(port, float(sys.argv[3]))
    else:
        fail("unknown mode " + mode)
