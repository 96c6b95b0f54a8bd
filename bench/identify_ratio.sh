#!/usr/bin/env bash
# Every loop of docs/identification.md with two `bistable` binaries (e.g. one built from an older commit
# and the current one), run one after the other per loop in the same script so both see the same
# machine load: wall seconds of each, the ratio old/new, and each run's errors and added terms (the
# result must not get worse while the time falls). Run it alone (or under the build lock) for honest
# ratios. The json column: same (the same JSON but for wall times), same* (and but for keys only one build
# writes), differ. A failing run stops the script.
#   bench/identify_ratio.sh OLD_BISTABLE NEW_BISTABLE [MEASURED_DIR] [LOOPS]
#   e.g. git worktree add /tmp/old <commit> && cmake -S /tmp/old -B /tmp/old/build -G Ninja \
#          -DCMAKE_BUILD_TYPE=Release && cmake --build /tmp/old/build --target bistable
#        bench/identify_ratio.sh /tmp/old/build/client/bistable build/client/bistable
# MEASURED_DIR holds silverbox/ and bistable-harvester/ (default ../shared/data/measured); loops whose
# data are missing are skipped with a note. LOOPS: a comma-separated subset of
#   syn_c2, syn_friction, syn_null, silverbox, harvester_inter, harvester_intra   (default: all)
set -euo pipefail
OLD=${1:?usage: bench/identify_ratio.sh OLD_BISTABLE NEW_BISTABLE [MEASURED_DIR] [LOOPS]}
NEW=${2:?usage: bench/identify_ratio.sh OLD_BISTABLE NEW_BISTABLE [MEASURED_DIR] [LOOPS]}
cd "$(dirname "$0")/.."
DATA=${3:-../shared/data/measured}
LOOPS=${4:-syn_c2,syn_friction,syn_null,silverbox,harvester_inter,harvester_intra}
for b in "$OLD" "$NEW"; do [ -x "$b" ] || { echo "error: '$b' is not an executable bistable binary" >&2; exit 2; }; done
for b in "$OLD" "$NEW"; do  # the CPU, the ISA and the lane width of each build (older builds lack `info`)
  echo "$b: $("$b" info 2>/dev/null || echo "(no \`bistable info\` in this build)")"
done
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
"$NEW" identify --make-synthetic "$TMP/syn" > /dev/null
SYN="--data $TMP/syn/chirp_6mm.csv --data $TMP/syn/chirp_10mm.csv --data $TMP/syn/chirp_14mm.csv --known m_main=0.282"
SB="$DATA/silverbox/silverbox_SNLS80mV.csv"
HV="$DATA/bistable-harvester"
HARV="--input-kind base_acceleration --input-scale 9.81 --output-kind velocity --output-scale 0.1 --columns input=base_acc_g,output=laser_V --known m_main=1"
args_of() {
  case "$1" in
    syn_c2) echo "$SYN --terms main.linear,main.viscous,main.friction" ;;
    syn_friction) echo "$SYN --terms main.linear,main.viscous,main.damping_y2" ;;
    syn_null) echo "$SYN --terms main.linear,main.viscous,main.damping_y2,main.friction" ;;
    silverbox) echo "--data $SB --input-kind force --output-kind analogue --columns input=u,output=y --terms main.linear,main.viscous \
--candidates main.stiffness_y2,main.stiffness_y3,main.stiffness_y5,main.damping_y2,main.damping_v3,main.drag,main.bias \
--range 40650:105712 --test-range 105712:127400 --test-range 100:40575 --test-range 100:32100" ;;
    harvester_inter) echo "--data $HV/bistable_sym_interwell_6p5Hz.csv $HARV --terms main.linear,main.stiffness_y3,main.viscous \
--candidates main.stiffness_y2,main.stiffness_y5,main.damping_y2,main.damping_v3,main.drag,main.bias --objective fft --max-seconds 8 --decimate 4" ;;
    harvester_intra) echo "--data $HV/bistable_sym_intrawell_left_6p5Hz.csv --data $HV/bistable_sym_intrawell_right_6p5Hz.csv $HARV \
--terms main.linear,main.stiffness_y3,main.viscous --candidates main.stiffness_y2,main.stiffness_y5,main.damping_y2,main.damping_v3,main.drag,main.bias \
--max-seconds 4 --decimate 4 --fit-offsets" ;;
    *) echo "error: unknown loop '$1' (syn_c2, syn_friction, syn_null, silverbox, harvester_inter, harvester_intra)" >&2; exit 2 ;;
  esac
}
summary() {  # JSON → "error a -> b, added [...]" (the error the loop minimised: spectral for --objective fft)
  /usr/bin/python3 -c "import json, sys; d = json.load(open(sys.argv[1]))
k = {'fft': 'fft_error_', 'shooting': 'shooting_error_'}.get(d.get('objective'), 'error_')
g = lambda v: 'null' if v is None else '%.4g' % v
print('%serror %s -> %s %%, added %s' % (k[:-6].replace('_', ' '), g(d.get(k + 'before')), g(d.get(k + 'after')), [e['term'] for e in d['effects_added']]))" "$1"
}
same() {  # two JSON outputs → "same" (but for wall times, the "seconds" keys) | "same*" (and for keys only one
  # build writes: a newer build's new keys) | "differ"
  /usr/bin/python3 -c "import json, sys
def strip(x, other):
    if isinstance(x, dict) and isinstance(other, dict):
        return {k: strip(v, other[k]) for k, v in x.items() if k != 'seconds' and k in other}
    if isinstance(x, list) and isinstance(other, list) and len(x) == len(other):
        return [strip(v, o) for v, o in zip(x, other)]
    return x
def keys(x):
    if isinstance(x, dict): return {k for k in x if k != 'seconds'} | {k + '.' + s for k, v in x.items() for s in keys(v)}
    if isinstance(x, list): return set().union(*[keys(v) for v in x]) if x else set()
    return set()
a, b = (json.load(open(f)) for f in sys.argv[1:3])
if strip(a, b) != strip(b, a): print('differ')
else: print('same' if keys(a) == keys(b) else 'same*')" "$1" "$2"
}
run() {  # binary args out → wall seconds
  local t0 t1
  t0=$(date +%s.%N)
  # shellcheck disable=SC2086
  "$1" identify $2 --json > "$3" || { echo "error: $1 identify failed (exit $?) on: $2" >&2; return 1; }
  t1=$(date +%s.%N)
  echo "$t0 $t1" | awk '{printf "%.2f", $2 - $1}'
}
printf '%-16s %9s %9s %7s %6s  %s\n' loop old_s new_s ratio json "result (old | new)"
IFS=, read -ra L <<< "$LOOPS"
for loop in "${L[@]}"; do
  a=$(args_of "$loop")
  case "$loop" in
    silverbox) [ -f "$SB" ] || { echo "$loop: skipped ($SB missing)"; continue; } ;;
    harvester_*) [ -d "$HV" ] || { echo "$loop: skipped ($HV missing)"; continue; } ;;
  esac
  to=$(run "$OLD" "$a" "$TMP/old.json")
  tn=$(run "$NEW" "$a" "$TMP/new.json")
  printf '%-16s %9s %9s %7s %6s  %s | %s\n' "$loop" "$to" "$tn" "$(awk -v a="$to" -v b="$tn" 'BEGIN{printf "%.2f", a / b}')" \
    "$(same "$TMP/old.json" "$TMP/new.json")" \
    "$(summary "$TMP/old.json")" "$(summary "$TMP/new.json")"
done
