#!/usr/bin/env bash
# A/B of two builds of bench_scaling (before and after a coordinator change), alternating in one
# script so both see the same machine: delivered items/s at 64 and 128 fake workers, two rounds.
#   bench/scaling_ab.sh BEFORE_BINARY AFTER_BINARY [SPEC=examples/paper_fig8_frf.toml]
set -euo pipefail
before=${1:?usage: scaling_ab.sh BEFORE AFTER [SPEC]}
after=${2:?usage: scaling_ab.sh BEFORE AFTER [SPEC]}
spec=${3:-examples/paper_fig8_frf.toml}
echo "| round | workers | build | delivered items/s | reports/s | mean report ms |"
echo "|---|---|---|---|---|---|"
for round in 1 2; do
  for w in 64 128; do
    for v in before after; do
      b=$before
      [ "$v" = after ] && b=$after
      row=$("$b" "$spec" --seconds 3 --min-workers "$w" --max-workers "$w" 2> /dev/null | grep -E "^\| $w ")
      IFS='|' read -r _ _ _ items _ reports ms _ <<< "$row"
      echo "| $round | $w | $v | ${items// /} | ${reports// /} | ${ms// /} |"
    done
  done
done
