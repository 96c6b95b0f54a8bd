#!/usr/bin/env bash
# A/B of two coordinator binaries (before and after a change), alternating in one script so both see
# the same machine: bench_scaling --external (the coordinator pinned to one CPU, the fake workers on the
# others, real records as payload), delivered items/s at 32 and 64 fake workers, two rounds.
#   bench/scaling_ab.sh BEFORE_COORDINATOR AFTER_COORDINATOR [SPEC=examples/paper_fig8_frf.toml]
# The first line is bench_scaling's header: the CPU, the ISA and the lane width its payload job ran at.
set -euo pipefail
before=${1:?usage: scaling_ab.sh BEFORE AFTER [SPEC]}
after=${2:?usage: scaling_ab.sh BEFORE AFTER [SPEC]}
spec=${3:-examples/paper_fig8_frf.toml}
bench=${BENCH:-build/bench/bench_scaling}
declare -A sum
header=1
for round in 1 2; do
  for w in 32 64; do
    for v in before after; do
      b=$before
      [ "$v" = after ] && b=$after
      out=$("$bench" "$spec" --external "$b" --seconds 3 --min-workers "$w" --max-workers "$w" 2> /dev/null)
      if [ "$header" = 1 ]; then
        echo "$out" | head -1
        echo "| round | fake workers | coordinator | delivered items/s | reports/s | mean report ms |"
        echo "|---|---|---|---|---|---|"
        header=0
      fi
      row=$(echo "$out" | grep -E "^\| $w ")
      IFS='|' read -r _ _ _ items _ reports ms _ <<< "$row"
      items=${items// /}
      echo "| $round | $w | $v | $items | ${reports// /} | ${ms// /} |"
      sum[$v]=$(( ${sum[$v]:-0} + items ))
    done
  done
done
awk -v a="${sum[after]}" -v b="${sum[before]}" 'BEGIN { printf "after / before, summed over the rows: %.2f\n", a / b }'
