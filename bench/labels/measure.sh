#!/usr/bin/env bash
# Issue 38's measurement: the main job (the Fig. 8 grid) in the paper's mode and with settled labels, in one
# script on the same machine state, alternating, fresh data directories; then both maps of the Fig. 8 and the
# stand-alone Fig. 7 grids scored against the held-out truth (score_map.py).
#   bench/labels/measure.sh [BUILD_DIR] [THREADS] [ROUNDS]
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
build=${1:-$root/build}
threads=${2:-1}
rounds=${3:-1}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
bin="$build/client/bistable"
run() {  # name spec -> prints seconds, leaves the map path in $tmp/name.path
  local d="$tmp/$1.$RANDOM"
  "$bin" run "$root/examples/$2" --threads "$threads" --no-plots --json --data "$d" >"$tmp/$1.json"
  /usr/bin/python3 -c "import json,sys; j=json.load(open(sys.argv[1])); print(j['files'][0]); print(j['seconds'], j['timing']['compute'], file=sys.stderr)" \
    "$tmp/$1.json" >"$tmp/$1.path" 2>"$tmp/$1.sec"
  cp "$(cat "$tmp/$1.path")" "$tmp/$1.h5"
  rm -rf "$d"
  echo "$1 wall $(cut -d' ' -f1 "$tmp/$1.sec") s, compute $(cut -d' ' -f2 "$tmp/$1.sec") s"
}
for r in $(seq "$rounds"); do
  run paper8 paper_fig8_frf.toml
  run settled8 paper_fig8_settled.toml
done
run paper7 paper_fig7_8_standalone.toml
run settled7 paper_fig7_settled.toml
for m in paper8 settled8; do echo "== $m vs fig8 truth"; /usr/bin/python3 "$here/score_map.py" "$here/fig8_truth.csv" "$tmp/$m.h5"; done
for m in paper7 settled7; do echo "== $m vs fig7 truth"; /usr/bin/python3 "$here/score_map.py" "$here/fig7_truth.csv" "$tmp/$m.h5"; done
