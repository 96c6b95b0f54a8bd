#!/usr/bin/env python3
"""The dashboard in a real browser: Debian's chromium, headless, driven over the Chrome DevTools
protocol (python3-websocket), against real processes on loopback (a coordinator with --http and a
worker) and real files.

Checks (issue 16's acceptance): the page loads with no console error; a map renders (screenshot not
blank; the pixels at the map's smallest and largest cell have the palette's end colours); clicking a
cell shows values equal, bit for bit, to `bistable point` with the command line the page gives; a running
sweep's progress advances on the page and its partial map fills in; a coordinator behind TLS and
tokens answers 401 and no data without a token, 403 to a worker token, serves a viewer token (header
or the HttpOnly cookie /api/session sets), and a viewer token can neither submit nor cancel over gRPC.

Usage: dashboard_test.py BUILD_DIR SOURCE_DIR [FIGURES_DIR]   (FIGURES_DIR: keep the screenshots there)
Exits 77 (skipped) when chromium or python3-websocket is missing.
"""
import base64
import io
import json
import os
import re
import shutil
import signal
import ssl
import subprocess
import sys
import tempfile
import time
import urllib.error
import urllib.request

try:
    import websocket  # python3-websocket
except ImportError:
    print("skipped: python3-websocket is not installed (scripts/setup.sh installs it)")
    sys.exit(77)
CHROMIUM = shutil.which("chromium")
if not CHROMIUM:
    print("skipped: chromium is not installed (scripts/setup.sh installs it)")
    sys.exit(77)
from PIL import Image  # python3-pil

BUILD, SOURCE = sys.argv[1], sys.argv[2]
FIGURES = sys.argv[3] if len(sys.argv) > 3 else None
BISTABLE = os.path.join(BUILD, "client", "bistable")
COORD = os.path.join(BUILD, "server", "bistable-coordinator")
WORKER = os.path.join(BUILD, "worker", "bistable-worker")
STOPS = [(68, 1, 84), (59, 82, 139), (33, 145, 140), (94, 201, 98), (253, 231, 37)]  # app.js's palettes
DIVERGING = [(33, 102, 172), (255, 255, 255), (178, 24, 43)]  # frf_db and lle, as the CLI's figures

SPEC = """name = "{name}"
model = "coupled"
[params]
eps = 1.0
eta = 0.1
eta_r = 0.075
phi = 2.0
lambda = 0.8
[axes]
alpha = {{ linspace = [0.1, 2.0, {na}] }}
omega = {{ linspace = [0.2, 2.5, {no}] }}
[integration]
integrator = "rk4"
dt = 0.01
t_end = {t_end}
t_keep = {t_keep}
[metrics]
store = ["frf_db", "lle", "motion", "period", "hd_index", "hd_peaks", "edr_t"]
chaos_threshold = 0.01
"""

procs = []
failures = []


def check(cond, what):
    print(("ok   " if cond else "FAIL ") + what, flush=True)
    if not cond:
        failures.append(what)


def start(cmd, pattern, env=None):
    """Starts a process and returns it with the groups of the first stdout line matching pattern."""
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    procs.append(p)
    deadline = time.time() + 20
    while time.time() < deadline:
        line = p.stdout.readline()
        if not line:
            break
        m = re.search(pattern, line)
        if m:
            return p, m.groups()
    raise RuntimeError(f"{cmd[0]} did not print {pattern!r}: {p.stderr.read() if p.poll() is not None else ''}")


def get(url, headers=None, ctx=None):
    req = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(req, timeout=30, context=ctx) as r:
            return r.status, r.read().decode(), dict(r.headers)
    except urllib.error.HTTPError as e:
        return e.code, e.read().decode(), dict(e.headers)


def run(cmd, env=None):
    return subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=env)


class Browser:
    """One headless chromium page over the DevTools protocol."""

    def __init__(self, tmp):
        args = [CHROMIUM, "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run", "--disable-extensions",
                "--remote-debugging-port=0", "--user-data-dir=" + os.path.join(tmp, "chromium"),
                "--window-size=1280,1500", "--force-device-scale-factor=1", "about:blank"]
        self.proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        procs.append(self.proc)
        browser_ws = None
        deadline = time.time() + 30
        while time.time() < deadline and not browser_ws:
            line = self.proc.stderr.readline()
            m = re.search(r"DevTools listening on (ws://\S+)", line)
            if m:
                browser_ws = m.group(1)
        if not browser_ws:
            raise RuntimeError("chromium did not start")
        port = re.search(r":(\d+)/", browser_ws).group(1)
        pages = json.loads(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10).read())
        page = [p for p in pages if p["type"] == "page"][0]
        self.ws = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=60, suppress_origin=True)
        self.next_id = 0
        self.errors = []
        self.loaded = False
        for domain in ("Page", "Runtime", "Log"):
            self.call(domain + ".enable")

    def _event(self, msg):
        method, params = msg.get("method"), msg.get("params", {})
        if method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
            self.errors.append("console: " + " ".join(str(a.get("value", a.get("description"))) for a in params.get("args", [])))
        elif method == "Runtime.exceptionThrown":
            self.errors.append("exception: " + json.dumps(params.get("exceptionDetails", {}))[:400])
        elif method == "Log.entryAdded" and params.get("entry", {}).get("level") == "error":
            self.errors.append("log: " + params["entry"].get("text", "") + " " + params["entry"].get("url", ""))
        elif method == "Page.loadEventFired":
            self.loaded = True

    def call(self, method, **params):
        self.next_id += 1
        mid = self.next_id
        self.ws.send(json.dumps({"id": mid, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv())
            if msg.get("id") == mid:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            self._event(msg)

    def eval(self, expr):
        r = self.call("Runtime.evaluate", expression=expr, awaitPromise=True, returnByValue=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{expr}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def wait(self, expr, seconds=20):
        deadline = time.time() + seconds
        while time.time() < deadline:
            v = self.eval(expr)
            if v:
                return v
            time.sleep(0.2)
        return None

    def navigate(self, url):
        self.loaded = False
        self.call("Page.navigate", url=url)
        deadline = time.time() + 20
        while not self.loaded and time.time() < deadline:
            self.eval("1")

    def screenshot(self, path=None, clip=None):
        params = {"format": "png"}
        if clip:
            params["clip"] = dict(clip, scale=1)
        data = base64.b64decode(self.call("Page.captureScreenshot", **params)["data"])
        if path:
            with open(path, "wb") as f:
                f.write(data)
        return Image.open(io.BytesIO(data)).convert("RGB")

    def click(self, x, y):
        for kind in ("mouseMoved", "mousePressed", "mouseReleased"):
            self.call("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left", clickCount=1)

    def close(self):
        self.ws.close()


def palette(v, lo, hi, diverging=False):
    stops = DIVERGING if diverging else STOPS
    if diverging:  # symmetric about 0
        hi = max(abs(lo), abs(hi), 1e-12)
        lo = -hi
    t = (v - lo) / (hi - lo) if hi > lo else 0.5
    t = min(1.0, max(0.0, t)) * (len(stops) - 1)
    i = min(len(stops) - 2, int(t))
    f = t - i
    return tuple(round(a + f * (b - a)) for a, b in zip(stops[i], stops[i + 1]))


def figure(name):
    return os.path.join(FIGURES, f"dashboard-{name}.png") if FIGURES else None


def open_coordinator(tmp, data_name="data", worker=True):
    """Coordinator (open, loopback) + one worker; returns its gRPC address, dashboard URL and process."""
    data = os.path.join(tmp, data_name)
    coord, (grpc_port,) = start([COORD, "--listen", "127.0.0.1:0", "--data", data, "--http", "127.0.0.1:0",
                                 "--log-level", "warn"], r"listening on 127\.0\.0\.1:(\d+)")
    http_port = re.search(r":(\d+)/", coord.stdout.readline()).group(1)
    addr = "127.0.0.1:" + grpc_port
    if worker:
        w = subprocess.Popen([WORKER, "--coordinator", addr, "--threads", "1", "--log-level", "warn"],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        procs.append(w)
    return addr, "http://127.0.0.1:" + http_port, coord


def stop(p, sig=signal.SIGTERM):
    p.send_signal(sig)
    try:
        p.wait(timeout=15)
    except subprocess.TimeoutExpired:
        p.kill()
        p.wait()


def write_spec(tmp, name, na, no, t_end, t_keep, extra_toml=""):
    path = os.path.join(tmp, name.replace(" ", "_") + ".toml")
    with open(path, "w") as f:
        f.write(SPEC.format(name=name, na=na, no=no, t_end=t_end, t_keep=t_keep) + extra_toml)
    return path


def submit(addr, tmp, name, na, no, t_end, t_keep, env=None, extra=()):
    path = write_spec(tmp, name, na, no, t_end, t_keep)
    return run([BISTABLE, "submit", path, "--coordinator", addr, "--json", *extra], env=env)


def api(base, route, host=None):
    """GET base + route as JSON: (status, parsed body or raw text)."""
    status, body, _ = get(base + route, {"Host": host} if host else None)
    try:
        return status, json.loads(body)
    except ValueError:
        return status, body


def browser_checks(tmp):
    addr, base, coord = open_coordinator(tmp)
    r = submit(addr, tmp, "published map", 16, 20, 200.0, 100.0)
    assert r.returncode == 0, r.stderr
    done_id = json.loads(r.stdout)["id"]
    w = run([BISTABLE, "status", done_id, "--coordinator", addr, "--watch", "--json"])
    check('"done"' in w.stdout, "the small sweep is published")

    b = Browser(tmp)
    b.navigate(base + "/")
    check(b.wait("document.querySelectorAll('#sweeps tbody tr').length >= 1") is not None, "the sweeps table lists the sweep")
    b.eval(f"window.dashboard.openSweep('{done_id}')")
    b.eval("document.getElementById('metric').value = 'frf_db'; document.getElementById('metric').onchange(); 1")
    check(b.wait("window.dashboard.state.map && window.dashboard.state.map.metric === 'frf_db'") is not None, "the frf_db map loads")
    time.sleep(0.3)
    m = b.eval("window.dashboard.state.map")
    check(m.get("diverging") is True, "frf_db is coloured blue-white-red about 0 dB, as in the CLI's figures")
    m0_values = m["values"]
    rect = b.eval("(() => { const r = document.getElementById('map').getBoundingClientRect(); return [r.left, r.top]; })()")
    shot = b.screenshot(figure("map"))
    nx, ny = len(m["x"]["values"]), len(m["y"]["values"])
    values = m["values"]
    colours = set(shot.crop((int(rect[0]) + 70, int(rect[1]) + 20, int(rect[0]) + 600, int(rect[1]) + 460)).getdata())
    check(len(colours) > 20, f"the map is not blank ({len(colours)} colours)")
    finite = [(v, k) for k, v in enumerate(values) if v is not None]
    for label, (v, k) in (("smallest", min(finite)), ("largest", max(finite))):
        ix, iy = k % nx, k // nx
        cx, cy = b.eval(f"window.dashboard.cellCenter({ix}, {iy})")
        px = shot.getpixel((int(rect[0] + 1 + cx), int(rect[1] + 1 + cy)))
        want = palette(v, m["min"], m["max"], m["diverging"])
        check(all(abs(a - c) <= 3 for a, c in zip(px, want)), f"{label} cell ({ix}, {iy}) = {v:.4g} dB is drawn {px}, palette {want}")

    # Hover, then click a cell: the page's numbers equal bistable point's with the page's command line.
    ix, iy = nx // 2, ny // 3
    cx, cy = b.eval(f"window.dashboard.cellCenter({ix}, {iy})")
    b.call("Input.dispatchMouseEvent", type="mouseMoved", x=rect[0] + 1 + cx, y=rect[1] + 1 + cy)
    tip = b.wait("!document.getElementById('tip').hidden && document.getElementById('tip').textContent")
    check(tip is not None and "frf_db" in tip and "omega" in tip, f"hover shows the cell's parameters and value: {tip!r}")
    b.screenshot(figure("hover"))
    b.click(rect[0] + 1 + cx, rect[1] + 1 + cy)
    cell = b.wait("window.dashboard.state.cell", 60)
    check(cell is not None, "clicking a cell computes it")
    want_point = iy * nx + ix  # alpha (y) is the first axis, omega (x) the last
    check(cell and cell["point"] == want_point, f"the clicked cell is point {want_point}")
    cmd = cell["command"].split()
    cmd[0] = BISTABLE
    cli = run(cmd)
    check(cli.returncode == 0 and json.loads(cli.stdout) == cell["result"],
          "the cell's values equal `bistable point --json` bit for bit (" + " ".join(cell["command"].split()[:8]) + " ...)")
    shown = b.eval("document.querySelector('#cell-metrics td[data-metric=\"frf_db\"]').textContent")
    check(shown == repr(json.loads(cli.stdout)["frf_db"]) or float(shown) == json.loads(cli.stdout)["frf_db"],
          f"the page shows frf_db = {shown}")
    b.eval("document.getElementById('cell-view').scrollIntoView(); 1")
    time.sleep(0.3)
    b.screenshot(figure("cell"))
    b.eval("window.scrollTo(0, 0); 1")

    # Query box.
    b.eval("document.getElementById('query').value = 'motion == chaotic'; document.getElementById('query-form').requestSubmit(); 1")
    q = b.wait("window.dashboard.state.mask && document.getElementById('query-result').textContent")
    check(q is not None and re.match(r"\d+ of 320 cells", q or ""), f"the query reports count and area: {q!r}")
    b.screenshot(figure("query"))
    b.eval("document.getElementById('query-clear').click(); 1")
    b.eval("document.getElementById('metric').value = 'motion'; document.getElementById('metric').onchange(); 1")
    legend = b.wait("window.dashboard.state.map && window.dashboard.state.map.metric === 'motion' && window.dashboard.state.map.categories.map(c => c[1]).join(',')")
    check(legend is not None and "chaotic" in legend, f"a category map names its categories: {legend}")
    time.sleep(0.3)
    shot = b.screenshot(figure("motion"))
    # The motion codes in the CLI figures' colours (engine CategoryColour): each shown kind's cell in its colour.
    m = b.eval("window.dashboard.state.map")
    cli_colours = {"intrawell": (0x2c, 0x7b, 0xb6), "interwell": (0xfd, 0xae, 0x61), "chaotic": (0xd7, 0x19, 0x1c)}
    nx = len(m["x"]["values"])
    seen = 0
    for code, name, colour in m["categories"]:
        if name not in cli_colours or code not in m["values"]:
            continue
        check(colour.lower() == "#%02x%02x%02x" % cli_colours[name], f"{name} has the CLI's colour: {colour}")
        k = m["values"].index(code)
        cx, cy = b.eval(f"window.dashboard.cellCenter({k % nx}, {k // nx})")
        px = shot.getpixel((int(rect[0] + 1 + cx), int(rect[1] + 1 + cy)))
        check(all(abs(a - c) <= 3 for a, c in zip(px, cli_colours[name])), f"a {name} cell is drawn {px}, the CLI's {cli_colours[name]}")
        seen += 1
    check(seen >= 2, f"at least two motion kinds on the map to compare ({seen})")

    # A running sweep: its progress advances on the page and its map fills in.
    # (long enough to be seen running: the server caches a live map for 2 s)
    r = submit(addr, tmp, "running map", 100, 120, 1200.0, 600.0)
    run_id = json.loads(r.stdout)["id"]
    b.eval(f"window.dashboard.openSweep('{run_id}')")
    progress = f"(() => {{ const r = document.querySelector('#sweeps tr[data-id=\"{run_id}\"]'); return r ? r.children[5].textContent : ''; }})()"
    first = b.wait(f"(() => {{ const t = {progress}; return t && !t.startsWith('0 /') ? t : ''; }})()", 30)
    second = b.wait(f"(() => {{ const t = {progress}; return t && t !== '{first}' ? t : ''; }})()", 30)
    check(first and second and int(second.split()[0]) > int(first.split()[0]), f"a running sweep's progress advances: {first} -> {second}")
    partial = b.wait("window.dashboard.state.map && window.dashboard.state.map.partial && window.dashboard.state.map.values.some(v => v !== null) && window.dashboard.state.map.values.some(v => v === null)", 20)
    check(partial is not None, "the running sweep's map is partial: some cells stored, some not yet")
    b.screenshot(figure("running"))
    run([BISTABLE, "cancel", run_id, "--coordinator", addr])

    # A map with an axis over 1024 values is decimated on the server (every 2nd omega of 1500); hover
    # and click map the shown cell to the sweep's own point index.
    r = submit(addr, tmp, "long axis", 2, 1500, 20.0, 10.0)
    long_id = json.loads(r.stdout)["id"]
    w = run([BISTABLE, "status", long_id, "--coordinator", addr, "--watch", "--json"])
    check('"done"' in w.stdout, "the long-axis sweep is published")
    status, m = api(base, f"/api/map?id={long_id}&metric=frf_db&x=omega&y=alpha")
    check(status == 200 and m["stride"] == {"x": 2, "y": 1} and len(m["x"]["values"]) == 750 and m["x"]["size"] == 1500
          and len(m["values"]) == 2 * 750, f"a 1500-value axis is shown every 2nd value (stride {m.get('stride') if status == 200 else m})")
    if status == 200:
        want = 0.2 + 20 * (2.5 - 0.2) / 1499
        check(abs(m["x"]["values"][10] - want) < 1e-12, f"shown x value 10 is omega[20] = {want}: {m['x']['values'][10]}")
    b.eval(f"window.dashboard.openSweep('{long_id}')")
    b.eval("document.getElementById('metric').value = 'frf_db'; document.getElementById('metric').onchange(); 1")
    got = b.wait(f"window.dashboard.state.map && window.dashboard.state.map.sweep === '{long_id}' && window.dashboard.state.map.metric === 'frf_db' "
                 "&& window.dashboard.state.map.x.stride === 2")
    item = b.eval("window.dashboard.itemOf({ix: 10, iy: 1})") if got else None
    check(item is not None and item["point"] == 1 * 1500 + 20, f"shown cell (10, 1) of the decimated map is point 1520: {item}")
    note = b.eval("document.getElementById('map-state').textContent")
    check(note is not None and "1 of every 2 cells shown along x" in note, f"the page says the map is decimated: {note!r}")
    time.sleep(1.5)
    check(not b.errors, "no console errors: " + "; ".join(b.errors))
    b.close()

    # The coordinator restarted on the same data: every sweep published before is served (spec from the index).
    stop(coord)
    addr, base, coord = open_coordinator(tmp)
    for route in (f"/api/sweep?id={done_id}", f"/api/map?id={done_id}&metric=frf_db", f"/api/query?id={done_id}&q=frf_db%20%3C%200",
                  f"/api/cell?id={done_id}&point=3&ic=0"):
        status, body = api(base, route)
        check(status == 200 and done_id in json.dumps(body), f"after a restart {route.split('?')[0]} serves the earlier sweep -> {status}")
    status, body = api(base, f"/api/map?id={done_id}&metric=frf_db")
    check(status == 200 and body["values"] == m0_values, "after a restart the map is the one published before")


def serve_checks(tmp):
    """Tokenless servers: Host names other than the loopback's are refused (DNS rebinding); a sweep too big
    for a live map says so instead of looking every item up; `bistable run --serve` serves the sweeps
    of earlier runs of its data directory, and a refined sweep's refine_level / refine_fill."""
    addr, base, coord = open_coordinator(tmp, "data-bare", worker=False)
    # 513 x 513 = 263,169 items > 2^18: planned (no worker), its partial map is not looked up.
    r = submit(addr, tmp, "too big to watch", 513, 513, 20.0, 10.0)
    check(r.returncode == 0, "a 513 x 513 sweep is submitted: " + r.stderr.strip()[:80])
    big = json.loads(r.stdout)["id"] if r.returncode == 0 else "0"
    t0 = time.time()
    status, m = api(base, f"/api/map?id={big}&metric=frf_db")
    check(status == 200 and m["partial"] and "not shown above 262144 items" in m["note"] and all(v is None for v in m["values"])
          and m["stride"] == {"x": 1, "y": 1} and len(m["values"]) == 513 * 513,
          f"a running sweep over 2^18 items: no live lookup, a note instead ({time.time() - t0:.2f} s): {m.get('note') if status == 200 else m}")
    status, q = api(base, f"/api/query?id={big}&q=frf_db%20%3C%200")
    check(status == 409 and "not shown above" in q.get("error", ""), f"its query says why it has no answer -> {status}")
    status, info = api(base, f"/api/sweep?id={big}")
    check(status == 200 and info["live_map"] is False, "/api/sweep says the live map is off")
    # DNS rebinding: a page elsewhere reaches the tokenless port under its own host name.
    port = base.rsplit(":", 1)[1]
    for route in ("/api/sweeps", f"/api/sweep?id={big}", f"/api/map?id={big}&metric=frf_db", "/", "/app.js", "/metrics"):
        status, body = api(base, route, host="evil.example:" + port)
        text = json.dumps(body)
        check(status == 421 and big not in text and "evil" not in text and "frf" not in text and len(text) < 200,
              f"Host evil.example: {route} -> {status}, no data, header not echoed")
    for host in ("localhost:" + port, "127.0.0.1:" + port, "[::1]:" + port, "localhost"):
        status, body = api(base, "/api/sweeps", host=host)
        check(status == 200 and big in json.dumps(body), f"Host {host}: served")
    status, body = api(base, "/healthz", host="evil.example")
    check(status == 200, "/healthz answers any host (no data)")
    run([BISTABLE, "cancel", big, "--coordinator", addr])
    stop(coord)

    # `bistable run --serve`: an earlier run's sweeps of the data directory, and a refined sweep.
    data = os.path.join(tmp, "data-run")
    refined = write_spec(tmp, "refined", 17, 17, 100.0, 50.0, '[refine]\nlevels = 2\ncriterion = "motion"\nmixed_after = 2\n')
    r = run([BISTABLE, "run", refined, "--data", data, "--no-plots", "--json", "--quiet"])
    check(r.returncode == 0, "a refined sweep runs: " + r.stderr.strip()[:120])
    ref_id = json.loads(r.stdout)["id"] if r.returncode == 0 else "0"
    other = write_spec(tmp, "served", 3, 3, 20.0, 10.0)
    p = subprocess.Popen([BISTABLE, "run", other, "--data", data, "--no-plots", "--quiet", "--serve", "127.0.0.1:0"],
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    procs.append(p)
    m = re.search(r"dashboard on (http://127\.0\.0\.1:\d+)/", p.stderr.readline())
    check(m is not None, "bistable run --serve prints its dashboard address")
    if not m:
        return
    sbase = m.group(1)
    status, info = api(sbase, f"/api/sweep?id={ref_id}")
    names = [x["name"] for x in info.get("metrics", [])] if status == 200 else []
    check(status == 200 and "refine_level" in names and "refine_fill" in names,
          f"run --serve opens a sweep of an earlier run, and offers refine_level/refine_fill: {status} {names}")
    status, fill = api(sbase, f"/api/map?id={ref_id}&metric=refine_fill")
    k_interp, nx = None, 17
    check(status == 200 and [c[1] for c in fill["categories"]] == ["computed", "interpolated", "chaotic_mixed"],
          f"refine_fill is a category map -> {status}")
    status, level = api(sbase, f"/api/map?id={ref_id}&metric=refine_level")
    check(status == 200 and level["min"] is not None and level["min"] == 0 and level["max"] == 2,
          f"refine_level map -> {status} ({level.get('min') if status == 200 else ''} .. {level.get('max') if status == 200 else ''})")
    if status == 200 and fill.get("values"):
        nx = len(fill["x"]["values"])
        k = k_interp = next((k for k, v in enumerate(fill["values"]) if v == 1), None)
        check(k is not None, "the refined map has interpolated cells")
        if k is not None:
            point = (k // nx) * 17 + k % nx  # y = alpha (first axis), x = omega
            status, cell = api(sbase, f"/api/cell?id={ref_id}&point={point}&ic=0")
            check(status == 200 and cell["refine_fill"] == "interpolated" and "interpolated" in cell["refine_note"]
                  and "computed now" in cell["refine_note"], f"an interpolated cell says so: {cell.get('refine_note') if status == 200 else cell}")
        k = fill["values"].index(0)
        status, cell = api(sbase, f"/api/cell?id={ref_id}&point={(k // nx) * 17 + k % nx}&ic=0")
        check(status == 200 and cell["refine_fill"] == "computed" and cell["refine_note"] == "", "a computed cell has no note")
    status, _ = api(sbase, "/api/sweeps", host="attacker.example")
    check(status == 421, f"run --serve refuses a foreign Host -> {status}")
    # On the page: the refine_fill map, and a clicked interpolated cell marked as such above its values.
    if status and fill.get("values") and k_interp is not None:
        os.makedirs(os.path.join(tmp, "browser2"), exist_ok=True)
        b = Browser(os.path.join(tmp, "browser2"))  # a profile of its own (the first chromium still holds its own)
        b.navigate(sbase + "/")
        b.wait("document.querySelectorAll('#sweeps tbody tr').length >= 2")
        b.eval(f"window.dashboard.openSweep('{ref_id}')")
        b.eval("document.getElementById('metric').value = 'refine_fill'; document.getElementById('metric').onchange(); 1")
        shown = b.wait(f"window.dashboard.state.map && window.dashboard.state.map.sweep === '{ref_id}' && window.dashboard.state.map.metric === 'refine_fill'")
        check(shown is not None, "the page draws refine_fill")
        rect = b.eval("(() => { const r = document.getElementById('map').getBoundingClientRect(); return [r.left, r.top]; })()")
        cx, cy = b.eval(f"window.dashboard.cellCenter({k_interp % nx}, {k_interp // nx})")
        b.click(rect[0] + 1 + cx, rect[1] + 1 + cy)
        note = b.wait("window.dashboard.state.cell && !document.getElementById('cell-refine').hidden && document.getElementById('cell-refine').textContent", 30)
        check(note is not None and "interpolated" in note and "computed now" in note, f"the page marks the interpolated cell: {note!r}")
        b.eval("document.getElementById('cell-view').scrollIntoView(); window.scrollBy(0, -420); 1")
        time.sleep(0.3)
        b.screenshot(figure("refined"))
        check(not b.errors, "no console errors: " + "; ".join(b.errors))
        b.close()
    stop(p, signal.SIGINT)  # Ctrl-C ends the run's serving


def auth_checks(tmp):
    certs = os.path.join(tmp, "certs")
    subprocess.run(["bash", os.path.join(SOURCE, "tests", "make_test_certs.sh"), certs, "127.0.0.1"], check=True,
                   capture_output=True)
    tokens = {}
    with open(os.path.join(tmp, "tokens"), "w") as f:
        for role in ("viewer", "client", "worker"):
            out = run([BISTABLE, "token", "--role", role, "--name", role + "1"]).stdout
            tokens[role] = re.search(r"token: (\S+)", out).group(1)
            f.write(re.search(r"tokens-file line: (.*)", out).group(1) + "\n")
    coord, (grpc_port,) = start([COORD, "--listen", "127.0.0.1:0", "--data", os.path.join(tmp, "data-tls"), "--http", "127.0.0.1:0",
                                 "--tls-cert", os.path.join(certs, "server.pem"), "--tls-key", os.path.join(certs, "server.key"),
                                 "--tokens", os.path.join(tmp, "tokens"), "--log-level", "warn"], r"listening on 127\.0\.0\.1:(\d+)")
    line = coord.stdout.readline()
    check(line.startswith("dashboard on https://"), "the dashboard is served over TLS: " + line.strip())
    base = "https://127.0.0.1:" + re.search(r":(\d+)/", line).group(1)
    addr = "127.0.0.1:" + grpc_port
    ctx = ssl.create_default_context(cafile=os.path.join(certs, "ca.pem"))
    env = dict(os.environ, BISTABLE_TOKEN=tokens["client"])
    r = submit(addr, tmp, "owned", 4, 4, 50.0, 25.0, env=env, extra=("--tls-ca", os.path.join(certs, "ca.pem")))
    check(r.returncode == 0, "a client token submits over TLS")
    sweep = json.loads(r.stdout)["id"] if r.returncode == 0 else "0"
    for route in ("/api/sweeps", f"/api/sweep?id={sweep}", f"/api/map?id={sweep}&metric=frf_db", f"/api/cell?id={sweep}&point=0&ic=0",
                  "/metrics"):
        status, body, _ = get(base + route, ctx=ctx)
        check(status == 401 and sweep not in body and "frf" not in body, f"no token: {route} -> {status}, no data ({body[:60]!r})")
    status, _, _ = get(base + "/api/sweeps", {"Authorization": "Bearer " + "0" * 64}, ctx)
    check(status == 401, f"an unknown token -> {status}")
    status, _, _ = get(base + "/api/sweeps", {"Authorization": "Bearer " + tokens["worker"]}, ctx)
    check(status == 403, f"a worker token may not read the dashboard -> {status}")
    status, body, _ = get(base + "/", ctx=ctx)
    check(status == 200 and "bistable" in body and tokens["viewer"] not in body, "the page itself loads without a token")
    status, body, _ = get(base + "/api/sweeps", {"Authorization": "Bearer " + tokens["viewer"]}, ctx)
    check(status == 200 and sweep in body, "a viewer token reads the sweeps")
    status, body, headers = get(base + "/api/session", {"Authorization": "Bearer " + tokens["viewer"]}, ctx)
    cookie = headers.get("Set-Cookie", "")
    check(status == 200 and "HttpOnly" in cookie and "Secure" in cookie and "SameSite=Strict" in cookie and tokens["viewer"] not in body,
          "/api/session keeps the token in an HttpOnly, Secure cookie and never echoes it")
    status, body, _ = get(base + "/api/sweeps", {"Cookie": cookie.split(";")[0]}, ctx)
    check(status == 200 and sweep in body, "the cookie alone reads the sweeps")
    venv = dict(os.environ, BISTABLE_TOKEN=tokens["viewer"])
    tls = ("--tls-ca", os.path.join(certs, "ca.pem"))
    r = submit(addr, tmp, "by viewer", 3, 3, 50.0, 25.0, env=venv, extra=tls)
    check(r.returncode != 0 and "permission" in r.stderr.lower(), "a viewer token cannot submit over gRPC: " + r.stderr.strip()[:90])
    r = run([BISTABLE, "cancel", sweep, "--coordinator", addr, *tls], env=venv)
    check(r.returncode != 0 and "permission" in r.stderr.lower(), "a viewer token cannot cancel over gRPC: " + r.stderr.strip()[:90])
    r = run([BISTABLE, "sweeps", "--coordinator", addr, "--json", *tls], env=venv)
    check(r.returncode == 0 and sweep in r.stdout, "a viewer token lists sweeps over gRPC")


def main():
    tmp = tempfile.mkdtemp(prefix="dashboard-test-")
    t0 = time.time()
    try:
        browser_checks(tmp)
        serve_checks(tmp)
        auth_checks(tmp)
    finally:
        for p in reversed(procs):
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"{len(failures)} failures in {time.time() - t0:.1f} s")
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
