#!/usr/bin/env bash
# Held-out truth samples of issue 38: random grid points (fixed seed) of the Fig. 8 grid (coupled) and the
# stand-alone Fig. 7 grid, each labelled by a long run (τ 30,000; labels from τ 20,000–30,000, and from
# τ 10,000–20,000 to flag points whose truth has not settled). Regenerates the files beside this script:
#   fig8_indices.txt, fig7_indices.txt   the samples (grid point indices, row-major alpha x omega)
#   fig8_truth.csv, fig7_truth.csv       the labels (bench/truth_labels.cc)
# Usage: bench/labels/make_truth.sh [BUILD_DIR] [GRID]   (GRID fig8 or fig7, default both; one thread, nice 10;
# 2-4 min per grid on this machine). Sizes: 2,000 points on Fig. 8 (309 chaotic), 3,800 on Fig. 7 (chaos is rarer
# stand-alone: ≥ 300 chaotic points).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
build=${1:-$root/build}
only=${2:-}
for g in fig8:paper_fig8_frf.toml:38008:2000 fig7:paper_fig7_8_standalone.toml:38007:3800; do
  IFS=: read -r name spec seed n <<<"$g"
  [[ -n "$only" && "$only" != "$name" ]] && continue
  /usr/bin/python3 - "$n" "$seed" >"$here/${name}_indices.txt" <<'PY'
import random, sys
n, seed = int(sys.argv[1]), int(sys.argv[2])
for i in sorted(random.Random(seed).sample(range(201 * 201), n)):
    print(i)
PY
  nice -n 10 "$build/bench/truth_labels" "$root/examples/$spec" "$here/${name}_indices.txt" --threads 1 \
    >"$here/${name}_truth.csv"
done
