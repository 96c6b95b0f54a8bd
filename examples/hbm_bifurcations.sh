#!/bin/sh
# Harmonic balance bifurcations (docs/numerics.md, "Bifurcations along branches, branch switching and fold curves").
# Run from the repository root after building; writes PNGs into ./hbm-example/.
set -e
B=${BISTABLE:-./build/client/bistable}
mkdir -p hbm-example

# 1. The period-doubling cascade of the double-well Duffing y'' + 0.3 y' - y + y^3 = alpha Omega^2 sin(Omega tau)
#    at Omega = 1.2: period doublings at alpha = 0.18443, 0.19909, 0.20215 (period 1 -> 2 -> 4 -> 8).
$B hbm --continue alpha --omega 1.2 --eta 0.3 --from 0.1 --to 0.25 --harmonics 10 --switch-pd 2
$B hbm --continue alpha --omega 1.2 --eta 0.3 --from 0.1 --to 0.25 --harmonics 10 --switch-pd 2 \
    --format png --out hbm-example/cascade.png

# 2. Fold curves in (alpha, Omega) from the folds at alpha = 0.3 (the +well resonance's curve has a cusp
#    near alpha = 0.02, Omega = 1.33: below it no hysteresis).
$B hbm --alpha 0.3 --fold-curve --fold-out hbm-example/folds.png

# 3. The same curves over the stand-alone motion map (paper Figs. 7a/8a, 201 x 201 points; eta 0.1 as the balance).
$B run examples/paper_fig7_8_standalone.toml --data hbm-example/data
MAP=$(ls hbm-example/data/sweeps/*.h5 | head -n 1)
$B hbm --alpha 0.3 --fold-curve --over-map "$MAP" --fold-out hbm-example/folds_over_motion.png
