#!/usr/bin/env bash
# Two builds' whole maps, alternating in one run (the machine is shared: compare within a run):
#   bench/map_ab.sh OLD_BISTABLE NEW_BISTABLE [ROUNDS] [THREADS] [SPEC]
# e.g. git worktree add /tmp/old HEAD~1 && (cd /tmp/old && cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release &&
#      cmake --build build --target bistable); bench/map_ab.sh /tmp/old/build/client/bistable build/client/bistable 5 2
# Each round runs `bistable run SPEC --threads T --no-plots` into a fresh data directory (nothing cached)
# and prints the run's own timing (plan, compute, publish); the last lines are the medians.
set -euo pipefail
OLD=${1:?usage: bench/map_ab.sh OLD NEW [ROUNDS] [THREADS] [SPEC]}
NEW=${2:?usage: bench/map_ab.sh OLD NEW [ROUNDS] [THREADS] [SPEC]}
ROUNDS=${3:-5}
THREADS=${4:-2}
SPEC=${5:-$(dirname "$0")/../examples/paper_fig8_frf.toml}
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
for b in "$OLD" "$NEW"; do  # the CPU, the ISA and the lane width of each build (older builds lack `info`)
  echo "$b: $("$b" info 2>/dev/null || echo "(no \`bistable info\` in this build)")"
done
for r in $(seq "$ROUNDS"); do
  for which in old new; do
    bin=$OLD
    [ "$which" = new ] && bin=$NEW
    rm -rf "$TMP/data"
    "$bin" run "$SPEC" --threads "$THREADS" --no-plots --quiet --json --data "$TMP/data" |
      /usr/bin/python3 -c "import json, sys; d = json.load(sys.stdin); t = d['timing']
print('$which', d['seconds'], t['plan'], t['compute'], t['publish'])" | tee -a "$TMP/runs"
  done
done
/usr/bin/python3 - "$TMP/runs" "$THREADS" <<'PY'
import statistics, sys
rows = [l.split() for l in open(sys.argv[1])]
for which in ("old", "new"):
    cols = list(zip(*[[float(x) for x in r[1:]] for r in rows if r[0] == which]))
    med = [statistics.median(c) for c in cols]
    print("%s, %s thread(s), median of %d: total %.3f s, plan %.3f, compute %.3f, publish %.3f" % (which, sys.argv[2], len(cols[0]), *med))
PY
