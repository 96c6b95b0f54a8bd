#!/usr/bin/env bash
# A real Slurm cluster on this one machine, and deploy/slurm/bistable.sbatch run on it UNCHANGED.
#   deploy/slurm/test-cluster.sh [--quick] [--build DIR] [--keep]
# A controller (ctl) and three compute nodes (node1..node3), each its own network namespace with its
# own hostname (UTS namespace), /etc/hosts and munged (one shared key: real munge authentication),
# joined by veth pairs on a bridge (10.79.0.0/24). slurmctld and slurmd use proctrack/linuxproc and
# task/none (no cgroups); slurm.conf, state, spool, logs and munge live under one temp dir. The
# namespaces share the host's filesystem, so the repository and the temp dir are the cluster's
# shared filesystem. Then it submits the sweep deploy/slurm/test-spec.toml with sbatch and checks:
#   - the map the cluster wrote equals the embedded `bistable run` of the same spec bit for bit
#     (deploy/compare-maps.py: every dataset's shape, dtype and bytes, every attribute);
#   - items per node (the job's `bistable workers` table; worker names are host:pid);
#   - the secrets directory is private (0700) on the shared path during the job and gone after it;
#   - a worker without a token, and one with a client token, are refused, saying why; a worker
#     dialing the head node by a name its certificate lacks (node1-alias) is refused, saying why;
#   - a node lost mid-sweep (kill -9 of every process in node3's namespace: munged, slurmd,
#     slurmstepd, worker): the sweep finishes, the acknowledged count never drops, the map is the
#     embedded one;
#   full mode also: a clean 3-node run first, an admin downing node2 mid-sweep
#   (scontrol update state=down), and a 1-node allocation (coordinator and worker on one node,
#   --overlap).
#   - the job-array path (deploy/slurm/array.sbatch, issue 43): 3 array tasks (`bistable run --shard I/3`),
#     a merge job after them, the merged map equal to the embedded one, a task rerun alone resuming;
# --quick (CI): the node-loss run with the refusals, map equality and items per node, and the array run.
# Prints a table (PASS/FAIL per check, with figures); exit 0 only when every row passes; 77 (with a
# one-line reason) when this machine cannot run it (not root, no network namespaces, no Slurm/munge).
# Everything it starts is torn down on exit (trap): processes, namespaces, bridge, temp dir (--keep
# keeps the temp dir: logs, job outputs, maps).
set -euo pipefail

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
SELF=$HERE/$(basename "${BASH_SOURCE[0]}")
REPO=$(cd "$HERE/../.." && pwd)
MARKER=.bistable-slurm-test

# Internal: run a command as cluster node NODE (called inside the node's network namespace, after
# `unshare --uts --mount`): its hostname, its /etc/hosts and its munged socket, then exec.
if [ "${1:-}" = --in-node ]; then
  node=${2:-} root=${3:-}
  shift 3
  [[ $node =~ ^(ctl|node[0-9])$ ]] || { echo "test-cluster.sh: bad node '$node'" >&2; exit 2; }
  [ -f "$root/$MARKER" ] || { echo "test-cluster.sh: $root is not a test cluster" >&2; exit 2; }
  hostname "$node"
  mount --bind "$root/etc/hosts" /etc/hosts
  mount --bind "$root/munge/$node" "$root/munge/sock"
  export SLURM_CONF=$root/etc/slurm.conf
  exec "$@"
fi

usage() { sed -n '2,/^set -euo/p' "$SELF" | sed '$d; s/^# \{0,1\}//'; }
QUICK=0 KEEP=0 BUILD=$REPO/build
while [ "$#" -gt 0 ]; do
  case $1 in
    --quick) QUICK=1 ;;
    --keep) KEEP=1 ;;
    --build) [ "$#" -ge 2 ] || { usage >&2; exit 2; }; BUILD=$2; shift ;;
    --build=*) BUILD=${1#--build=} ;;
    -h | --help) usage; exit 0 ;;
    *) echo "test-cluster.sh: unknown argument '$1'" >&2; usage >&2; exit 2 ;;
  esac
  shift
done
BUILD=$(cd "$BUILD" 2>/dev/null && pwd) || { echo "test-cluster.sh: no build directory $BUILD" >&2; exit 1; }
CLI=$BUILD/client/bistable WORKER=$BUILD/worker/bistable-worker COORDINATOR=$BUILD/server/bistable-coordinator
SPEC=$HERE/test-spec.toml
PY=/usr/bin/python3

skip() { echo "SKIP: $*"; exit 77; }
[ "$(id -u)" -eq 0 ] || skip "needs root (network namespaces, hostnames, mounts)"
for tool in slurmctld slurmd sbatch squeue scontrol sinfo scancel srun munged munge unmunge ip unshare openssl timeout; do
  command -v "$tool" > /dev/null || skip "$tool is not installed (apt-get install slurmctld slurmd slurm-client munge)"
done
"$PY" -c 'import h5py, numpy' 2> /dev/null || skip "$PY lacks h5py/numpy (apt-get install python3-h5py python3-numpy)"
for b in "$CLI" "$WORKER" "$COORDINATOR"; do
  [ -x "$b" ] || { echo "test-cluster.sh: no $b (build the project first)" >&2; exit 1; }
done
while read -r v; do unset "$v"; done < <(compgen -e | grep '^BISTABLE_' || true)

# ---------------------------------------------------------------------------------------------
# The cluster
SFX=$(($$ % 100000))
BR=bslbr$SFX
NODES=(ctl node1 node2 node3)
declare -A ADDR=([ctl]=10.79.0.1 [node1]=10.79.0.11 [node2]=10.79.0.12 [node3]=10.79.0.13)
ns_of() { printf 'bsl%s-%s' "$SFX" "$1"; }
T=""
NS_MADE=()
BR_MADE=0
PRE_PIDS=$(pgrep -d ' ' -x 'slurmctld|slurmd|slurmstepd|munged|srun|sbatch|bistable|bistable-coordi|bistable-worker' || true)
TORN_DOWN=0

# on NODE CMD...: run CMD as that node.
on() {
  local node=$1
  shift
  ip netns exec "$(ns_of "$node")" unshare --uts --mount --propagation private -- "$SELF" --in-node "$node" "$T" "$@"
}

teardown() {
  [ "$TORN_DOWN" = 0 ] || return 0
  TORN_DOWN=1
  set +e
  local ns pids all="" i
  for ns in "${NS_MADE[@]}"; do
    pids=$(ip netns pids "$ns" 2> /dev/null | tr '\n' ' ')
    all+=" $pids"
    [ -n "${pids// /}" ] && kill -TERM $pids 2> /dev/null
  done
  for i in $(seq 50); do
    pids=""
    for ns in "${NS_MADE[@]}"; do pids+=$(ip netns pids "$ns" 2> /dev/null | tr '\n' ' '); done
    [ -z "${pids// /}" ] && break
    [ "$i" -eq 20 ] && kill -KILL $pids 2> /dev/null
    sleep 0.2
  done
  for ns in "${NS_MADE[@]}"; do ip netns del "$ns" 2> /dev/null; done
  [ "$BR_MADE" = 1 ] && ip link del "$BR" 2> /dev/null
  # Killed processes may be zombies for a moment (no longer in any namespace listing).
  LEFT_PIDS=""
  for i in $(seq 25); do
    LEFT_PIDS=""
    for p in $(tr ' ' '\n' <<<"$all" | sort -un); do
      case $(ps -o stat= -p "$p" 2> /dev/null) in "" | Z*) ;; *) LEFT_PIDS+=" $p" ;; esac
    done
    [ -z "$LEFT_PIDS" ] && break
    sleep 0.2
  done
  if [ -n "$T" ] && [ -f "$T/$MARKER" ]; then
    if [ "$KEEP" = 1 ]; then echo "test-cluster.sh: kept $T"; else rm -rf -- "$T"; fi
  fi
  set -e
}
on_exit() {
  local rc=$?
  teardown
  exit "$rc"
}
trap on_exit EXIT
trap 'exit 143' TERM
trap 'exit 130' INT

log() { printf '[%4ds] %s\n' "$SECONDS" "$*"; }
ROWS=()
row() { ROWS+=("$1"$'\t'"$2"$'\t'"$3"); log "$2  $1: $3"; }

T=$(mktemp -d /tmp/bistable-slurm.XXXXXX)
chmod 755 "$T"
touch "$T/$MARKER"
mkdir -p "$T/etc" "$T/munge/sock" "$T/state" "$T/spool" "$T/run" "$T/log" "$T/runs"
for n in "${NODES[@]}"; do mkdir -p "$T/munge/$n" "$T/spool/$n"; chmod 755 "$T/munge/$n"; done

# Namespaces and the bridge (exit 77 when this kernel or container cannot make them).
ip netns add "$(ns_of ctl)" 2> /dev/null || skip "ip netns add failed (no network namespaces here)"
NS_MADE+=("$(ns_of ctl)")
for n in node1 node2 node3; do ip netns add "$(ns_of "$n")"; NS_MADE+=("$(ns_of "$n")"); done
ip link add "$BR" type bridge 2> /dev/null || skip "cannot create a bridge here"
BR_MADE=1
ip link set "$BR" up
i=0
for n in "${NODES[@]}"; do
  i=$((i + 1))
  ip link add "bsv$SFX-$i" type veth peer name eth0 netns "$(ns_of "$n")" 2> /dev/null || skip "cannot create veth pairs here"
  ip link set "bsv$SFX-$i" master "$BR" up
  ip -n "$(ns_of "$n")" addr add "${ADDR[$n]}/24" dev eth0
  ip -n "$(ns_of "$n")" link set eth0 up
  ip -n "$(ns_of "$n")" link set lo up
done
{
  echo "127.0.0.1 localhost"
  for n in "${NODES[@]}"; do echo "${ADDR[$n]} $n"; done
  echo "${ADDR[node1]} node1-alias"  # resolves, but is not in the coordinator's certificate
} > "$T/etc/hosts"
on node1 hostname > /dev/null || skip "cannot enter a node (unshare --uts --mount inside ip netns exec failed)"

# Munge: one key, one munged per node (its socket bind-mounted at the path slurm.conf names).
if command -v mungekey > /dev/null; then
  mungekey --create --keyfile="$T/munge/munge.key" 2> /dev/null
else
  dd if=/dev/urandom of="$T/munge/munge.key" bs=1024 count=1 status=none
fi
chmod 600 "$T/munge/munge.key"
for n in "${NODES[@]}"; do
  on "$n" munged --force --socket="$T/munge/sock/munge.socket" --key-file="$T/munge/munge.key" \
    --pid-file="$T/munge/$n/munged.pid" --log-file="$T/log/munged-$n.log" --seed-file="$T/munge/$n/munged.seed" ||
    { echo "munged failed on $n:"; cat "$T/log/munged-$n.log"; exit 1; }
done
start_munged() {
  on "$1" munged --force --socket="$T/munge/sock/munge.socket" --key-file="$T/munge/munge.key" \
    --pid-file="$T/munge/$1/munged.pid" --log-file="$T/log/munged-$1.log" --seed-file="$T/munge/$1/munged.seed"
}
cred=$(on node2 munge -n --socket="$T/munge/sock/munge.socket")
munge_check=$(on node3 unmunge --socket="$T/munge/sock/munge.socket" <<<"$cred" | sed -n 's/^ENCODE_HOST: *//p')

# Slurm.
CPUS=$(nproc)
cat > "$T/etc/slurm.conf" <<EOF
# Generated by deploy/slurm/test-cluster.sh
ClusterName=bsltest$SFX
SlurmctldHost=ctl(${ADDR[ctl]})
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$T/munge/sock/munge.socket
StateSaveLocation=$T/state
SlurmdSpoolDir=$T/spool/%n
SlurmctldPidFile=$T/run/slurmctld.pid
SlurmdPidFile=$T/run/slurmd-%n.pid
SlurmctldLogFile=$T/log/slurmctld.log
SlurmdLogFile=$T/log/slurmd-%n.log
SlurmctldDebug=info
SlurmdDebug=info
PlugStackConfig=$T/etc/plugstack.conf
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=none
MailProg=/bin/true
ReturnToService=1
SlurmdTimeout=10
SlurmctldTimeout=30
MessageTimeout=10
InactiveLimit=0
KillWait=5
MinJobAge=3600
EOF
for n in node1 node2 node3; do
  echo "NodeName=$n NodeHostname=$n NodeAddr=${ADDR[$n]} CPUs=$CPUS State=UNKNOWN" >> "$T/etc/slurm.conf"
done
echo "PartitionName=sweep Nodes=node1,node2,node3 Default=YES MaxTime=INFINITE State=UP" >> "$T/etc/slurm.conf"
: > "$T/etc/plugstack.conf"
# slurmd 22.05 loads a cgroup plugin even with proctrack/linuxproc and task/none; autodetect fails
# inside `ip netns exec` (it mounts a fresh /sys, without /sys/fs/cgroup). Name v1: nothing uses it.
printf 'CgroupPlugin=cgroup/v1\nCgroupAutomount=no\n' > "$T/etc/cgroup.conf"

on ctl slurmctld || { echo "slurmctld failed:"; tail -n 20 "$T/log/slurmctld.log"; exit 1; }
start_slurmd() { on "$1" slurmd -N "$1"; }
for n in node1 node2 node3; do start_slurmd "$n" || { echo "slurmd failed on $n:"; tail -n 20 "$T/log/slurmd-$n.log"; exit 1; }; done

# wait_idle NODE...: until sinfo shows each idle (60 s).
wait_idle() {
  local end=$((SECONDS + 60)) n s ok
  while :; do
    ok=1
    for n in "$@"; do
      s=$(on ctl sinfo -h -n "$n" -o %t 2> /dev/null || true)
      [ "$s" = idle ] || ok=0
    done
    [ "$ok" = 1 ] && return 0
    [ "$SECONDS" -lt "$end" ] || { on ctl sinfo -N -l || true; return 1; }
    sleep 0.5
  done
}
wait_idle node1 node2 node3 || { echo "the nodes did not come up:"; tail -n 20 "$T/log/slurmctld.log"; exit 1; }
hosts_seen=$(for n in "${NODES[@]}"; do on "$n" hostname; done | tr '\n' ' ')
row "cluster: ctl + node1..3, own netns/hostname/munged" PASS \
  "hostnames ${hosts_seen% }; munge cred from node2 decoded on node3 (ENCODE_HOST ${munge_check:-?}); sinfo: 3 nodes idle, $CPUS CPUs each; Slurm $(slurmctld -V | awk '{print $2}')"

# ---------------------------------------------------------------------------------------------
# The embedded reference map (on the host, before any run competes for the cores).
log "embedded reference: bistable run $(basename "$SPEC")"
t0=$SECONDS
"$CLI" run "$SPEC" --data "$T/embedded" --no-plots --quiet --json > "$T/embedded.json"
EMBEDDED=$T/embedded/sweeps/$("$PY" -c 'import json,sys; print(json.load(open(sys.argv[1]))["id"])' "$T/embedded.json").h5
[ -f "$EMBEDDED" ] || { echo "test-cluster.sh: the embedded run wrote no $EMBEDDED" >&2; exit 1; }
ITEMS=$("$PY" -c 'import json,sys; print(json.load(open(sys.argv[1]))["items"])' "$T/embedded.json")
log "embedded: $ITEMS items in $((SECONDS - t0)) s"

# ---------------------------------------------------------------------------------------------
# One sbatch run: run_job NAME NNODES PORT ACTION REFUSALS
#   ACTION: none | kill9:NODE (every process in NODE's namespace) | down:NODE (scontrol)
REFUSALS_DONE=0
CERT_ROW=0
run_job() {
  local name=$1 nnodes=$2 port=$3 action=$4 refusals=$5
  local run=$T/runs/$name job out sec sweep="" st wk acted=0 act_at="" act_t=0 down_t="" perm="" t0 limit=420 state
  local victim=${action#*:} kind=${action%%:*}
  mkdir -p "$run"
  t0=$SECONDS
  # From the run directory: the job's default secrets path is under $SLURM_SUBMIT_DIR.
  job=$(cd "$run" && on ctl env BISTABLE_SRC="$REPO" BISTABLE_BIN="$BUILD" BISTABLE_DATA="$run/data" BISTABLE_PORT="$port" \
    BISTABLE_LEASE_SECONDS=3 BISTABLE_JOB_SECONDS=0.5 BISTABLE_STOP_SECONDS=20 \
    sbatch --parsable --exclusive --nodes="$nnodes" --chdir="$run" --output="$run/job-%j.out" --job-name="bsl-$name" \
    "$REPO/deploy/slurm/bistable.sbatch" "$SPEC")
  job=${job%%;*}
  out=$run/job-$job.out
  sec=$run/.bistable-secrets-$job
  log "$name: job $job on $nnodes node(s), action $action"
  : > "$run/progress.log"
  while :; do
    state=$(on ctl squeue -h -j "$job" -o %T 2> /dev/null || true)
    [ -n "$state" ] || break
    if [ -z "$sweep" ] && [ -f "$out" ]; then
      sweep=$(sed -n 's/^bistable\.sbatch: sweep \([0-9a-f]*\) submitted$/\1/p; T; q' "$out")
    fi
    if [ -n "$sweep" ] && [ -r "$sec/client.token" ]; then
      if [ -z "$perm" ]; then
        perm=$(stat -c '%a %U' "$sec" 2> /dev/null || true)
        cp "$sec/tls/server.pem" "$run/server.pem" 2> /dev/null || true  # the public certificate
      fi
      if st=$(on ctl "$CLI" status "$sweep" --json --coordinator "node1:$port" --tls-ca "$sec/tls/ca.pem" \
        --token-file "$sec/client.token" 2> /dev/null); then
        printf '%s %s\n' "$SECONDS" "$st" >> "$run/progress.log"
      fi
      if wk=$(on ctl "$CLI" workers --json --coordinator "node1:$port" --tls-ca "$sec/tls/ca.pem" \
        --token-file "$sec/client.token" 2> /dev/null); then
        printf '%s\n' "$wk" > "$run/workers.json"
        cat "$run/workers.json" >> "$run/workers-all.json"
      fi
      if [ "$refusals" = 1 ] && [ "$REFUSALS_DONE" = 0 ]; then
        refusal_checks "$port" "$sec" "$run"
        REFUSALS_DONE=1
      fi
      if [ "$kind" != none ] && [ "$acted" = 0 ] && [ -n "${st:-}" ]; then
        local done_n total busy
        done_n=$(sed -n 's/.*"items_done":\([0-9]*\).*/\1/p' <<<"$st")
        total=$(sed -n 's/.*"items_total":\([0-9]*\).*/\1/p' <<<"$st")
        busy=$("$PY" -c 'import json,sys; print(sum(w["items_done"] for w in json.load(open(sys.argv[1])) if w["name"].startswith(sys.argv[2] + ":")))' \
          "$run/workers.json" "$victim" 2> /dev/null || echo 0)
        if [ -n "$done_n" ] && [ -n "$total" ] && [ "$total" -gt 0 ] && [ $((done_n * 100)) -ge $((total * 20)) ] && [ "$busy" -gt 0 ]; then
          act_at="$done_n/$total items acknowledged, $victim's worker had $busy"
          act_t=$SECONDS
          if [ "$kind" = kill9 ]; then
            local pids comms
            pids=$(ip netns pids "$(ns_of "$victim")" | paste -sd, -)
            comms=$(ps -o comm= -p "$pids" 2> /dev/null | sort | uniq -c | awk '{printf "%s%s x%s", (NR > 1 ? ", " : ""), $2, $1}' || true)
            log "$name: kill -9 every process of $victim: $comms"
            act_at+=" (killed: $comms)"
            # shellcheck disable=SC2086
            kill -KILL ${pids//,/ } 2> /dev/null || true
          else
            log "$name: scontrol update nodename=$victim state=down"
            on ctl scontrol update nodename="$victim" state=down reason=bistable-test
            [[ $(on ctl scontrol show node "$victim" 2> /dev/null) == *State=DOWN* ]] && down_t=$SECONDS
          fi
          acted=1
        fi
      fi
    fi
    if [ "$acted" = 1 ] && [ -z "$down_t" ]; then
      [[ $(on ctl scontrol show node "$victim" 2> /dev/null) == *State=DOWN* ]] && down_t=$SECONDS
    fi
    if [ $((SECONDS - t0)) -ge "$limit" ]; then
      log "$name: still running after ${limit}s: scancel"
      on ctl scancel "$job" || true
      sleep 5
      break
    fi
    sleep 0.5
  done
  local wall=$((SECONDS - t0)) info jstate jexit map
  info=$(on ctl scontrol show job -o "$job" 2> /dev/null || true)
  jstate=$(grep -o 'JobState=[A-Z_]*' <<<"$info" | cut -d= -f2)
  jexit=$(grep -o ' ExitCode=[0-9:]*' <<<"$info" | cut -d= -f2)
  map=$(sed -n 's/^bistable\.sbatch: sweep [0-9a-f]* done; map: //p' "$out" 2> /dev/null | tail -n 1)
  if [ "$jstate" = COMPLETED ] && [ "$jexit" = 0:0 ] && [ -n "$map" ]; then
    row "$name: sbatch --nodes=$nnodes, job ends" PASS "job $job COMPLETED 0:0 in ${wall}s; sweep $sweep; map $map"
  else
    row "$name: sbatch --nodes=$nnodes, job ends" FAIL "job $job ${jstate:-?} ${jexit:-?} after ${wall}s; see $out: $(tail -n 2 "$out" 2> /dev/null | tr '\n' ' ')"
  fi
  local cmp rc=0
  if [ -n "$map" ] && [ -f "$map" ]; then
    cmp=$("$PY" "$HERE/../compare-maps.py" "$map" "$EMBEDDED" 2>&1) || rc=1
  else
    cmp="no map" rc=1
  fi
  row "$name: map == embedded bistable run" "$([ "$rc" = 0 ] && echo PASS || echo FAIL)" "$cmp"
  # Items per node, from the workers table the job printed after the sweep ended.
  local per
  per=$("$PY" - "$out" "$ITEMS" <<'PY'
import re, sys
rows, seen = [], False
for line in open(sys.argv[1], errors="replace"):
    if re.match(r"^worker\s+leases\s+items", line):
        seen, rows = True, []
        continue
    m = re.match(r"^(\S+):(\d+)\s+(\d+)\s+(\d+)\s", line) if seen else None
    if m:
        rows.append((m.group(1), m.group(2), int(m.group(4))))
    elif seen and rows:
        seen = False
if not rows:
    print("FAIL\tno workers table in the job output"); sys.exit()
total = sum(r[2] for r in rows)
per = {}
for host, pid, items in rows:
    per.setdefault(host, []).append(f"{items} (pid {pid})")
text = "; ".join(f"{h}: {', '.join(v)}" for h, v in sorted(per.items()))
print(f"{'PASS' if total == int(sys.argv[2]) else 'FAIL'}\t{text}; sum {total} of {sys.argv[2]}")
PY
)
  local head
  head=$(sed -n 's/^bistable\.sbatch: job [0-9]*: coordinator on \([^ ]*\) .*/\1/p; T; q' "$out" 2> /dev/null || true)
  row "$name: items per node (workers host:pid)" "${per%%$'\t'*}" "${per#*$'\t'}; coordinator on ${head:-?}"
  if [ "$CERT_ROW" = 0 ]; then
    # The coordinator's certificate names the head node by DNS name and address; workers dial the name.
    local sans dial
    sans=$(openssl x509 -in "$run/server.pem" -noout -ext subjectAltName 2> /dev/null | tail -n +2 | sed 's/^ *//')
    dial=$(sed -n 's/^bistable\.sbatch: coordinator up at //p; T; q' "$out" 2> /dev/null || true)
    if [[ $sans == *"DNS:${dial%:*}"* && $sans == *"IP Address:${ADDR[node1]}"* && ${dial%:*} == node1 ]]; then
      row "TLS: certificate names the head by DNS name and IP" PASS "SANs: $sans; workers and clients dial $dial"
    else
      row "TLS: certificate names the head by DNS name and IP" FAIL "SANs: ${sans:-none}; dial: ${dial:-?}"
    fi
    CERT_ROW=1
  fi
  if [ -n "$perm" ] && [ ! -e "$sec" ]; then
    row "$name: secrets on the shared path, private, removed" PASS "$sec was '$perm' during the job, gone after it"
  else
    row "$name: secrets on the shared path, private, removed" FAIL "mode/owner '${perm:-never seen}', exists after: $([ -e "$sec" ] && echo yes || echo no)"
  fi
  if [ "$kind" != none ]; then
    local mono
    # The coordinator's acknowledged count over the run (polled every ~0.5 s) never drops and reaches
    # the total; the job says the sweep is done (its last poll may precede the "done" state).
    local persum
    persum=$(sed -n 's/.*; sum \([0-9]*\) of .*/\1/p' <<<"$per")
    mono=$("$PY" - "$run/progress.log" "$([ -n "$map" ] && echo "done" || echo not-done)" "$act_t" "${persum:-0}" <<'PY'
import json, sys
seq = []
for line in open(sys.argv[1]):
    t, js = line.split(" ", 1)
    s = json.loads(js)
    seq.append((int(t), s["items_done"], s["items_total"], s["state"]))
if not seq:
    print("FAIL\tno status polls\t"); sys.exit()
drops = [(a[1], b[1]) for a, b in zip(seq, seq[1:]) if b[1] < a[1]]
last = seq[-1]
full = [t for t, d, n, _ in seq if d == n]
final = int(sys.argv[4])
ok = not drops and final == last[2] and sys.argv[2] == "done"
after = f"{full[0] - int(sys.argv[3])}s later" if full else "after the last poll"
print(f"{'PASS' if ok else 'FAIL'}\t{len(seq)} status polls: acknowledged items never dropped"
      f"{'' if not drops else ' (DROPS: ' + str(drops[:3]) + ')'}; last poll {last[1]}/{last[2]} {last[3]};"
      f" at the end (job's workers table) {final}/{last[2]}, sweep {sys.argv[2]}\t{after}")
PY
)
    if [ "$acted" = 1 ]; then
      local what
      if [ "$kind" = kill9 ]; then what="kill -9 of all $victim's processes"; else what="scontrol down $victim"; fi
      row "$name: $what mid-sweep" "$([ "$jstate" = COMPLETED ] && [ "$rc" = 0 ] && echo PASS || echo FAIL)" \
        "at $act_at; all items acknowledged ${mono##*$'\t'} (lease 3 s), job ended $((wall - (act_t - t0)))s later$([ -n "$down_t" ] && echo "; Slurm marked $victim DOWN after $((down_t - act_t))s, job kept running (--no-kill)")"
      local rest=${mono#*$'\t'}
      row "$name: nothing acknowledged lost" "${mono%%$'\t'*}" "${rest%$'\t'*}"
    else
      row "$name: $action mid-sweep" FAIL "the trigger (20% done, $victim's worker busy) never came"
    fi
  fi
}

# refusal_checks PORT SECRETS RUN: rogue workers from the login node (ctl) against the running coordinator.
refusal_checks() {
  local port=$1 sec=$2 run=$3 rc msg
  rc=0
  msg=$(on ctl env -u BISTABLE_TOKEN timeout 20 "$WORKER" --coordinator "node1:$port" --tls-ca "$sec/tls/ca.pem" \
    --threads 1 --name rogue-notoken 2>&1) || rc=$?
  if [ "$rc" -ne 0 ] && [ "$rc" -ne 124 ] && grep -qi unauthenticated <<<"$msg"; then
    row "worker without a token refused" PASS "exit $rc: $(grep -i -m1 unauthenticated <<<"$msg")"
  else
    row "worker without a token refused" FAIL "exit $rc: $msg"
  fi
  rc=0
  msg=$(on ctl env -u BISTABLE_TOKEN timeout 20 "$WORKER" --coordinator "node1:$port" --tls-ca "$sec/tls/ca.pem" \
    --token-file "$sec/client.token" --threads 1 --name rogue-clienttoken 2>&1) || rc=$?
  if [ "$rc" -ne 0 ] && [ "$rc" -ne 124 ] && grep -qi 'permission denied' <<<"$msg"; then
    row "worker with a client token refused" PASS "exit $rc: $(grep -i -m1 'permission denied' <<<"$msg")"
  else
    row "worker with a client token refused" FAIL "exit $rc: $msg"
  fi
  # A valid worker token, but dialing node1-alias (resolves to node1; not in the certificate). The
  # worker keeps retrying a coordinator it cannot verify (it waits for coordinators to come up),
  # logging why; SIGTERM after 4 s.
  rc=0
  msg=$(on ctl env -u BISTABLE_TOKEN timeout --preserve-status -s TERM 4 "$WORKER" --coordinator "node1-alias:$port" \
    --tls-ca "$sec/tls/ca.pem" --token-file "$sec/worker.token" --threads 1 --name rogue-badname 2>&1) || rc=$?
  printf '%s\n' "$msg" > "$run/rogue-badname.log"
  local why stopped client_msg
  why=$(grep -o -m1 'Peer name [^ ]* is not in peer certificate' <<<"$msg" || true)
  stopped=$(grep -o -m1 -E 'stopped after [0-9]+ items|stopped .*items=[0-9]+' <<<"$msg" || true)
  client_msg=$(on ctl "$CLI" workers --coordinator "node1-alias:$port" --tls-ca "$sec/tls/ca.pem" \
    --token-file "$sec/client.token" 2>&1 || true)
  # (Whether it computed nothing is the "rogue workers never registered" row.)
  if [ -n "$why" ] && ! [[ $stopped =~ [1-9][0-9]*( items|$) ]] && grep -q 'not in peer certificate' <<<"$client_msg"; then
    row "worker dialing a name not in the certificate refused" PASS \
      "worker log: '$why'${stopped:+, $stopped}, exit $rc after SIGTERM at 4 s; client: '$(grep -o 'cannot reach [^(]*([^)]*' <<<"$client_msg" | head -n 1))'"
  else
    row "worker dialing a name not in the certificate refused" FAIL "worker rc $rc: ${why:-no reason}; ${stopped:-?}; client: $client_msg"
  fi
}

# ---------------------------------------------------------------------------------------------
# The job-array path (issue 43): deploy/slurm/array.sbatch as an array of N shards, the merge as a job
# depending on it, then one task rerun alone (it resumes: everything reused).  run_array NAME N
# wait_jobs JOB...: until squeue lists none of them (420 s).
wait_jobs() {
  local end=$((SECONDS + 420))
  while [ -n "$(on ctl squeue -h -j "$(IFS=,; echo "$*")" -o %i 2> /dev/null || true)" ]; do
    [ "$SECONDS" -lt "$end" ] || { on ctl scancel "$@" || true; sleep 5; return 1; }
    sleep 0.5
  done
}
run_array() {
  local name=$1 n=$2 run=$T/runs/$1 arr mid rerun t0 states bad map cmp rc=0 nodes
  mkdir -p "$run"
  t0=$SECONDS
  arr=$(on ctl env BISTABLE_BIN="$BUILD" BISTABLE_DATA="$run/data" \
    sbatch --parsable --array=0-$((n - 1)) --chdir="$run" --output="$run/array-%A_%a.out" --job-name="bsl-$name" \
    "$REPO/deploy/slurm/array.sbatch" "$SPEC")
  arr=${arr%%;*}
  mid=$(on ctl env BISTABLE_BIN="$BUILD" BISTABLE_DATA="$run/data" \
    sbatch --parsable --dependency=afterok:"$arr" --chdir="$run" --output="$run/merge-%j.out" --job-name="bsl-$name-merge" \
    "$REPO/deploy/slurm/array.sbatch" --merge "$SPEC")
  mid=${mid%%;*}
  log "$name: array job $arr ($n tasks), merge job $mid after it"
  wait_jobs "$arr" "$mid" || log "$name: still running after 420 s: cancelled"
  # Every task and the merge COMPLETED 0:0 (MinJobAge keeps their records).
  states=$(on ctl scontrol show job -o "$arr" 2> /dev/null | grep -o 'JobState=[A-Z_]* .* ExitCode=[0-9:]*' |
    sed 's/JobState=\([A-Z_]*\) .* ExitCode=\([0-9:]*\)/\1 \2/' | sort | uniq -c | sed 's/^ *//' | paste -sd, -)
  bad=$(on ctl scontrol show job -o "$arr" "$mid" 2> /dev/null | grep -vc 'JobState=COMPLETED .* ExitCode=0:0' || true)
  nodes=$(grep -ho 'on [a-z0-9]*: shard [0-9]*/[0-9]*' "$run"/array-*.out 2> /dev/null | awk '{print $4 " on " $2}' | sort | sed 's/:$//' | paste -sd, -)
  map=$(sed -n 's/^array\.sbatch: sweep [0-9a-f]* merged; map: //p' "$run"/merge-"$mid".out 2> /dev/null | tail -n 1)
  if [ "$bad" = 0 ] && [ -n "$map" ]; then
    row "$name: sbatch --array=0-$((n - 1)), then --merge, jobs end" PASS \
      "array job $arr: $n tasks (${states:-?}); shards ${nodes:-?}; merge job $mid COMPLETED 0:0; $((SECONDS - t0))s; map $map"
  else
    row "$name: sbatch --array=0-$((n - 1)), then --merge, jobs end" FAIL \
      "array $arr: ${states:-?}; merge $mid: $(tail -n 2 "$run"/merge-"$mid".out 2> /dev/null | tr '\n' ' ')"
  fi
  if [ -n "$map" ] && [ -f "$map" ]; then
    cmp=$("$PY" "$HERE/../compare-maps.py" "$map" "$EMBEDDED" 2>&1) || rc=1
  else
    cmp="no map" rc=1
  fi
  row "$name: merged map == embedded bistable run" "$([ "$rc" = 0 ] && echo PASS || echo FAIL)" "$cmp"
  # One task again, alone (a failed task resubmitted): it resumes from its store and computes nothing.
  rerun=$(on ctl env BISTABLE_BIN="$BUILD" BISTABLE_DATA="$run/data" BISTABLE_SHARDS="$n" \
    sbatch --parsable --array=1 --chdir="$run" --output="$run/rerun-%A_%a.out" --job-name="bsl-$name-rerun" \
    "$REPO/deploy/slurm/array.sbatch" "$SPEC")
  rerun=${rerun%%;*}
  wait_jobs "$rerun" || true
  local said
  said=$(grep -h '^shard 1/' "$run"/rerun-"$rerun"_1.out 2> /dev/null || true)
  if [[ $said =~ \(0\ computed,\ [1-9][0-9]*\ reused ]]; then
    row "$name: a task rerun alone resumes from its store" PASS "BISTABLE_SHARDS=$n sbatch --array=1: '$said'"
  else
    row "$name: a task rerun alone resumes from its store" FAIL "'${said:-no output}' ($run/rerun-${rerun}_1.out)"
  fi
}

PORT=50100
if [ "$QUICK" = 0 ]; then
  run_job clean 3 $((PORT + 1)) none 1
  run_job node-loss 3 $((PORT + 2)) kill9:node3 0
  start_munged node3 && start_slurmd node3
  wait_idle node3 || row "node3 back after the node-loss run" FAIL "not idle"
  run_job admin-down 3 $((PORT + 3)) down:node2 0
  # An admin-downed node stays DOWN (ReturnToService=1) until resumed.
  [ "$(on ctl sinfo -h -n node2 -o %t)" = idle ] || on ctl scontrol update nodename=node2 state=resume || true
  wait_idle node2 || row "node2 back after the admin-down run" FAIL "not idle"
  run_job single-node 1 $((PORT + 4)) none 0
else
  run_job node-loss 3 $((PORT + 2)) kill9:node3 1
fi
run_array array 3
# The rogue workers must never have registered.
if grep -qs rogue- "$T"/runs/*/workers-all.json; then
  row "rogue workers never registered" FAIL "$(grep -ho '"rogue-[a-z]*' "$T"/runs/*/workers-all.json | sort -u | tr '\n' ' ')"
else
  row "rogue workers never registered" PASS "no rogue-* name in any 'bistable workers' poll"
fi

# ---------------------------------------------------------------------------------------------
# Teardown, then check nothing is left.
KEEP_T=$T
teardown
left_ns=$(ip netns list | grep -c "^bsl$SFX-" || true)
left_br=$(ip link show "$BR" > /dev/null 2>&1 && echo 1 || echo 0)
# Any slurm/munge/bistable process of this cluster left anywhere: its command line or environment
# names the temp dir (SLURM_CONF, the munge socket, the secrets). Other tests' processes don't;
# zombies are excepted (this machine's init reaps within seconds).
for i in $(seq 25); do
  new_pids=""
  for p in $(pgrep -x 'slurmctld|slurmd|slurmstepd|munged|srun|sbatch|bistable|bistable-coordi|bistable-worker' || true); do
    [[ " $PRE_PIDS " == *" $p "* ]] && continue
    grep -qaF "$KEEP_T" "/proc/$p/cmdline" "/proc/$p/environ" 2> /dev/null || continue
    case $(ps -o stat= -p "$p" 2> /dev/null) in "" | Z*) ;; *) new_pids+=" $p" ;; esac
  done
  [ -z "$new_pids" ] && break
  sleep 0.2
done
if [ -z "$LEFT_PIDS$new_pids" ] && [ "$left_ns" = 0 ] && [ "$left_br" = 0 ]; then
  row "teardown" PASS "no slurmctld/slurmd/slurmstepd/munged/srun/bistable* process of this cluster, namespace or bridge left$([ "$KEEP" = 1 ] && echo "; kept $KEEP_T")"
else
  row "teardown" FAIL "processes:${LEFT_PIDS}${new_pids} namespaces: $left_ns bridge: $left_br"
fi

fails=0
echo
echo "Slurm test cluster ($([ "$QUICK" = 1 ] && echo quick || echo full)), $(date -u '+%Y-%m-%d %H:%M UTC'), ${SECONDS}s"
printf '%-56s %-5s %s\n' "check" "" "figures"
for r in "${ROWS[@]}"; do
  IFS=$'\t' read -r name verdict figures <<<"$r"
  printf '%-56s %-5s %s\n' "$name" "$verdict" "$figures"
  [ "$verdict" = PASS ] || fails=$((fails + 1))
done
echo "$((${#ROWS[@]} - fails))/${#ROWS[@]} passed"
[ "$fails" -eq 0 ]
