#!/usr/bin/env bash
# Distributed vs embedded on the same spec and the same cores, in one script (shared machine load):
# `bistable run --threads 2` against a coordinator with 2 single-thread workers, then 1, 2, 4, 8
# worker processes. Times are compute-phase wall times; ratios are what to compare.
#   bench/bench_distributed.sh [GRID=100] [BUILD_DIR=build]
# The first line says the CPU, the ISA and the lane width of the build measured (`bistable info`).
set -euo pipefail
cd "$(dirname "$0")/.."
GRID=${1:-100}
BUILD=${2:-build}
CLI="$BUILD/client/bistable"
DIR=$(mktemp -d)
trap 'pkill -P $$ 2>/dev/null || true; rm -rf "$DIR"' EXIT
"$CLI" info
cat > "$DIR/spec.toml" <<TOML
model = "coupled"
[axes]
alpha = { linspace = [0.05, 3.0, $GRID] }
omega = { linspace = [0.05, 3.0, $GRID] }
TOML

embedded() {
  rm -rf "$DIR/emb"
  "$CLI" run "$DIR/spec.toml" --data "$DIR/emb" --threads 2 --json --quiet --no-plots |
    /usr/bin/python3 -c 'import json,sys; print(json.load(sys.stdin)["seconds"])'  # plan + compute + publish
}

distributed() {  # $1 = worker processes
  rm -rf "$DIR/dist"
  local port
  port=$(/usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  "$BUILD/server/bistable-coordinator" --listen "127.0.0.1:$port" --data "$DIR/dist" > "$DIR/coord.out" 2>&1 &
  local cpid=$! wpids=()
  # Workers start once the coordinator listens (else their first registrations back off for seconds).
  until grep -q listening "$DIR/coord.out" 2>/dev/null; do sleep 0.02; done
  for i in $(seq "$1"); do
    "$BUILD/worker/bistable-worker" --coordinator "127.0.0.1:$port" --threads 1 --name "w$i" > /dev/null 2>&1 &
    wpids+=($!)
  done
  local id
  for _ in $(seq 100); do id=$("$CLI" submit "$DIR/spec.toml" --coordinator "127.0.0.1:$port" 2>/dev/null) && break; sleep 0.05; done
  # (timing starts after submit returns: planning is inside both measurements' counterparts)
  local t0 t1
  t0=$(date +%s.%N)
  # One streaming watch (not a polling loop of processes, which would steal the cores being measured).
  "$CLI" status "$id" --watch --json --coordinator "127.0.0.1:$port" > /dev/null 2>&1 || true
  t1=$(date +%s.%N)
  kill "${wpids[@]}" "$cpid" 2>/dev/null; wait 2>/dev/null || true
  echo "$t1 - $t0" | bc -l
}

points=$((GRID * GRID))
e1=$(embedded); d2=$(distributed 2); e2=$(embedded); d2b=$(distributed 2)
/usr/bin/python3 - "$points" "$e1" "$e2" "$d2" "$d2b" <<'PY'
import sys
n, e1, e2, d1, d2 = int(sys.argv[1]), *map(float, sys.argv[2:])
e, d = (e1 + e2) / 2, (d1 + d2) / 2
print(f"same spec ({n} points, tau 0-500), 2 cores, interleaved runs (mean of 2):")
print(f"  embedded `bistable run --threads 2`     {e:6.2f} s  ({n / e:6.0f} points/s)")
print(f"  coordinator + 2 worker processes       {d:6.2f} s  ({n / d:6.0f} points/s)")
print(f"  distributed overhead                   {100 * (d / e - 1):+5.1f} %")
PY
echo "worker processes on loopback (2 cores):"
for w in 1 2 4 8; do
  t=$(distributed "$w")
  /usr/bin/python3 -c "import sys; t=float('$t'); print(f'  {$w} worker(s): {t:6.2f} s  ({$points / t:6.0f} points/s)')"
done
