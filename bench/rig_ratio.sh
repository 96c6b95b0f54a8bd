#!/usr/bin/env bash
# The rig's map paths against a converged reference and against each other, in one run (issue 41):
#   bench/rig_ratio.sh [BUILD_DIR] [--rounds R] [--detail] [--n N] [--paths "dopri5 default rk4"]
#                      [--ref-data DIR] [--grids "example intrawell chaotic"]
# Grids (N × N points, default 10 × 10, of examples/dimensional_table2.toml's rig: Table 2 with Stribeck
# friction on both bodies, t 0–20 s, window 10–20 s, dt 1 ms):
#   example    A0 1–20 mm    × f0 1–12 Hz    (the example's range)
#   intrawell  A0 0.2–3 mm   × f0 1–12 Hz    (low amplitude: intrawell, sticking and creeping)
#   chaotic    A0 9–16 mm    × f0 1.5–4.5 Hz (the band where the rig's chaotic points lie)
# Reference: Dormand–Prince at rtol 1e-10, atol 1e-13, computed once and kept in --ref-data (default
# /tmp/bistable-rig-reference; 20–40 s per grid on this machine). Paths: dopri5 = Dormand–Prince, rtol 1e-6,
# atol 1e-9, one point at a time (the rig's default before numerics 1.5.0: the baseline of every ratio);
# default = the spec as the example gives it (since 1.5.0 ROS34PW2 in lanes, rtol 5e-6); rosenbrock = the
# same, said explicitly; rk4 = fixed-step RK4 in lanes; a path may carry tolerances: rosenbrock@RTOL[@ATOL].
# Each path runs `bistable run SPEC --threads 1 --no-plots` on a fresh data directory (nothing cached), R
# rounds (default 3) with the paths alternating; times are medians: CPU (user + sys of the process: what
# the run costs, robust against the machine's other load) and wall (the run's plan + compute + publish).
# Prints, per grid and path: times, the ratio to the default (dopri5) path, motion equal %, period
# equal %, FRF within 0.05 dB %, LLE within 0.05 /s % (and 0.1 /s), and LLE within 0.05 /s over the
# points the reference calls regular (not chaotic: a chaotic point's finite-time LLE differs between
# any two integrations), and FRF within 0.05 dB over the same points (a chaotic window's maximum differs too). --detail lists every point that differs from the reference, with both values.
# The first line is `bistable info` (CPU, vector unit, lane width: dynamics/host_lanes.h).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=build
N=10
PATHS="dopri5 default rk4"
REFDATA=/tmp/bistable-rig-reference
GRIDS="example intrawell chaotic"
DETAIL=0
ROUNDS=3
while [ $# -gt 0 ]; do
  case "$1" in
    --n) N=$2; shift 2 ;;
    --paths) PATHS=$2; shift 2 ;;
    --ref-data) REFDATA=$2; shift 2 ;;
    --grids) GRIDS=$2; shift 2 ;;
    --detail) DETAIL=1; shift ;;
    --rounds) ROUNDS=$2; shift 2 ;;
    -*) echo "unknown option $1" >&2; exit 2 ;;
    *) BUILD=$1; shift ;;
  esac
done
BIN=$BUILD/client/bistable
[ -x "$BIN" ] || { echo "build $BIN first (cmake --build $BUILD --target bistable)" >&2; exit 2; }
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
"$BIN" info
echo "commit $(git rev-parse --short HEAD 2>/dev/null || echo unknown)$(git diff --quiet 2>/dev/null || echo ' (modified)'), $(date -u +%Y-%m-%dT%H:%MZ), one thread, N = $N per axis"
/usr/bin/python3 - "$BIN" "$TMP" "$REFDATA" "$N" "$PATHS" "$GRIDS" "$DETAIL" "$ROUNDS" <<'PY'
import csv, io, json, math, os, re, resource, statistics, subprocess, sys
binary, tmp, refdata, n, paths, grids = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), sys.argv[5].split(), sys.argv[6].split()
detail = sys.argv[7] == "1"
rounds = int(sys.argv[8])
example = open("examples/dimensional_table2.toml").read()
ranges = {"example": ((1.0, 20.0), (1.0, 12.0)), "intrawell": ((0.2, 3.0), (1.0, 12.0)), "chaotic": ((9.0, 16.0), (1.5, 4.5))}
integration = {
    "reference": 'rtol = 1e-10\natol = 1e-13\nintegrator = "dopri5"',
    "default": "",  # the spec's own (since numerics 1.5.0 ROS34PW2 in lanes at its rtol 5e-6)
    "dopri5": 'rtol = 1e-6\nintegrator = "dopri5"',
    "rosenbrock": 'integrator = "rosenbrock"',
    "rk4": 'integrator = "rk4"',
}
metrics = ["motion", "period", "frf_db", "lle"]

def spec(grid, path):
    (a0, a1), (f0, f1) = ranges[grid]
    s = re.sub(r"a0_mm = .*", "a0_mm = { linspace = [%g, %g, %d] }" % (a0, a1, n), example)
    s = re.sub(r"f0_hz = .*", "f0_hz = { linspace = [%g, %g, %d] }" % (f0, f1, n), s)
    name, *tols = path.split("@")  # e.g. rosenbrock@1e-4@1e-7: that path at rtol 1e-4, atol 1e-7
    extra = integration[name]
    if tols:
        extra += "\nrtol = %s" % tols[0] + ("\natol = %s" % tols[1] if len(tols) > 1 else "")
    if extra:  # the path's lines open the [integration] table (an rtol line of the example's would repeat a key)
        s = re.sub(r"^rtol = .*\n", "", s, flags=re.M)
        assert "[integration]\n" in s, "the example has no [integration] table"
        s = s.replace("[integration]\n", "[integration]\n" + extra + "\n", 1)
    f = os.path.join(tmp, "%s_%s.toml" % (grid, path))
    open(f, "w").write(s)
    return f

def run(grid, path, data):
    """One `bistable run` into data: its JSON, its CPU seconds (user + sys of the process), the four maps."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run([binary, "run", spec(grid, path), "--threads", "1", "--no-plots", "--quiet", "--json", "--data", data],
                         check=True, capture_output=True, text=True).stdout
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    d = json.loads(out)
    vals = {}
    for m in metrics:
        c = subprocess.run([binary, "map", d["id"], "--metric", m, "--format", "csv", "--data", data],
                           check=True, capture_output=True, text=True).stdout
        vals[m] = {(r["a0_mm"], r["f0_hz"]): float(r[m]) for r in csv.DictReader(io.StringIO(c))}
    return d, cpu, vals

def close(a, b, tol):
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    return abs(a - b) <= tol

print()
print("Times: median of %d rounds (paths alternating within a round, fresh data directory each run); "
      "CPU = user + sys seconds of the `bistable run` process, wall = the run's own plan + compute + publish. "
      "x = dopri5 rtol 1e-6 (the default before numerics 1.5.0) time / this path's, by CPU (by wall)." % rounds)
print()
print("| grid | path | CPU s | wall s | x faster (CPU) | x faster (wall) | motion equal | period equal | FRF within 0.05 dB | LLE within 0.05 /s | LLE within 0.1 /s | LLE within 0.05 /s, non-chaotic ref | FRF within 0.05 dB, non-chaotic ref |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
sys.stdout.flush()
for grid in grids:
    _, _, ref = run(grid, "reference", refdata)
    times = {p: ([], []) for p in paths}
    vals = {}
    for r in range(rounds):
        for path in paths:
            data = os.path.join(tmp, "data_%s_%s_%d" % (grid, path, r))
            d, cpu, v = run(grid, path, data)
            assert d["computed"] == len(ref["motion"]) and d["cached"] == 0, d
            times[path][0].append(cpu)
            times[path][1].append(d["seconds"])
            vals[path] = v
            subprocess.run(["rm", "-rf", data], check=True)
    base = None
    for path in paths:
        if path.split("@")[0] == "dopri5":
            base = (statistics.median(times[path][0]), statistics.median(times[path][1]))
            break
    for path in paths:
        v = vals[path]
        cpu, wall = statistics.median(times[path][0]), statistics.median(times[path][1])
        keys = list(ref["motion"])
        pct = lambda ok: 100.0 * sum(ok) / len(ok)
        mo = pct([v["motion"][k] == ref["motion"][k] for k in keys])
        pe = pct([v["period"][k] == ref["period"][k] for k in keys])
        fr = pct([close(v["frf_db"][k], ref["frf_db"][k], 0.05) for k in keys])
        l5 = pct([close(v["lle"][k], ref["lle"][k], 0.05) for k in keys])
        l10 = pct([close(v["lle"][k], ref["lle"][k], 0.1) for k in keys])
        regular = [k for k in keys if ref["motion"][k] != 2]
        lr = pct([close(v["lle"][k], ref["lle"][k], 0.05) for k in regular]) if regular else float("nan")
        fr_reg = pct([close(v["frf_db"][k], ref["frf_db"][k], 0.05) for k in regular]) if regular else float("nan")
        ratio = ("%.1f" % (base[0] / cpu), "%.1f" % (base[1] / wall)) if base else ("-", "-")
        print("| %s | %s | %.2f | %.2f | %s | %s | %.0f %% | %.0f %% | %.0f %% | %.0f %% | %.0f %% | %.0f %% of %d | %.0f %% of %d |" %
              (grid, path, cpu, wall, ratio[0], ratio[1], mo, pe, fr, l5, l10, lr, len(regular), fr_reg, len(regular)))
        if detail:  # the points that differ from the reference, with both values
            for key in keys:
                bad = [m for m in metrics if not (v[m][key] == ref[m][key] if m in ("motion", "period") else
                                                   close(v[m][key], ref[m][key], 0.05))]
                if bad:
                    print("    A0 %s f0 %s: " % key + ", ".join("%s %.4g (ref %.4g)" % (m, v[m][key], ref[m][key]) for m in metrics))
    sys.stdout.flush()
PY
