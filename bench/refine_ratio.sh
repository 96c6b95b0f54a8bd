#!/bin/bash
# Adaptive maps against uniform ones, in one run (issue 17). Runs examples/paper_fig8_refined.toml
# (Fig. 8b on a 1601 x 1601 grid, coarse level 201 x 201, 3 halvings) refined by the FRF 0 dB criterion
# and by motion type, then a uniform 401 x 401 window of the same grid in a fresh data directory, and
# prints:
#   - points computed by each refined map / the uniform grid's points, wall time / the uniform grid's
#     wall time (measured when --full-uniform is given, else the window's time scaled by its points);
#   - the window check: every point the refined map computed equals the uniform run bit for bit (all
#     stored metrics), boundary cells (refined to the finest spacing) included; and how often the filled
#     points' criterion class differs from the uniform run's (what refinement misses).
# Every run uses its own fresh data directory (nothing comes from a cache).
# Usage: bench/refine_ratio.sh [BUILD_DIR] [--full-uniform]     (run from the repository root)
set -euo pipefail
BUILD=${1:-build}
FULL=${2:-}
BIN=$BUILD/client/bistable
SPEC=examples/paper_fig8_refined.toml
PY=/usr/bin/python3  # h5py
WORK=$(mktemp -d /tmp/refine_ratio.XXXXXX)
trap 'rm -rf "$WORK"' EXIT
"$BIN" info  # the CPU, the ISA and the lane width of the build measured
A0=0 O0=400 N=401  # the window: alpha indices A0..A0+400, omega indices O0..O0+400 of the 1601 grid

run() {  # run SPEC DATA -> prints "computed seconds" (JSON from bistable run)
  "$BIN" run "$1" --data "$2" --json --no-plots --quiet |
    "$PY" -c 'import json,sys; j=json.load(sys.stdin); print(j["computed"], j["seconds"], j["files"][0])'
}

declare -A COMPUTED SECS MAP
for crit in frf_0db motion; do
  sed "s/^criterion = .*/criterion = \"$crit\"/" "$SPEC" > "$WORK/refined_$crit.toml"
  read -r c s m < <(run "$WORK/refined_$crit.toml" "$WORK/data_$crit")
  COMPUTED[$crit]=$c SECS[$crit]=$s MAP[$crit]=$m
done

# The uniform window: the refined map's own axis values (exact doubles, repr round-trips), as lists.
"$PY" - "$SPEC" "${MAP[frf_0db]}" "$WORK/window.toml" $A0 $O0 $N <<'EOF'
import re, sys, h5py
spec, path, out, a0, o0, n = sys.argv[1], sys.argv[2], sys.argv[3], *map(int, sys.argv[4:])
text = open(spec).read()
text = text[:text.index("[refine]")]
with h5py.File(path) as f:
    alpha = f["alpha"][a0:a0 + n]
    omega = f["omega"][o0:o0 + n]
lists = "alpha = [%s]\nomega = [%s]\n" % (", ".join(repr(float(v)) for v in alpha), ", ".join(repr(float(v)) for v in omega))
text = re.sub(r"alpha = \{[^}]*\}\nomega = \{[^}]*\}\n", lists, text)
text = text.replace('name = "paper Fig. 8b refined to 1601 x 1601"', 'name = "uniform window of the refined grid"')
text = text.replace(', "refine_level"', "")  # not a metric of a uniform map
open(out, "w").write(text)
EOF
read -r UC US UM < <(run "$WORK/window.toml" "$WORK/data_window")

FULL_SECONDS=""
if [ "$FULL" = "--full-uniform" ]; then
  sed -e '/^\[refine\]/,$d' -e 's/, "refine_level"//' "$SPEC" > "$WORK/uniform.toml"
  read -r FC FULL_SECONDS FM < <(run "$WORK/uniform.toml" "$WORK/data_uniform")
fi

"$PY" - "$UM" "${MAP[frf_0db]}" "${MAP[motion]}" $A0 $O0 $N "${COMPUTED[frf_0db]}" "${SECS[frf_0db]}" \
  "${COMPUTED[motion]}" "${SECS[motion]}" "$UC" "$US" "$FULL_SECONDS" <<'EOF'
import sys, h5py, numpy as np
um, fm, mm = sys.argv[1:4]
a0, o0, n = map(int, sys.argv[4:7])
cf, sf, cm, sm, uc, us = float(sys.argv[7]), float(sys.argv[8]), float(sys.argv[9]), float(sys.argv[10]), float(sys.argv[11]), float(sys.argv[12])
full = float(sys.argv[13]) if sys.argv[13] else None
total = 1601 * 1601
uniform_seconds = full if full else us * total / uc
how = "measured" if full else "window time x %d/%d points" % (total, int(uc))
print("uniform 1601 x 1601: %d points, %.1f s (%s)" % (total, uniform_seconds, how))
ok = True
with h5py.File(um) as u:
    metrics = [k for k in u.keys() if k in ("frf_db", "lle", "motion", "period", "hd_index", "edr_b", "edr_r", "edr_t",
                                            "energy_balance_residual", "y_min", "y_max", "hd_peak_freq", "hd_peak_amp")]
    for name, path, c, s in (("frf_0db", fm, cf, sf), ("motion", mm, cm, sm)):
        with h5py.File(path) as r:
            sl = (slice(a0, a0 + n), slice(o0, o0 + n))
            fill = r["refine_fill"][sl]
            level = r["refine_level"][sl]
            computed = fill == 0
            boundary = computed & (level == 3)
            differ = 0
            for m in metrics:
                a, b = r[m][sl], u[m][:]
                eq = (a.view(np.uint64) == b.view(np.uint64)) if a.dtype == np.float64 else (a == b)
                if eq.ndim == 3:
                    eq = eq.all(axis=2)
                differ += int((computed & ~eq).sum())
            if name == "frf_0db":
                cls_r, cls_u = r["frf_db"][sl] >= 0, u["frf_db"][:] >= 0
            else:
                cls_r, cls_u = r["motion"][sl], u["motion"][:]
            filled = fill != 0
            miss = int((filled & (cls_r != cls_u)).sum())
            mixed = int((fill == 2).sum())
            print("refined by %-8s %7d points = %.4f of uniform, %6.1f s = %.3f of uniform time" % (name, c, c / total, s, s / uniform_seconds))
            print("  window 401 x 401: %d computed (%d at the finest level), %d values differ from the uniform run; "
                  "filled points whose class differs: %d of %d (%.2f %%); chaotic-mixed points: %d" %
                  (int(computed.sum()), int(boundary.sum()), differ, miss, int(filled.sum()), 100.0 * miss / max(1, int(filled.sum())), mixed))
            ok = ok and differ == 0
print("window check: %s" % ("every computed point equals the uniform run bit for bit" if ok else "MISMATCH"))
sys.exit(0 if ok else 1)
EOF
