#!/usr/bin/env bash
# End-to-end sweep throughput and the reference comparison, all in one script so the ratios share the
# machine's load (absolute times on these shared machines drift by ±30 % between runs).
#   bench/bench_sweep.sh [BUILD_DIR]     (default: build)
# The first line says the CPU, the ISA and the lane width of the build measured (`bistable info`).
# 1. The paper's map settings: coupled, alpha x Omega = 201 x 201, tau 0-500, h 0.01, FRF + LLE + motion + HD + EDR,
#    all cores, including writing the HDF5 file (plots excluded).
# 2. The same 12 sample points through `bistable run --threads 1` and through scipy solve_ivp (single core both).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD=${1:-build}
BIN="$BUILD/client/bistable"
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT

"$BIN" info
echo "== 1. paper map settings (examples/paper_fig8_frf.toml), $(nproc) cores"
"$BIN" run examples/paper_fig8_frf.toml --data "$TMP/map" --json --quiet --no-plots > "$TMP/map.json"
/usr/bin/python3 - "$TMP/map.json" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
t = j["timing"]
print(f"  {j['computed']} points in {j['seconds']:.2f} s = {j['points_per_second']:.0f} points/s end to end "
      f"(plan {t['plan']:.2f} s, compute {t['compute']:.2f} s, publish {t['publish']:.2f} s; {j['threads']} threads)")
PY

ALPHAS="0.3,1.0,2.0"
OMEGAS="0.5,0.8,1.2,2.5"
cat > "$TMP/sample.toml" <<TOML
model = "coupled"
[axes]
alpha = [${ALPHAS}]
omega = [${OMEGAS}]
[metrics]
store = ["frf_db", "lle", "motion"]
TOML
echo "== 2. 12 sample points, one core each"
"$BIN" run "$TMP/sample.toml" --data "$TMP/sample" --json --quiet --no-plots --threads 1 > "$TMP/ours.json"
ID=$(/usr/bin/python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['id'])" "$TMP/ours.json")
"$BIN" map "$ID" --metric frf_db --format json --data "$TMP/sample" > "$TMP/frf.json"
"$BIN" map "$ID" --metric lle --format json --data "$TMP/sample" > "$TMP/lle.json"
/usr/bin/python3 bench/scipy_reference.py "$ALPHAS" "$OMEGAS" > "$TMP/scipy.json"
/usr/bin/python3 - "$TMP/ours.json" "$TMP/scipy.json" "$TMP/frf.json" "$TMP/lle.json" <<'PY'
import json, sys
ours, ref, frf, lle = (json.load(open(p)) for p in sys.argv[1:5])
ours_pps = ours["computed"] / ours["timing"]["compute"]
print(f"  bistable run (1 thread, 8-lane RK4 h=0.01): {ours_pps:9.1f} points/s")
print(f"  scipy solve_ivp RK45 rtol 1e-8 (1 core):    {ref['points_per_second']:9.3f} points/s")
print(f"  ratio: {ours_pps / ref['points_per_second']:.0f}x")
print("  per point (alpha, Omega): FRF dB ours / scipy, LLE ours / scipy")
na = len(frf["axes"]["alpha"]); nw = len(frf["axes"]["omega"])
for k, v in enumerate(ref["values"]):
    i, j = divmod(k, nw)
    print(f"    ({v['alpha']:.1f}, {v['omega']:.1f})  {frf['values'][i][j]:8.3f} / {v['frf_db']:8.3f}   "
          f"{lle['values'][i][j]:8.4f} / {v['lle']:8.4f}")
PY
