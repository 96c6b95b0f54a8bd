#!/usr/bin/env bash
# The cost curve (issue 14): `bistable run` on the paper's main job (examples/paper_fig8_frf.toml) over
# grids 41², 101², 201², 401², 801² at the spec's tau_end, and over tau_end 250 ... 4,000 on a 61² grid
# (window [tau_end/2, tau_end], the spec's proportion), with --threads 1 and 2: wall time, peak memory
# (GNU time's max RSS), the fitted log-log exponents, HDF5 publish time and map size per million points,
# and the coordinator's memory per queued job (a real bistable-coordinator, no workers). Every run is
# printed with its fraction of the reference kernel's bound, points/s x RK4 steps per point /
# (reference M steps/s with one copy per thread), the reference measured just before and after each run.
#   bench/cost_curve.sh REFERENCE_KERNEL.cc [BUILD_DIR] [--quick] [--table FILE] [--plot FILE.png]
#                       [--threads 1,2] [--tau-grid 61] [--grids 41,101] [--taus 250,500] [--coord-grids 201,401]
#                       [--rounds N] [--workdir DIR]
#   e.g. bench/cost_curve.sh ../shared/bench/reference_kernel.cc build --quick --plot /tmp/cost.png
# Paths are relative to the current directory. The reference kernel is compiled in a temporary directory
# exactly as bench/kernel_ratio.sh does (never copied into the project). --quick: grids 41² and 101²,
# tau_end 250 and 500, coordinator at 101² and 201² (about a minute here). Maps go to a temporary directory
# on $TMPDIR's disk (--workdir to choose), removed afterwards. Run it alone on the machine (timing).
set -euo pipefail
REF=${1:?usage: bench/cost_curve.sh REFERENCE_KERNEL.cc [BUILD_DIR] [--quick] [--table FILE] [--plot FILE]}
shift
BUILD=build
if [ $# -gt 0 ] && [ "${1#--}" = "$1" ]; then BUILD=$1; shift; fi
REPO=$(cd "$(dirname "$0")/.." && pwd)
[ -f "$REF" ] || { echo "error: reference kernel $REF not found" >&2; exit 2; }
REF=$(realpath "$REF")
case "$BUILD" in /*) ;; *) BUILD=$(realpath -m "$BUILD") ;; esac
ARGS=()
while [ $# -gt 0 ]; do  # make the file arguments absolute before changing directory
  case "$1" in
    --table|--plot|--workdir) ARGS+=("$1" "$(realpath -m "${2:?$1 needs a value}")"); shift 2 ;;
    *) ARGS+=("$1"); shift ;;
  esac
done
[ -x /usr/bin/time ] || { echo "error: GNU time (/usr/bin/time, Debian package time) is needed for peak memory" >&2; exit 2; }
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
g++ -O3 -march=native -fopenmp-simd -mprefer-vector-width=512 -o "$TMP/ref" "$REF"
cd "$REPO"
"$BUILD/client/bistable" info  # the CPU, the ISA and the lane width of the build measured
/usr/bin/python3 bench/cost_curve.py --ref-bin "$TMP/ref" --build "$BUILD" "${ARGS[@]}"
