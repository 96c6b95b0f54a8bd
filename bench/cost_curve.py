#!/usr/bin/python3
"""The cost curve (issue 14): wall time and peak memory of `bistable run` on the paper's main job
(examples/paper_fig8_frf.toml) over grid size and over tau_end, the fitted log-log exponents, HDF5 publish
time and map file size per million points, and the coordinator's memory per queued job. Every run is
printed with its ratio to the reference kernel measured in the same script, alternating with the runs.
Called by bench/cost_curve.sh (which compiles the reference kernel); see docs/numerics.md#cost-curve."""
import argparse
import json
import math
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
import tomllib

SPEC = "examples/paper_fig8_frf.toml"


def log(msg):
    print(msg, file=sys.stderr, flush=True)


# ---------------------------------------------------------------- spec variants
def spec_variant(base_text, grid, t_end, t_keep):
    """The paper spec with both axes' counts set to `grid` and the window [t_keep, t_end]; checked by parsing."""
    text, n = re.subn(r"^((?:alpha|omega) = \{ linspace = \[[^,\]]+, [^,\]]+, )\d+(\] \})", rf"\g<1>{grid}\g<2>", base_text,
                      flags=re.M)
    if n != 2:
        sys.exit(f"error: {SPEC}: expected alpha and omega linspace axes, found {n}")
    text, n1 = re.subn(r"^t_end = .*$", f"t_end = {t_end!r}", text, flags=re.M)
    text, n2 = re.subn(r"^t_keep = .*$", f"t_keep = {t_keep!r}", text, flags=re.M)
    if n1 != 1 or n2 != 1:
        sys.exit(f"error: {SPEC}: expected one t_end and one t_keep line")
    s = tomllib.loads(text)
    assert s["axes"]["alpha"]["linspace"][2] == grid and s["axes"]["omega"]["linspace"][2] == grid
    assert s["integration"]["t_end"] == t_end and s["integration"]["t_keep"] == t_keep
    return text


# ---------------------------------------------------------------- reference kernel
def reference(ref_bin, threads, blocks):
    """T copies of the reference kernel at once (one per thread of the run it brackets): the T-core bound, M steps/s."""
    procs = [subprocess.Popen([ref_bin, str(blocks)], stdout=subprocess.PIPE, text=True) for _ in range(threads)]
    total = 0.0
    for p in procs:
        out, _ = p.communicate()
        m = re.search(r"([0-9.]+) Msteps/s", out)
        if p.returncode != 0 or not m:
            sys.exit(f"error: reference kernel failed: {out!r}")
        total += float(m.group(1))
    return total


# ---------------------------------------------------------------- one bistable run
def run_map(cli, spec_text, threads, work):
    d = tempfile.mkdtemp(prefix="run-", dir=work)
    try:
        spec = os.path.join(d, "spec.toml")
        with open(spec, "w") as f:
            f.write(spec_text)
        tfile = os.path.join(d, "time.txt")
        cmd = ["/usr/bin/time", "-f", "%e %M", "-o", tfile, cli, "run", spec, "--data", os.path.join(d, "data"),
               "--threads", str(threads), "--json", "--quiet", "--no-plots"]
        p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if p.returncode != 0:
            sys.exit(f"error: {' '.join(cmd)} exited {p.returncode}:\n{p.stderr}")
        j = json.loads(p.stdout)
        wall, maxrss_kb = open(tfile).read().split()[-2:]
        h5 = j["files"][0]
        return {"wall": float(wall), "rss_mb": int(maxrss_kb) / 1024, "seconds": j["seconds"], "timing": j["timing"],
                "points": j["points"], "computed": j["computed"], "h5_mb": os.path.getsize(h5) / 1e6}
    finally:
        shutil.rmtree(d, ignore_errors=True)


# ---------------------------------------------------------------- coordinator memory
def proc_status(pid):
    out = {}
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            k, _, v = line.partition(":")
            if k in ("VmRSS", "VmHWM"):
                out[k] = int(v.split()[0]) * 1024  # kB -> bytes
    return out


def coordinator_memory(build, cli, spec_text, work):
    d = tempfile.mkdtemp(prefix="coord-", dir=work)
    out_path, err_path = os.path.join(d, "coord.out"), os.path.join(d, "coord.err")
    spec = os.path.join(d, "spec.toml")
    with open(spec, "w") as f:
        f.write(spec_text)
    with open(out_path, "w") as o, open(err_path, "w") as e:
        coord = subprocess.Popen([os.path.join(build, "server", "bistable-coordinator"), "--listen", "127.0.0.1:0",
                                  "--data", os.path.join(d, "data"), "--log-format", "json"], stdout=o, stderr=e)
    try:
        port = None
        for _ in range(400):
            time.sleep(0.025)
            m = re.search(r"listening on \S+:(\d+)", open(out_path).read())
            if m:
                port = m.group(1)
                break
            if coord.poll() is not None:
                break
        if port is None:
            sys.exit(f"error: bistable-coordinator did not start:\n{open(err_path).read()}")
        addr = f"127.0.0.1:{port}"
        time.sleep(0.5)
        before = proc_status(coord.pid)
        t0 = time.monotonic()
        p = subprocess.run([cli, "submit", spec, "--coordinator", addr, "--json"], stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)
        submit_s = time.monotonic() - t0
        if p.returncode != 0:
            sys.exit(f"error: bistable submit exited {p.returncode}: {p.stderr}")
        sweep = json.loads(p.stdout)["id"]
        time.sleep(1.0)  # let the checkpoint thread and allocator settle
        queued = proc_status(coord.pid)
        planned = None
        for line in open(err_path):
            try:
                ev = json.loads(line)
            except json.JSONDecodeError:
                continue
            if ev.get("event") == "sweep.planned" and ev.get("sweep") == sweep:
                planned = ev
        if planned is None:
            sys.exit(f"error: no sweep.planned event in the coordinator's log:\n{open(err_path).read()}")
        subprocess.run([cli, "cancel", sweep, "--coordinator", addr], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        time.sleep(1.0)
        cancelled = proc_status(coord.pid)
        return {"items": int(planned["items"]), "jobs": int(planned["jobs"]), "plan_ms": float(planned["plan_ms"]),
                "submit_s": submit_s, "rss0": before["VmRSS"], "rss": queued["VmRSS"], "hwm": queued["VmHWM"],
                "rss_cancelled": cancelled["VmRSS"]}
    finally:
        coord.send_signal(signal.SIGTERM)
        try:
            coord.wait(timeout=10)
        except subprocess.TimeoutExpired:
            coord.kill()
            coord.wait()
        shutil.rmtree(d, ignore_errors=True)


# ---------------------------------------------------------------- fits
def loglog_fit(xs, ys):
    """Least squares of log y = a + k log x: returns (k, a)."""
    lx, ly = [math.log(x) for x in xs], [math.log(y) for y in ys]
    return linear_fit(lx, ly)


def linear_fit(xs, ys):
    n = len(xs)
    if n < 2:
        return float("nan"), float("nan")
    mx, my = sum(xs) / n, sum(ys) / n
    sxx = sum((x - mx) ** 2 for x in xs)
    if sxx == 0:
        return float("nan"), float("nan")
    k = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx
    return k, my - k * mx


def median_of_rounds(runs):
    """One row per configuration: the median of each figure over its rounds (peak memory: the largest)."""
    groups = {}
    for r in runs:
        groups.setdefault((r["series"], r["grid"], r["t_end"], r["threads"]), []).append(r)
    out = []
    for rs in groups.values():
        m = dict(rs[0])
        for k in ("wall", "seconds", "pps", "ref", "fraction", "h5_mb"):
            m[k] = statistics.median(r[k] for r in rs)
        m["timing"] = {k: statistics.median(r["timing"][k] for r in rs) for k in rs[0]["timing"]}
        m["rss_mb"] = max(r["rss_mb"] for r in rs)
        m["rounds"] = len(rs)
        out.append(m)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--ref-bin", required=True)
    ap.add_argument("--build", required=True)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--threads", default="1,2", help="comma-separated thread counts (default 1,2)")
    ap.add_argument("--tau-grid", type=int, default=61, help="grid (per axis) of the tau_end series (default 61)")
    ap.add_argument("--grids", help="comma-separated grids of the grid series (default 41,101,201,401,801)")
    ap.add_argument("--taus", help="comma-separated tau_end of the tau series (default 250,500,1000,2000,4000)")
    ap.add_argument("--coord-grids", help="grids of the coordinator memory test (default 201,401,801)")
    ap.add_argument("--rounds", type=int, default=1, help="measure every configuration N times, report medians")
    ap.add_argument("--ref-blocks", type=int, default=256, help="reference kernel blocks of 16 points per measurement")
    ap.add_argument("--table")
    ap.add_argument("--plot")
    ap.add_argument("--workdir", help="where maps are written (default: a temporary directory)")
    a = ap.parse_args()

    cli = os.path.join(a.build, "client", "bistable")
    for exe in (cli, os.path.join(a.build, "server", "bistable-coordinator")):
        if not os.access(exe, os.X_OK):
            sys.exit(f"error: {exe} missing: build it first (cmake --build {a.build})")
    ints = lambda s: [int(x) for x in s.split(",") if x]
    threads = ints(a.threads)
    # An explicit empty list ("--taus=") leaves that series out.
    grids = ints(a.grids) if a.grids is not None else ([41, 101] if a.quick else [41, 101, 201, 401, 801])
    taus = ([float(x) for x in a.taus.split(",") if x] if a.taus is not None else
            [250.0, 500.0] if a.quick else [250.0, 500.0, 1000.0, 2000.0, 4000.0])
    coord_grids = (ints(a.coord_grids) if a.coord_grids is not None else
                   [101, 201] if a.quick else [201, 401, 801])

    base_text = open(SPEC).read()
    base = tomllib.loads(base_text)
    dt = base["integration"]["dt"]
    t_end0, t_keep0 = base["integration"]["t_end"], base["integration"]["t_keep"]
    keep_frac = t_keep0 / t_end0  # the window keeps the spec's proportion: t_keep = t_end * 250/500

    configs = [("grid", g, t_end0, t_keep0) for g in grids]
    configs += [("tau", a.tau_grid, t, t * keep_frac) for t in taus]

    work = a.workdir or tempfile.mkdtemp(prefix="cost-curve-")
    os.makedirs(work, exist_ok=True)
    events = []  # ("ref", T, M steps/s) and ("run", T, result), in the order measured
    try:
        total = len(configs) * len(threads) * a.rounds
        k = 0
        for series, g, t_end, t_keep in [c for _ in range(a.rounds) for c in configs]:  # rounds span the session
            text = spec_variant(base_text, g, t_end, t_keep)
            for T in threads:
                k += 1
                r = reference(a.ref_bin, T, a.ref_blocks)
                events.append(("ref", T, r))
                log(f"[{k}/{total}] reference x{T}: {r:.1f} M steps/s; bistable run {g}x{g}, tau_end {t_end:g}, "
                    f"--threads {T} ...")
                res = run_map(cli, text, T, work)
                res.update(series=series, grid=g, t_end=t_end, t_keep=t_keep, threads=T,
                           steps=int(round(t_end / dt)))
                events.append(("run", T, res))
                log(f"    {res['wall']:.2f} s wall, {res['rss_mb']:.0f} MB peak")
        for T in threads:
            events.append(("ref", T, reference(a.ref_bin, T, a.ref_blocks)))

        log("coordinator memory per queued job ...")
        coord = []
        for g in coord_grids:
            c = coordinator_memory(a.build, cli, spec_variant(base_text, g, t_end0, t_keep0), work)
            c["grid"] = g
            coord.append(c)
    finally:
        if not a.workdir:
            shutil.rmtree(work, ignore_errors=True)

    # Each run's bound: the mean of the reference measured just before and just after it with as many copies as threads.
    runs = []
    for i, ev in enumerate(events):
        if ev[0] != "run":
            continue
        T, res = ev[1], ev[2]
        before = next(e[2] for e in reversed(events[:i]) if e[0] == "ref" and e[1] == T)
        after = next(e[2] for e in events[i + 1:] if e[0] == "ref" and e[1] == T)
        res["ref"] = (before + after) / 2
        res["pps"] = res["computed"] / res["seconds"]
        res["fraction"] = res["pps"] * res["steps"] / (res["ref"] * 1e6)
        runs.append(res)
    runs = median_of_rounds(runs)

    lines = []
    out = lines.append
    mode = "custom" if (a.grids is not None or a.taus is not None) else "quick" if a.quick else "full"
    rounds = f", median of {a.rounds} rounds" if a.rounds > 1 else ""
    out(f"### Cost curve ({mode}{rounds}): `{SPEC}` variants, dt {dt:g}, window [t_end x {keep_frac:g}, t_end]")
    out("")
    out("`run s` = plan + compute + publish (the run's JSON), `wall s` = the whole process (`/usr/bin/time`), "
        "`x bound` = points/s x steps per point / reference kernel M steps/s with as many copies as threads, "
        "measured just before and after the run.")
    out("")
    out("| threads | grid | points | tau_end | steps/point | wall s | run s | plan / compute / publish s | peak RSS MB "
        "| points/s | reference M steps/s | x bound | map MB |")
    out("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in runs:
        t = r["timing"]
        out(f"| {r['threads']} | {r['grid']}² | {r['points']:,} | {r['t_end']:g} | {r['steps']:,} | {r['wall']:.2f} "
            f"| {r['seconds']:.2f} | {t['plan']:.2f} / {t['compute']:.2f} / {t['publish']:.2f} | {r['rss_mb']:.0f} "
            f"| {r['pps']:,.0f} | {r['ref']:.0f} | {r['fraction']:.2f} | {r['h5_mb']:.2f} |")
    out("")
    out("Fitted exponents (log-log least squares; 1 = linear):")
    out("")
    out("| threads | wall s vs points | run s vs points | compute s vs points | wall s vs tau_end | run s vs tau_end "
        "| compute s vs tau_end | peak RSS: bytes per point (linear fit) |")
    out("|---|---|---|---|---|---|---|---|")
    fits = {}
    for T in threads:
        g = [r for r in runs if r["threads"] == T and r["series"] == "grid"]
        s = [r for r in runs if r["threads"] == T and r["series"] == "tau"]
        f = lambda rs, x, y: loglog_fit([x(r) for r in rs], [y(r) for r in rs])
        kp = [f(g, lambda r: r["points"], y) for y in (lambda r: r["wall"], lambda r: r["seconds"],
                                                        lambda r: r["timing"]["compute"])]
        kt = [f(s, lambda r: r["t_end"], y) for y in (lambda r: r["wall"], lambda r: r["seconds"],
                                                       lambda r: r["timing"]["compute"])]
        mem = linear_fit([r["points"] for r in g], [r["rss_mb"] * 1024 * 1024 for r in g])[0]
        fits[T] = (kp[0], kt[0])
        out(f"| {T} | {kp[0][0]:.3f} | {kp[1][0]:.3f} | {kp[2][0]:.3f} | {kt[0][0]:.3f} | {kt[1][0]:.3f} | {kt[2][0]:.3f} "
            f"| {mem:,.0f} |")
    out("")
    out("HDF5 publish (fold into the cache, write the map, index it) and map file size, grid series:")
    out("")
    out("| threads | points | publish s | publish s per M points | map MB | map MB per M points |")
    out("|---|---|---|---|---|---|")
    for r in runs:
        if r["series"] == "grid":
            mp = r["points"] / 1e6
            out(f"| {r['threads']} | {r['points']:,} | {r['timing']['publish']:.3f} | {r['timing']['publish'] / mp:.2f} "
                f"| {r['h5_mb']:.2f} | {r['h5_mb'] / mp:.1f} |")
    g_all = [r for r in runs if r["series"] == "grid"]
    pub_slope = linear_fit([r["points"] / 1e6 for r in g_all], [r["timing"]["publish"] for r in g_all])[0]
    mb_slope = linear_fit([r["points"] / 1e6 for r in g_all], [r["h5_mb"] for r in g_all])[0]
    out("")
    out(f"Linear fits over the grid series: publish {pub_slope:.2f} s per M points, map file {mb_slope:.1f} MB per "
        f"M points (dt {dt:g}, tau_end {t_end0:g}, the spec's {len(base['metrics']['store'])} stored metrics).")
    if coord:
        out("")
        out("Coordinator memory: a fresh `bistable-coordinator` per size, no workers, one sweep submitted "
            f"(tau_end {t_end0:g}); VmRSS from /proc before the submit, 1 s after it returned (jobs queued), and 1 s "
            "after `cancel` (which frees the plan):")
        out("")
        out("| grid | items | jobs queued | plan ms | RSS before MB | RSS queued MB | peak (VmHWM) MB | RSS after cancel MB "
            "| growth per queued job, bytes | growth per queued item, bytes | freed by cancel per item, bytes |")
        out("|---|---|---|---|---|---|---|---|---|---|---|")
        for c in coord:
            dr = c["rss"] - c["rss0"]
            out(f"| {c['grid']}² | {c['items']:,} | {c['jobs']:,} | {c['plan_ms']:.0f} | {c['rss0'] / 2**20:.1f} "
                f"| {c['rss'] / 2**20:.1f} | {c['hwm'] / 2**20:.1f} | {c['rss_cancelled'] / 2**20:.1f} "
                f"| {dr / c['jobs']:,.0f} | {dr / c['items']:,.1f} | {(c['rss'] - c['rss_cancelled']) / c['items']:,.1f} |")
        if len(coord) >= 2:
            growth = [c["rss"] - c["rss0"] for c in coord]
            ki = linear_fit([c["items"] for c in coord], growth)[0]
            out("")
            msg = f"Marginal (linear fit of the RSS growth across sizes): {ki:,.1f} bytes per queued item"
            jobs = [c["jobs"] for c in coord]
            if max(jobs) >= 2 * min(jobs):
                msg += f", {linear_fit(jobs, growth)[0]:,.0f} bytes per queued job"
            else:
                msg += (" (the job count barely changes across these sizes — a sweep has at least 64 jobs, sized to "
                        "about 2 s of work — so there is no per-job fit; a job holds its items)")
            out(msg + ".")
    text = "\n".join(lines) + "\n"
    print(text, end="")
    if a.table:
        with open(a.table, "w") as f:
            f.write(text)

    if a.plot:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.5))
        for T in threads:
            for ax, series, x in ((ax1, "grid", "points"), (ax2, "tau", "t_end")):
                rs = sorted((r for r in runs if r["threads"] == T and r["series"] == series), key=lambda r: r[x])
                xs, ys = [r[x] for r in rs], [r["wall"] for r in rs]
                k, c = fits[T][0] if series == "grid" else fits[T][1]
                line = ax.loglog(xs, ys, "o", label=f"--threads {T}")[0]
                if not math.isnan(k):
                    ax.loglog(xs, [math.exp(c) * v ** k for v in xs], "-", color=line.get_color(),
                              label=f"fit, exponent {k:.2f}")
        ax1.set_xlabel("grid points (α × Ω)")
        ax1.set_ylabel("wall time [s]")
        ax1.set_title(f"time vs points (τ_end {t_end0:g})")
        ax2.set_xlabel("τ_end (window [τ_end/2, τ_end])")
        ax2.set_ylabel("wall time [s]")
        ax2.set_title(f"time vs τ_end ({a.tau_grid}² grid)")
        for ax in (ax1, ax2):
            ax.grid(True, which="both", alpha=0.3)
            ax.legend()
        fig.suptitle(f"bistable run, {SPEC} ({mode})")
        fig.tight_layout()
        fig.savefig(a.plot, dpi=110)
        log(f"plot: {a.plot}")


if __name__ == "__main__":
    main()
