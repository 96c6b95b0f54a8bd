#!/usr/bin/env bash
# Which of the harvester's wells is deeper, window by window: the declared Duffing model with the piezo coupling and
# a quadratic stiffness (main.linear, stiffness_y3, viscous, piezo, stiffness_y2; nothing added: --max-added 0),
# fitted under the shooting objective (0.46 s segments, absolute frame, both outputs, --decimate 4) to each disjoint
# 8 s window (4096 samples after decimation) of the symmetric and the asymmetric interwell records.
#
# Per window: the shooting error, the same fit's error without stiffness_y2, k_lin, k3, k2 ± σ, the asymmetry ε = k2 / (k3 d) with d = sqrt(−k_lin / k3) and
# the depth ratio left/right of the fitted potential V = k_lin y²/2 + k2 y³/3 + k3 y⁴/4 (> 1: the left well is
# deeper). Per record: the windows with ε > 0, the median and the spread of ε. Then the sym intrawell pair's local
# well stiffnesses by equation error (an independent, non-chaotic estimate of the sym wells' asymmetry). σ is the fit's Gauss–Newton
# uncertainty; the spread over windows is the honest one for chaotic records (docs/identification.md,
# "Which well is deeper").
#   bench/harvester_wells.sh BISTABLE [DATA] [WINDOWS_SYM] [WINDOWS_ASYM] [SHIFT]
# DATA: the folder holding bistable-harvester/ (default ../shared/data/measured); WINDOWS_*: how many windows of
# each record (default all: 10 and 5); SHIFT: start every window this many samples later (default 0; 1 shows how
# the fit's basin depends on the window's first sample). About 60 s per window (two fits) on 2 cores; run it alone.
# IDENTIFY_FLAGS (environment): more `bistable identify` flags for every fit, e.g. "--lm-iterations 400".
# JOINT=1 (environment): one fit per record over all its chosen windows at once (each window a record of the fit:
# segments from all of them, one parameter set), printed as window 0; about 4 (asym) and 7 (sym) minutes per fit
# with "--lm-iterations 400".
# Needs /usr/bin/python3.
set -euo pipefail
BIN=${1:?usage: bench/harvester_wells.sh BISTABLE [DATA] [WINDOWS_SYM] [WINDOWS_ASYM] [SHIFT]}
DATA=${2:-../shared/data/measured}
NSYM=${3:-10}
NASYM=${4:-5}
SHIFT=${5:-0}
[ -x "$BIN" ] || { echo "error: '$BIN' is not an executable bistable binary" >&2; exit 2; }
"$BIN" info  # the CPU, the ISA and the lane width of the build measured
HV="$DATA/bistable-harvester"
[ -d "$HV" ] || { echo "error: '$HV' is not a folder (give DATA, the folder holding bistable-harvester/)" >&2; exit 2; }
for n in "$NSYM" "$NASYM" "$SHIFT"; do
  [[ "$n" =~ ^[0-9]+$ ]] || { echo "error: window counts and SHIFT must be non-negative integers, got '$n'" >&2; exit 2; }
done
[ "$NSYM" -le 10 ] && [ "$NASYM" -le 5 ] || { echo "error: the records hold 10 (sym) and 5 (asym) windows of 8 s" >&2; exit 2; }
EXTRA=${IDENTIFY_FLAGS:-}
[[ "$EXTRA" =~ ^[-a-z0-9.=_\ ]*$ ]] || { echo "error: IDENTIFY_FLAGS may hold flags and numbers only, got '$EXTRA'" >&2; exit 2; }
PY=/usr/bin/python3
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
IO=(--input-kind base_acceleration --input-scale 9.81 --output-kind velocity --output-scale 0.1
    --columns input=base_acc_g,output=laser_V,output2=piezo_V --known m_main=1)
TERMS=main.linear,main.stiffness_y3,main.viscous,main.piezo,main.stiffness_y2
W=4096
JOINT=${JOINT:-0}
[[ "$JOINT" =~ ^[01]$ ]] || { echo "error: JOINT must be 0 or 1, got '$JOINT'" >&2; exit 2; }
fit() {  # fit OUT_STEM IDENTIFY_ARGS...: with stiffness_y2, and again without it (both fitted afresh: the loop's declared fit)
  local out=$1; shift
  # shellcheck disable=SC2086 # EXTRA is split into flags on purpose
  "$BIN" identify "$@" "${IO[@]}" --max-added 0 --objective shooting --horizon 0.46 --decimate 4 --output-frame absolute \
      --json $EXTRA --terms "$TERMS" > "$out.json" 2> "$out.err" || { echo "$out failed:" >&2; cat "$out.err" >&2; }
  # shellcheck disable=SC2086
  "$BIN" identify "$@" "${IO[@]}" --max-added 0 --objective shooting --horizon 0.46 --decimate 4 --output-frame absolute \
      --json $EXTRA --terms "${TERMS%,main.stiffness_y2}" > "$out-sym.json" 2> "$out-sym.err" ||
    { echo "$out without y2 failed:" >&2; cat "$out-sym.err" >&2; }
}
for rec in sym asym; do
  n=$NSYM; [ "$rec" = asym ] && n=$NASYM
  csv="$HV/bistable_${rec}_interwell_6p5Hz.csv"
  if [ "$JOINT" = 1 ]; then
    # All windows as records of one fit (each its own file: --range would apply to all): segments from every window.
    files=()
    for ((k = 0; k < n; ++k)); do
      awk -v a=$(((k * W + SHIFT) * 4)) -v b=$((((k + 1) * W + SHIFT) * 4)) 'NR == 1 || (NR - 2 >= a && NR - 2 < b)' \
        "$csv" > "$TMP/win-$rec-$k.csv"
      files+=(--data "$TMP/win-$rec-$k.csv")
    done
    [ "$n" -gt 0 ] && fit "$TMP/$rec-0" "${files[@]}"
  else
    for ((k = 0; k < n; ++k)); do
      fit "$TMP/$rec-$k" --data "$csv" --range "$((k * W + SHIFT)):$(((k + 1) * W + SHIFT))"
    done
  fi
done
if [ "$JOINT" = 1 ]; then NSYM=$((NSYM > 0)); NASYM=$((NASYM > 0)); fi
$PY - "$TMP" "$NSYM" "$NASYM" "$HV" <<'PYEOF'
import json, math, os, sys
import numpy as np
tmp, counts, hv = sys.argv[1], {"sym": int(sys.argv[2]), "asym": int(sys.argv[3])}, sys.argv[4]

def depth_ratio(klin, k2, k3):
    # wells of V = klin y^2/2 + k2 y^3/3 + k3 y^4/4: roots of k3 y^2 + k2 y + klin = 0; depth = -V(well)
    disc = k2 * k2 - 4 * k3 * klin
    if k3 <= 0 or klin >= 0 or disc <= 0:
        return float("nan")
    V = lambda y: klin * y * y / 2 + k2 * y ** 3 / 3 + k3 * y ** 4 / 4
    left, right = (-k2 - math.sqrt(disc)) / (2 * k3), (-k2 + math.sqrt(disc)) / (2 * k3)
    return V(left) / V(right)

print("%-5s %3s %8s %9s %8s %10s %16s %15s %7s" % ("rec", "win", "shoot_%", "no_y2_%", "k_lin", "k3", "k2 +- sigma", "eps +- sigma", "L/R"))
for rec in ("sym", "asym"):
    eps_all, gains = [], []
    for k in range(counts[rec]):
        path = os.path.join(tmp, "%s-%d.json" % (rec, k))
        try:
            j = json.load(open(path))
        except (OSError, ValueError):
            print("%-5s %3d  (no result)" % (rec, k))
            continue
        p, u = j["params"], j["uncertainty"]
        try:
            without = json.load(open(os.path.join(tmp, "%s-%d-sym.json" % (rec, k))))["shooting_error_after"]
        except (OSError, ValueError, KeyError):
            without = float("nan")
        gains.append(without - j["shooting_error_after"])
        klin, k3, k2 = p["main.linear.k_lin"], p["main.stiffness_y3.k3"], p["main.stiffness_y2.k2"]
        if klin < 0 and k3 > 0:
            s = k3 * math.sqrt(-klin / k3)
            eps, es = k2 / s, u["main.stiffness_y2.k2"] / s
            eps_all.append(eps)
        else:
            eps = es = float("nan")
        print("%-5s %3d %8.1f %9.1f %8.0f %10.3g %8.0f +- %5.0f %6.3f +- %5.3f %7.2f" % (
            rec, k, j["shooting_error_after"], without, klin, k3, k2, u["main.stiffness_y2.k2"], eps, es, depth_ratio(klin, k2, k3)))
    if eps_all:
        e = np.array(eps_all)
        med = float(np.median(e))
        print("%-5s  eps > 0 in %d of %d windows; median %.3f, mean %.3f, sd %.3f; depth ratio L/R at the median %.2f" % (
            rec, int((e > 0).sum()), len(e), med, e.mean(), e.std(ddof=1) if len(e) > 1 else float("nan"),
            depth_ratio(-1.0, med, 1.0)))
        g = np.array(gains)
        print("%-5s  the shooting error without y2 minus with it: median %.1f points, lower with y2 in %d of %d windows" % (
            rec, float(np.nanmedian(g)), int((g > 0).sum()), len(g)))

# An independent check of the sym configuration from its intrawell pair (same drive, one record in each well, small
# orbits that are not chaotic): an equation-error regression of each well's local force, in the absolute frame the
# loops chose (relative velocity y' = laser - integral of the base acceleration; derivatives and integrals in the
# 1-40 Hz band by FFT):  y'' + c y' + k y + q y^2 + b = -a_base,  in 8 blocks of each record (mean, sd over blocks).
# k is the well's local stiffness per unit mass (the piezo's stiffening included), q's sign the side of the barrier:
# a quartic's well at +d has q = 3 k3 d > 0. For V = k_lin y^2/2 + k2 y^3/3 + k3 y^4/4 the curvature ratio of the
# wells fixes eps; the depth ratio follows. The amplitude ratio at 6.5 Hz is printed too (it folds in the damping).
def local_force(path, blocks=8):
    d = np.loadtxt(path, delimiter=",", skiprows=1)
    t, acc, vel = d[:, 0], d[:, 1] * 9.81, d[:, 3] / 10
    n = len(t)
    f = np.fft.rfftfreq(n, float(np.median(np.diff(t))))
    band = (f >= 1.0) & (f <= 40.0)
    def op(x, p):  # band-limited derivative (p = 1), integral (p = -1) or filter (p = 0)
        X = np.fft.rfft(x)
        Y = np.zeros_like(X)
        Y[band] = X[band] * (2j * np.pi * f[band]) ** p
        return np.fft.irfft(Y, n)
    yd = op(vel, 0) - op(acc, -1)
    y, ydd, a = op(yd, -1), op(yd, 1), op(acc, 0)
    rows = []
    for k in range(blocks):
        s = slice(n // 20 + k * (n * 9 // 10) // blocks, n // 20 + (k + 1) * (n * 9 // 10) // blocks)
        M = np.column_stack([yd, y, y * y, np.ones(n)])[s]
        rows.append(np.linalg.lstsq(M, (-a - ydd)[s], rcond=None)[0])
    e = np.exp(-2j * np.pi * 6.5 * (t - t[0]))
    # The well's own ringing: the velocity spectrum's peak between 7 and 11 Hz (above the drive), whole record.
    V = np.abs(np.fft.rfft((vel - vel.mean()) * np.hanning(n)))
    ring = (f > 7.0) & (f < 11.0)
    return np.array(rows), abs(np.mean(vel * e)) / abs(np.mean(acc * e)), float(f[ring][np.argmax(V[ring])])

try:
    (L, gL, fL), (R, gR, fR) = (local_force(os.path.join(hv, "bistable_sym_intrawell_%s_6p5Hz.csv" % w)) for w in ("left", "right"))
except OSError as e:
    print("intrawell check skipped: %s" % e)
    L = None
if L is not None:
    for name, r in (("left", L), ("right", R)):
        print("sym intrawell %-5s: local k %.1f +- %.1f s^-2, q %.4g +- %.2g m^-1 s^-2, c %.3f +- %.3f s^-1 (8 blocks)" % (
            name, r[:, 1].mean(), r[:, 1].std(ddof=1), r[:, 2].mean(), r[:, 2].std(ddof=1), r[:, 0].mean(), r[:, 0].std(ddof=1)))
    ratio = L[:, 1].mean() / R[:, 1].mean()
    sd = ratio * math.hypot(L[:, 1].std(ddof=1) / L[:, 1].mean(), R[:, 1].std(ddof=1) / R[:, 1].mean()) / math.sqrt(len(L))

    def curvature_ratio(eps):  # f'(left well) / f'(right well) of f(u) = -u + eps u^2 + u^3
        u = np.sort(np.roots([1, eps, -1]).real)
        c = -1 + 2 * eps * u + 3 * u * u
        return c[0] / c[1]

    grid = np.linspace(-0.5, 0.5, 20001)
    best = grid[np.argmin([abs(curvature_ratio(e) - ratio) for e in grid])]
    print("sym intrawell: q < 0 in the left record and > 0 in the right: the left file's well is at negative y (%s);" % (
        "yes" if L[:, 2].mean() < 0 < R[:, 2].mean() else "NO"))
    print("               local stiffness left / right %.4f +- %.4f -> eps %.3f, depth ratio L/R %.2f of the quartic;" % (
        ratio, sd, best, depth_ratio(-1.0, best, 1.0)))
    print("               velocity / base acceleration at 6.5 Hz, right over left %.3f (damping c and the drive differ too)" % (gR / gL))
    print("               ringing peak (7-11 Hz) left %.2f Hz, right %.2f Hz: squared ratio %.3f" % (fL, fR, (fL / fR) ** 2))

# Would the whole record's statistics show the depth? Simulate the symmetric-model Duffing of the asym shooting fit
# (k_lin -1161, k3 3.96e6 per unit mass, c0 1.79; docs/identification.md) at the measured asym base acceleration
# (RK4 at the sample rate, input averaged at the half step), with eps 0 ... 0.3, and print the share of time at y > 0
# and the section's mirror test: (y, v) at phase phi against -(y, v) at phi + pi, an energy distance, beside the
# half-vs-half floor of the same section (mean over 8 phases; y integrated from v above 0.5 Hz, as for the data).
def integrate(v, fs, fc=0.5):
    n = len(v)
    V, f = np.fft.rfft(v - v.mean()), np.fft.rfftfreq(n, 1 / fs)
    Y = np.zeros_like(V)
    Y[f > fc] = V[f > fc] / (2j * np.pi * f[f > fc])
    return np.fft.irfft(Y, n)

def energy_distance(A, B):
    md = lambda X, Y: np.sqrt(((X[:, None, :] - Y[None, :, :]) ** 2).sum(-1)).mean()
    return 2 * md(A, B) - md(A, A) - md(B, B)

def mirror_test(v, fs):
    y, P = integrate(v, fs), fs / 6.5
    N = int(len(v) / P) - 1
    test, floor = [], []
    for ph in np.arange(8) / 16:
        i0, i1 = (np.arange(N) * P + ph * P).astype(int), (np.arange(N) * P + (ph + 0.5) * P).astype(int)
        A, B = np.c_[y[i0], v[i0]], -np.c_[y[i1], v[i1]]
        s = A.std(0)
        A, B = A / s, B / s
        test.append(energy_distance(A, B))
        floor.append(energy_distance(A[: N // 2], A[N // 2 :]))
    return np.mean(test), np.mean(floor)

for rec in ("sym", "asym"):
    d = np.loadtxt(os.path.join(hv, "bistable_%s_interwell_6p5Hz.csv" % rec), delimiter=",", skiprows=1)
    m, fl = mirror_test(d[:, 3] / 10, 1 / (d[1, 0] - d[0, 0]))
    print("%-4s measured: mirror test %.4f, half-vs-half floor %.4f" % (rec, m, fl))
fs, acc = 1 / (d[1, 0] - d[0, 0]), d[:, 1] * 9.81  # d: the asym record
k1, k3, c = 1161.0, 3.96e6, 1.79
dw = math.sqrt(k1 / k3)
eps = np.array([0, 0.05, 0.1, 0.2, 0.3])
K2 = eps * k3 * dw
rhs = lambda y, v, a: (v, -c * v + k1 * y - K2 * y * y - k3 * y ** 3 - a)
y, v, h = np.full(len(eps), -dw), np.zeros(len(eps)), 1 / fs
Y, Vs = np.zeros((len(acc), len(eps))), np.zeros((len(acc), len(eps)))
for i in range(len(acc) - 1):
    am = (acc[i] + acc[i + 1]) / 2
    a1 = rhs(y, v, acc[i])
    a2 = rhs(y + h / 2 * a1[0], v + h / 2 * a1[1], am)
    a3 = rhs(y + h / 2 * a2[0], v + h / 2 * a2[1], am)
    a4 = rhs(y + h * a3[0], v + h * a3[1], acc[i + 1])
    y, v = y + h / 6 * (a1[0] + 2 * a2[0] + 2 * a3[0] + a4[0]), v + h / 6 * (a1[1] + 2 * a2[1] + 2 * a3[1] + a4[1])
    Y[i + 1], Vs[i + 1] = y, v
for j, e in enumerate(eps):
    m, fl = mirror_test(Vs[:, j], fs)
    print("asym input, Duffing with eps %.2f (depth ratio L/R %.2f): time at y > 0 %.2f, mirror test %.4f, floor %.4f" % (
        e, depth_ratio(-1.0, e, 1.0), (Y[:, j] > 0).mean(), m, fl))
PYEOF
