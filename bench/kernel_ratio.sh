#!/usr/bin/env bash
# The ensemble kernel, and optionally a whole map, against the reference kernel (a plain SoA RK4 of the
# coupled model with one tangent vector, kept outside the project as a ruler), built and run in this
# script, alternating, so all see the same machine load. Prints each round and the medians.
#   bench/kernel_ratio.sh REFERENCE_KERNEL.cc [BUILD_DIR] [ROUNDS] [--map SPEC.toml]
#   e.g. bench/kernel_ratio.sh ../shared/bench/reference_kernel.cc build 5 --map examples/paper_fig8_frf.toml
# The reference is compiled as its header says (g++ -O3 -march=native -fopenmp-simd
# -mprefer-vector-width=512; GCC's default -ffp-contract=fast lets it use FMA) and once more with
# -ffp-contract=off, so the FMA share is visible; -march is the build's own (native, or x86-64-v3 for a
# portable build, read from bench_kernel's header), so both sides use the same vector unit.
# Kernel rows (bench_kernel, the coupled model at the paper's settings, τ 0–500, window from 250):
#   - "same work as the reference": τ 0–500 with no window (bench_kernel's BM_KernelNoWindow), i.e.
#     state + tangent + renormalisation, what the reference does;
#   - "with the sweep's window": the window's quadratures, strobes, turning points and samples over
#     τ 250–500 (BM_KernelCoupledTangent), what a sweep point costs in the kernel.
# --map: the whole map `bistable run SPEC --threads T --no-plots` (fresh data directory, nothing
# cached) for T = 1 and 2; its lane-steps/s = points × steps per point ÷ wall seconds, against the
# kernel bound = T × the kernel-with-window rate of the same round (issue 14's "whole map ≥ 0.8×"); for
# T = 2 also against the kernel measured on both cores at once (two bench_kernel processes), since two
# vCPUs of this VM do not deliver twice one.
# The kernel rows run the engine's lane width W (bench_kernel: 8 on AVX-512, 4 on AVX2, fixed at compile
# time) and 2W; the first line printed is bench_kernel's header (CPU, ISA, W).
set -euo pipefail
cd "$(dirname "$0")/.."
REF=${1:?usage: bench/kernel_ratio.sh REFERENCE_KERNEL.cc [BUILD_DIR] [ROUNDS] [--map SPEC.toml]}
BUILD=${2:-build}
ROUNDS=${3:-5}
MAP=""
if [ "${4:-}" = "--map" ]; then MAP=${5:?--map needs a spec}; fi
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
[ -x "$BUILD/bench/bench_kernel" ] || { echo "build $BUILD/bench/bench_kernel first (cmake --build $BUILD --target bench_kernel)" >&2; exit 2; }
HEADER=$("$BUILD/bench/bench_kernel" --header)
W=$(echo "$HEADER" | sed -n 's/.*| lanes: \([0-9]*\) .*/\1/p')
MARCH=$(echo "$HEADER" | sed -n 's/.*-march=\([A-Za-z0-9_.-]*\).*/\1/p')
[ -n "$W" ] && [ -n "$MARCH" ] || { echo "no lane width or -march in bench_kernel's header: $HEADER" >&2; exit 2; }
echo "$HEADER"
echo "reference kernel compiled with -march=$MARCH (the build's target)"
g++ -O3 -march="$MARCH" -fopenmp-simd -mprefer-vector-width=512 -o "$TMP/ref" "$REF"
g++ -O3 -march="$MARCH" -fopenmp-simd -mprefer-vector-width=512 -ffp-contract=off -o "$TMP/ref_nofma" "$REF"
STEPS=0
if [ -n "$MAP" ]; then
  [ -x "$BUILD/client/bistable" ] || { echo "build $BUILD/client/bistable first" >&2; exit 2; }
  STEPS=$(/usr/bin/python3 -c "import sys, tomllib; s = tomllib.load(open(sys.argv[1], 'rb')); i = s.get('integration', {}); print(round(i.get('t_end', 500) / i.get('dt', 0.01)))" "$MAP")
fi
map_rate() {  # threads → M lane-steps/s of the whole map
  rm -rf "$TMP/data"
  "$BUILD/client/bistable" run "$MAP" --threads "$1" --no-plots --quiet --json --data "$TMP/data" |
    /usr/bin/python3 -c "import json, sys; d = json.load(sys.stdin); print('%.1f' % (d['points'] * $STEPS / d['seconds'] / 1e6))"
}

pair_kernel() {  # M lane-steps/s of one kernel-with-window process
  "$BUILD/bench/bench_kernel" --benchmark_filter="BM_KernelCoupledTangent<$W>" --benchmark_min_time=0.5 2>/dev/null |
    sed -n "s/^BM_KernelCoupledTangent<$W>.*rk4_steps_per_s=\([0-9.]*\)M\/s.*/\1/p"
}

for r in $(seq "$ROUNDS"); do
  ref=$("$TMP/ref" 1024 | sed -n 's/.* \([0-9.]*\) Msteps\/s.*/\1/p')
  nofma=$("$TMP/ref_nofma" 1024 | sed -n 's/.* \([0-9.]*\) Msteps\/s.*/\1/p')
  ours=$("$BUILD/bench/bench_kernel" --benchmark_filter="BM_Kernel(NoWindow|CoupledTangent)<($W|$((2 * W)))>" --benchmark_min_time=0.5 2>/dev/null |
         sed -n 's/^BM_Kernel\(NoWindow\|CoupledTangent\)<\([0-9]*\)>.*rk4_steps_per_s=\([0-9.]*\)M\/s.*/\1_\2 \3/p' | tr '\n' ' ')
  maps=""
  if [ -n "$MAP" ]; then
    # The kernel on both cores at once (two processes): what two threads can get on this VM, where the
    # two vCPUs do not give twice one (the reference, run twice at once, reached 0.67-0.94 of 2x alone).
    pair=$( { pair_kernel & pair_kernel; wait; } | awk '{ s += $1 } END { printf "%.1f", s }')
    maps="map1 $(map_rate 1) map2 $(map_rate 2) kernel2 $pair"
  fi
  echo "round $r: reference $ref M/s, without FMA $nofma M/s, kernel (M lane-steps/s) $ours $maps"
  echo "$ref $nofma $ours $maps" >> "$TMP/rounds"
done
/usr/bin/python3 - "$TMP/rounds" "$W" <<'PY'
import statistics, sys
rows = [line.split() for line in open(sys.argv[1])]
W = int(sys.argv[2])
ref = [float(r[0]) for r in rows]
med = statistics.median
cols = {}
for r in rows:
    for k in range(2, len(r), 2):
        cols.setdefault(r[k], []).append(float(r[k + 1]))
print("median of %d alternating rounds, M RK4 lane-steps/s (per core for kernels):" % len(rows))
print("  reference kernel (16 lanes, FMA)                          %7.1f   1.00" % med(ref))
print("  reference kernel, -ffp-contract=off                       %7.1f   %.2f" % (med([float(r[1]) for r in rows]), med([float(r[1]) / float(r[0]) for r in rows])))
names = {"NoWindow": "kernel, same work as the reference", "CoupledTangent": "kernel with the sweep's window"}
for key in sorted(k for k in cols if "_" in k):
    kind, w = key.split("_")
    v = cols[key]
    print("  %-40s %2s lanes %7.1f   %.2f" % (names[kind], w, med(v), med([x / a for a, x in zip(ref, v)])))
if "map1" in cols:
    kern = cols.get("CoupledTangent_%d" % W)
    for t in (1, 2):
        v = cols["map%d" % t]
        print("  whole map, %d thread(s)                                  %7.1f   %.2f of the reference x %d, %.2f of the kernel bound (%d x kernel with window)"
              % (t, med(v), med([x / (t * a) for a, x in zip(ref, v)]), t, med([x / (t * k) for k, x in zip(kern, v)]), t))
    pair = cols["kernel2"]
    print("  kernel with window, two processes at once (sum)          %7.1f   %.2f of 2 x one alone"
          % (med(pair), med([p / (2 * k) for k, p in zip(kern, pair)])))
    print("  whole map, 2 threads, against the two-process kernel                %.2f of the measured two-core kernel bound"
          % med([x / p for p, x in zip(pair, cols["map2"])]))
PY
