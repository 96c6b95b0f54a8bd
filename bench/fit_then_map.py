#!/usr/bin/env python3
"""Fit, then map, against the truth (issue 42's synthetic check), on as many generated records as asked.

For each record (an amplitude and a seed of the snap-through family, `identify --make-synthetic --synthetic
bistable`): fit it with the truth's own terms (`identify --report`), map the fitted model and the truth over the
same drive grid (`run`, model = "terms"), map the fitted model again with its parameters drawn from the fit's
covariance ([robustness] covariance = true), and compare the motion labels point by point. A point where fit and
truth disagree is mapped once more with --resample draws (one point, many samples), so that small probabilities
are resolved: the check asks that the truth's regime have a probability under the fit's uncertainty that is
away from 0 (at least two standard errors above it) — the fit's σ covers the disagreement — and prints it.

  /usr/bin/python3 bench/fit_then_map.py BISTABLE OUT [--records 12:1,10:2,...] [--samples 32]
      [--resample 1024] [--grid 19] [--threads 0] [--bootstrap N]

Needs h5py (Debian's python3-h5py). Prints a markdown table (one row per record) and writes summary.json in OUT.
"""
import argparse
import json
import os
import subprocess
import sys

import h5py
import numpy as np

REGIMES = {0: "intrawell", 1: "interwell", 2: "chaotic", 3: "quasi-periodic", 4: "unresolved", -1: "undefined"}


def run(cmd, **kw):
    r = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if r.returncode != 0:
        sys.exit(f"failed ({r.returncode}): {' '.join(cmd)}\n{r.stderr[-2000:]}")
    return r.stdout


def spec(name, report, a0, f0, samples=0, seed=1):
    axes = (f"a0_mm = {{ linspace = [{a0[0]}, {a0[1]}, {a0[2]}] }}\nf0_hz = {{ linspace = [{f0[0]}, {f0[1]}, {f0[2]}] }}"
            if isinstance(a0, tuple) else f"a0_mm = [{a0!r}]\nf0_hz = [{f0!r}]")
    text = (f'name = "{name}"\nmodel = "terms"\n\n[terms]\nreport = "{report}"\n\n[axes]\n{axes}\n\n'
            '[integration]\nt_end = 20.0\nt_keep = 10.0\n\n[metrics]\nstore = ["motion", "lle"]\n')
    if samples:
        text += f"\n[robustness]\nsamples = {samples}\ncovariance = true\nseed = {seed}\n"
    return text


def map_of(bistable, out, name, text, threads):
    path = os.path.join(out, name + ".toml")
    with open(path, "w") as f:
        f.write(text)
    res = json.loads(run([bistable, "run", path, "--data", os.path.join(out, "store"), "--json", "--quiet",
                          "--no-plots", "--threads", str(threads)], cwd=out))
    return h5py.File(res["files"][0], "r")


def one_record(args, amp, seed):
    out = os.path.abspath(os.path.join(args.out, f"a{amp:g}_s{seed}"))
    os.makedirs(out, exist_ok=True)
    run([args.bistable, "identify", "--make-synthetic", os.path.join(out, "syn"), "--synthetic", "bistable",
         "--synthetic-amplitude", str(amp), "--synthetic-seed", str(seed)])
    truth = json.load(open(os.path.join(out, "syn", "truth.json")))
    csv = os.path.join(out, "syn", truth["synthetic"]["records"][0]["file"])
    fit = json.loads(run([args.bistable, "identify", "--data", csv, "--terms", ",".join(truth["final_terms"]),
                          "--known", f"m_main={truth['settings']['m_main']}", "--report", os.path.join(out, "fit"),
                          "--json"] + (["--bootstrap", str(args.bootstrap)] if args.bootstrap else [])))
    g = args.grid
    a0, f0 = (2.0, 20.0, g), (1.0, 10.0, g)
    mt = map_of(args.bistable, out, "truth", spec("truth", "syn/truth.json", a0, f0), args.threads)
    mf = map_of(args.bistable, out, "fit", spec("fit", "fit/report.json", a0, f0), args.threads)
    mr = map_of(args.bistable, out, "fit_cov", spec("fit under covariance", "fit/report.json", a0, f0, args.samples),
                args.threads)
    lt, lf = mt["motion"][()], mf["motion"][()]
    agree = int((lt == lf).sum())
    rows = []
    for i, j in zip(*np.nonzero(lt != lf)):
        a, f = float(mt["a0_mm"][i]), float(mt["f0_hz"][j])
        frac = lambda m, reg: float(m[f"frac_{reg}"][()].reshape(m[f"frac_{reg}"].shape)[i, j]) if f"frac_{reg}" in m else None
        big = map_of(args.bistable, out, f"point_{i}_{j}", spec(f"fit at {a:g} mm {f:g} Hz", "fit/report.json", a, f,
                                                                 args.resample, seed=7), args.threads)
        labels = big["motion"][()].reshape(-1)
        n = labels.size
        p_truth = float((labels == lt[i, j]).mean())
        p_fit = float((labels == lf[i, j]).mean())
        se = lambda p: (p * (1 - p) / n) ** 0.5
        rows.append({"a0_mm": a, "f0_hz": f, "truth": REGIMES[int(lt[i, j])], "fit": REGIMES[int(lf[i, j])],
                     f"p_truth_regime_{args.samples}": frac(mr, REGIMES[int(lt[i, j])]),
                     "p_truth_regime": p_truth, "p_truth_se": se(p_truth), "p_fit_regime": p_fit,
                     "samples": n, "covered": p_truth - 2 * se(p_truth) > 0 and p_truth > 0})
    p = fit["params"]
    s = fit.get("uncertainty", {})
    z = {k: (p[k] - v) / s[k] for k, v in truth["params"].items() if s.get(k)}
    return {"record": f"{amp:g} mm, seed {seed}", "points": int(lt.size), "agree": agree,
            "sigma": "bootstrap" if (fit.get("bootstrap") or {}).get("fitted") else "gauss-newton",
            "disagree": rows, "z": z, "error_after_percent": fit.get("error_after")}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("bistable")
    ap.add_argument("out")
    ap.add_argument("--records", default="12:1", help="AMPLITUDE_MM:SEED,... (default 12:1)")
    ap.add_argument("--samples", type=int, default=32)
    ap.add_argument("--resample", type=int, default=1024)
    ap.add_argument("--grid", type=int, default=19)
    ap.add_argument("--threads", type=int, default=0)
    ap.add_argument("--bootstrap", type=int, default=0, help="identify --bootstrap N (0: Gauss-Newton sigma)")
    args = ap.parse_args()
    args.bistable = os.path.abspath(args.bistable)
    os.makedirs(args.out, exist_ok=True)
    results = []
    print("| record | labels agree | disagreeing points: truth / fit, P(truth's regime) under the fit's covariance "
          "(draws) | covered | largest |z| of the fit against the truth |")
    print("|---|---|---|---|---|")
    for item in args.records.split(","):
        amp, seed = item.split(":")
        r = one_record(args, float(amp), int(seed))
        results.append(r)
        dis = "; ".join(f"{d['a0_mm']:g} mm {d['f0_hz']:g} Hz: {d['truth']} / {d['fit']}, "
                        f"{d['p_truth_regime']:.3f} ± {d['p_truth_se']:.3f} ({d['samples']})" for d in r["disagree"])
        cov = sum(d["covered"] for d in r["disagree"])
        zmax = max(r["z"].items(), key=lambda kv: abs(kv[1])) if r["z"] else ("-", 0)
        print(f"| {r['record']} | {r['agree']} of {r['points']} ({100 * r['agree'] / r['points']:.1f} %) | "
              f"{dis or '-'} | {cov} of {len(r['disagree'])} | {zmax[0]} {zmax[1]:+.1f} |", flush=True)
    dis = [d for r in results for d in r["disagree"]]
    zs = [abs(z) for r in results for z in r["z"].values()]
    print(f"\n{len(results)} records; labels agree on {min(100 * r['agree'] / r['points'] for r in results):.1f}-"
          f"{max(100 * r['agree'] / r['points'] for r in results):.1f} % of the points; {len(dis)} disagreeing points, "
          f"{sum(d['covered'] for d in dis)} with the truth's regime probability > 2 standard errors above 0; the "
          f"fit against the truth in its own sigma ({results[0]['sigma'] if results else '-'}): |z| < 2 for "
          f"{sum(z < 2 for z in zs)}, < 3 for {sum(z < 3 for z in zs)} of {len(zs)} parameters")
    with open(os.path.join(args.out, "summary.json"), "w") as f:
        json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
