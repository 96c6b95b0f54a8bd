#!/usr/bin/env bash
# Repeated fault run: one sweep through a coordinator and 3 workers while the coordinator and the
# workers are killed with SIGKILL at random (each victim restarted at once), at least KILLS times;
# then the map is compared byte for byte with the embedded `bistable run` of the same spec.
#   bench/fault_run.sh [KILLS=24] [GRID=170] [BUILD_DIR=build]  (a smaller grid may finish before KILLS)
# Exit 0 when the maps are identical and the kill count was reached before the sweep finished.
set -euo pipefail
cd "$(dirname "$0")/.."
KILLS=${1:-24}
GRID=${2:-170}
BUILD=${3:-build}
COORD="$BUILD/server/bistable-coordinator"
WORKER="$BUILD/worker/bistable-worker"
CLI="$BUILD/client/bistable"
DIR=$(mktemp -d)
PORT=$(/usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
ADDR="127.0.0.1:$PORT"
declare -a WPIDS
CPID=""
cleanup() {
  for p in "${WPIDS[@]:-}" "$CPID"; do [ -n "$p" ] && kill -9 "$p" 2>/dev/null || true; done
  rm -rf "$DIR"
}
trap cleanup EXIT

cat > "$DIR/spec.toml" <<TOML
name = "fault run"
model = "coupled"
[axes]
alpha = { linspace = [0.05, 3.0, $GRID] }
omega = { linspace = [0.05, 3.0, $GRID] }
[integration]
t_end = 300.0
t_keep = 150.0
TOML

start_coord() {
  "$COORD" --listen "$ADDR" --data "$DIR/data" --lease-seconds 1 --job-seconds 0.05 > "$DIR/coord.log" 2>&1 &
  CPID=$!
}
start_worker() {
  "$WORKER" --coordinator "$ADDR" --threads 1 --name "w$1-$RANDOM" > /dev/null 2>&1 &
  WPIDS[$1]=$!
}
status() { "$CLI" status "$ID" --json --coordinator "$ADDR" 2>/dev/null || echo '{"state":"unreachable"}'; }

start_coord
for i in 0 1 2; do start_worker $i; done
ID=""
for _ in $(seq 100); do
  ID=$("$CLI" submit "$DIR/spec.toml" --coordinator "$ADDR" 2>/dev/null) && break
  sleep 0.1
done
[ -n "$ID" ] || { echo "fault run: submit failed"; exit 1; }

T0=$(date +%s.%N)
kills=0; coord_kills=0
while true; do
  state=$(status | /usr/bin/python3 -c 'import json,sys; print(json.load(sys.stdin)["state"])')
  [ "$state" = "done" ] && break
  sleep "0.$((RANDOM % 20 + 10))"
  if [ "$kills" -lt "$KILLS" ]; then
    victim=$((RANDOM % 4))
    if [ "$victim" -eq 3 ]; then
      kill -9 "$CPID" 2>/dev/null || true; wait "$CPID" 2>/dev/null || true
      start_coord; coord_kills=$((coord_kills + 1))
    else
      kill -9 "${WPIDS[$victim]}" 2>/dev/null || true; wait "${WPIDS[$victim]}" 2>/dev/null || true
      start_worker "$victim"
    fi
    kills=$((kills + 1))
  fi
done
T1=$(date +%s.%N)
"$CLI" run "$DIR/spec.toml" --data "$DIR/embedded" --quiet --no-plots > /dev/null
/usr/bin/python3 - "$DIR/data/sweeps/$ID.h5" "$DIR/embedded/sweeps/$ID.h5" "$kills" "$coord_kills" "$KILLS" "$T0" "$T1" <<'PY'
import sys, h5py
a, b, kills, ck, want, t0, t1 = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5]), float(sys.argv[6]), float(sys.argv[7])
fa, fb = h5py.File(a, "r"), h5py.File(b, "r")
diff = [k for k in fb.keys() if fa[k][()].tobytes() != fb[k][()].tobytes()]
print(f"fault run: {kills} kills ({ck} of the coordinator) in {t1 - t0:.1f} s; "
      f"{len(fb.keys())} datasets, {'identical' if not diff else 'DIFFERENT: ' + ', '.join(diff)}")
sys.exit(0 if not diff and kills >= want else 1)
PY
