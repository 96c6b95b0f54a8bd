#!/usr/bin/env bash
# The ensemble kernel against the reference kernel (a plain SoA RK4 of the coupled model with one tangent
# vector, kept outside the project as a ruler), built and run in this script, alternating, so both see
# the same machine load. Prints each round and the median ratio per lane width (issue 14's first target).
#   bench/kernel_ratio.sh REFERENCE_KERNEL.cc [BUILD_DIR] [ROUNDS]
#   e.g. bench/kernel_ratio.sh ../shared/bench/reference_kernel.cc build 5
# The reference is compiled as its header says (g++ -O3 -march=native -fopenmp-simd
# -mprefer-vector-width=512; GCC's default -ffp-contract=fast lets it use FMA) and once more with
# -ffp-contract=off, the project's setting (bit-identical lanes), so the FMA share of the gap is visible.
set -euo pipefail
cd "$(dirname "$0")/.."
REF=${1:?usage: bench/kernel_ratio.sh REFERENCE_KERNEL.cc [BUILD_DIR] [ROUNDS]}
BUILD=${2:-build}
ROUNDS=${3:-5}
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
g++ -O3 -march=native -fopenmp-simd -mprefer-vector-width=512 -o "$TMP/ref" "$REF"
g++ -O3 -march=native -fopenmp-simd -mprefer-vector-width=512 -ffp-contract=off -o "$TMP/ref_nofma" "$REF"
[ -x "$BUILD/bench/bench_kernel" ] || { echo "build $BUILD/bench/bench_kernel first (cmake --build $BUILD --target bench_kernel)" >&2; exit 2; }

for r in $(seq "$ROUNDS"); do
  ref=$("$TMP/ref" 1024 | sed -n 's/.* \([0-9.]*\) Msteps\/s.*/\1/p')
  nofma=$("$TMP/ref_nofma" 1024 | sed -n 's/.* \([0-9.]*\) Msteps\/s.*/\1/p')
  ours=$("$BUILD/bench/bench_kernel" --benchmark_filter='BM_KernelCoupledTangent<(8|16)>' --benchmark_min_time=0.5 2>/dev/null |
         sed -n 's/^BM_KernelCoupledTangent<\([0-9]*\)>.*rk4_steps_per_s=\([0-9.]*\)M\/s.*/\1 \2/p' | tr '\n' ' ')
  echo "round $r: reference $ref M/s, reference without FMA $nofma M/s, kernel (lanes M/s) $ours"
  echo "$ref $nofma $ours" >> "$TMP/rounds"
done
/usr/bin/python3 - "$TMP/rounds" <<'PY'
import statistics, sys
rows = [line.split() for line in open(sys.argv[1])]
ref = [float(r[0]) for r in rows]
nofma = [float(r[1]) for r in rows]
lanes = {}
for r in rows:
    for k in range(2, len(r), 2):
        lanes.setdefault(r[k], []).append(float(r[k + 1]))
print("median of %d alternating rounds, M RK4 lane-steps/s on one core:" % len(rows))
print("  reference kernel (16 lanes, FMA)              %7.1f   1.00" % statistics.median(ref))
print("  reference kernel, -ffp-contract=off           %7.1f   %.2f" % (statistics.median(nofma), statistics.median([b / a for a, b in zip(ref, nofma)])))
for w, v in sorted(lanes.items(), key=lambda kv: int(kv[0])):
    ratios = [x / a for a, x in zip(ref, v)]
    print("  bench_kernel, %2s lanes                         %7.1f   %.2f" % (w, statistics.median(v), statistics.median(ratios)))
PY
