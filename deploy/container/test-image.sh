#!/usr/bin/env bash
# Builds the container image and tests it end to end with podman:
#   deploy/container/test-image.sh [--host-bistable PATH] [--context DIR] [--image NAME] [--base NAME]
#                                  [--spec FILE] [--rootfs-only] [--logs DIR]
#  1. the base image (make-base.sh, kept once built) and the image (podman build, under the shared build lock
#     $BISTABLE_BUILD_LOCK, default /tmp/bistable-build.lock: one heavy build at a time on this machine; do not
#     run this script while holding that lock, or set BISTABLE_BUILD_LOCK= );
#  2. ldd of the three binaries inside the image: no library "not found";
#  3. the image runs as a numeric non-root user that can write /var/lib/bistable; the entrypoint dispatches
#     coordinator / worker / CLI; gnuplot renders an embedded run's plots (read-only root filesystem);
#  4. on a podman network: a coordinator with TLS and tokens (a throwaway CA from tests/make_test_certs.sh,
#     tokens minted by the image's `bistable token`, mounted read-only), two workers (both hardened as in
#     compose.yaml: read-only root, no capabilities, no-new-privileges), a client container submitting
#     deploy/container/test-sweep.toml and watching it finish; both workers must have computed;
#  5. the coordinator's map equals the host's embedded `bistable run SPEC --no-plots` bit for bit, every
#     HDF5 dataset (deploy/compare-maps.py with Debian's /usr/bin/python3 and h5py);
#  6. `podman stop` ends coordinator and workers by SIGTERM (exec'd PID 1), not by SIGKILL.
# Prints a table of the checks; exit 0 if all pass, 1 if one fails, 77 (with a one-line reason) if podman
# cannot run containers here: then it tests the image's root filesystem instead (podman image mount or
# podman export, chroot, ldd, --help of both services), if an image exists. Containers, network and temporary
# files are removed at exit; images stay cached.
#   --host-bistable PATH  the host's CLI for the reference run (default: build/client/bistable)
#   --context DIR         build context (default: this repository); e.g. a `git archive` snapshot
#   --rootfs-only         skip containers: the fallback checks alone (exit 77)
#   --logs DIR            keep the logs (image build, containers, client output) in DIR
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
repo=$(cd "$here/../.." && pwd)
base=${BISTABLE_BASE_IMAGE:-localhost/bistable-base:bookworm}
image=${BISTABLE_IMAGE:-localhost/bistable-sweep:latest}
context=$repo
host_bistable=$repo/build/client/bistable
spec=$here/test-sweep.toml
lock=${BISTABLE_BUILD_LOCK-/tmp/bistable-build.lock}   # set to "" for no lock
rootfs_only=0
logs=""
while [ "$#" -gt 0 ]; do
  case "$1" in
    --host-bistable) host_bistable=${2:?}; shift ;;
    --context) context=$(cd "${2:?}" && pwd); shift ;;
    --image) image=${2:?}; shift ;;
    --base) base=${2:?}; shift ;;
    --spec) spec=${2:?}; shift ;;
    --rootfs-only) rootfs_only=1 ;;
    --logs) logs=${2:?}; shift ;;
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    *) echo "test-image: unknown argument: $1" >&2; exit 2 ;;
  esac
  shift
done
if ! command -v podman >/dev/null; then
  echo "SKIP: podman is not installed (scripts/setup.sh installs it)"
  exit 77
fi
binaries=(/usr/local/bin/bistable /usr/local/bin/bistable-coordinator /usr/local/bin/bistable-worker)

# ---- the table ----------------------------------------------------------------------------------------
names=() results=() seconds=() details=()
record() {  # NAME PASS|FAIL|SKIP SECONDS DETAIL
  names+=("$1"); results+=("$2"); seconds+=("$3"); details+=("$4")
  printf 'test-image: %-24s %-4s %7s s  %s\n' "$1" "$2" "$3" "$4" >&2
}
now() { date +%s.%N; }
since() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.1f", b - a }'; }
print_table() {
  local i
  printf '\n%-24s %-6s %9s  %s\n' "check" "result" "seconds" "detail"
  printf '%-24s %-6s %9s  %s\n' "------------------------" "------" "---------" "------"
  for i in "${!names[@]}"; do
    printf '%-24s %-6s %9s  %s\n' "${names[$i]}" "${results[$i]}" "${seconds[$i]}" "${details[$i]}"
  done
}
failed() {
  local r
  for r in "${results[@]}"; do [ "$r" != FAIL ] || return 0; done
  return 1
}

# ---- cleanup ------------------------------------------------------------------------------------------
tmp=$(mktemp -d /var/tmp/bistable-test-image.XXXXXX)
prefix="bistable-test-$$"
net="$prefix-net"
containers=()
network_made=0
mounted=""
# shellcheck disable=SC2317  # called by the trap
cleanup() {
  local c
  if [ -n "$logs" ]; then
    mkdir -p "$logs"
    cp "$tmp"/*.log "$tmp"/*.json "$logs/" 2>/dev/null || true
    for c in "${containers[@]}"; do podman logs "$c" > "$logs/${c#"$prefix-"}.log" 2>&1 || true; done
  fi
  for c in "${containers[@]}"; do podman rm -f -v -t 0 "$c" >/dev/null 2>&1 || true; done
  if [ "$network_made" -eq 1 ]; then podman network rm "$net" >/dev/null 2>&1 || true; fi
  if [ -n "$mounted" ]; then podman image unmount "$image" >/dev/null 2>&1 || true; fi
  rm -rf --one-file-system "$tmp"
}
trap cleanup EXIT

# Files the container user (uid 10001) reads from read-only mounts.
own() {
  if [ "$(id -u)" -eq 0 ]; then chown "$@"; else podman unshare chown "$@"; fi
}

# ---- 1. base image ------------------------------------------------------------------------------------
t=$(now)
if podman image exists "$base"; then
  record "base image" PASS "$(since "$t")" "cached: $base"
elif "$here/make-base.sh" --tag "$base" > "$tmp/base.log" 2>&1; then
  record "base image" PASS "$(since "$t")" "built: $base ($(tail -n 1 "$tmp/base.log" | sed 's/.*(//; s/)//'))"
else
  record "base image" FAIL "$(since "$t")" "make-base.sh failed: $(tail -n 1 "$tmp/base.log")"
  tail -n 30 "$tmp/base.log" >&2
  print_table; exit 1
fi

# ---- can podman run containers here? ------------------------------------------------------------------
# Some hosts refuse podman's defaults: rlimits above the caller's hard limit (no CAP_SYS_RESOURCE), or crun
# on a cgroup v1/v2 hybrid with a controller on v2. Try the defaults, then ulimits within the hard limits,
# then runc as well; a working fallback is used for the build and every container (CONTAINERS_CONF).
engine_probe() { podman run --rm --network none "$base" true 2>&1; }
t=$(now)
engine_detail="podman defaults"
first_error=""
if ! first_error=$(engine_probe); then
  first_error=$(printf '%s\n' "$first_error" | grep -v '^$' | tail -n 1)
  nofile=$(ulimit -Hn); [ "$nofile" != unlimited ] || nofile=1048576
  engine_ok=0
  later_errors=""
  for runtime in "" runc; do
    if [ -n "$runtime" ] && ! command -v "$runtime" >/dev/null; then continue; fi
    {
      printf '[containers]\ndefault_ulimits = ["nofile=%s:%s", "nproc=4096:4096"]\n' "$nofile" "$nofile"
      if [ -n "$runtime" ]; then printf '[engine]\nruntime = "%s"\n' "$runtime"; fi
    } > "$tmp/containers.conf"
    if CONTAINERS_CONF="$tmp/containers.conf" engine_probe > "$tmp/probe.log" 2>&1; then
      export CONTAINERS_CONF="$tmp/containers.conf"
      engine_detail="ulimits nofile=$nofile nproc=4096${runtime:+, runtime $runtime} (defaults: $first_error${later_errors})"
      engine_ok=1
      break
    fi
    later_errors+="; ulimits${runtime:+ + $runtime}: $(grep -v '^$' "$tmp/probe.log" | tail -n 1)"
  done
  if [ "$engine_ok" -eq 0 ]; then
    rootfs_only=2
    engine_detail="podman cannot run containers here: $first_error$later_errors"
  fi
fi
if [ "$rootfs_only" -eq 2 ]; then
  record "container engine" SKIP "$(since "$t")" "$engine_detail"
else
  record "container engine" PASS "$(since "$t")" "$engine_detail"
fi

# ---- 2. image -----------------------------------------------------------------------------------------
if [ "$rootfs_only" -eq 0 ]; then
  t=$(now)
  locked=(); if [ -n "$lock" ]; then locked=(flock "$lock"); fi
  if "${locked[@]}" podman build --layers -f "$context/deploy/container/Containerfile" \
       --build-arg "BASE=$base" -t "$image" "$context" > "$tmp/build.log" 2>&1; then
    size=$(podman image inspect --format '{{.Size}}' "$image")
    npk=$(podman run --rm --network none --entrypoint /bin/cat "$image" \
            /usr/local/share/bistable/runtime-packages.txt | wc -l)
    record "image build" PASS "$(since "$t")" "$image, $((size / 1000000)) MB, $npk runtime library packages (ldd + dpkg -S)"
  else
    record "image build" FAIL "$(since "$t")" "podman build failed: $(grep -E '^(Error|error):' "$tmp/build.log" | tail -n 1)"
    tail -n 40 "$tmp/build.log" >&2
    print_table; exit 1
  fi
elif ! podman image exists "$image"; then
  record "image build" SKIP 0 "no runtime to build with, and no $image to inspect"
  print_table
  echo "SKIP: $engine_detail; no image to test"
  exit 77
fi

# ---- fallback: the image's root filesystem, without containers ----------------------------------------
if [ "$rootfs_only" -ne 0 ]; then
  t=$(now)
  root=""
  how=""
  if [ "$(id -u)" -eq 0 ] && root=$(podman image mount "$image" 2>"$tmp/mount.log"); then
    mounted=1; how="podman image mount"
  else
    mkdir "$tmp/rootfs"
    c=$(podman create "$image")
    containers+=("$c")
    podman export "$c" | tar -C "$tmp/rootfs" -xf - --no-same-owner 2>/dev/null || true
    root=$tmp/rootfs; how="podman export"
  fi
  problems=""
  for b in "${binaries[@]}"; do
    out=$(chroot "$root" /usr/bin/ldd "$b" 2>&1) || problems+=" ldd-$(basename "$b")-failed"
    if grep -q 'not found' <<< "$out"; then problems+=" $(basename "$b"):$(grep 'not found' <<< "$out" | awk '{print $1}' | paste -sd, -)"; fi
  done
  [ -z "$problems" ] && r=PASS || r=FAIL
  record "ldd (rootfs)" "$r" "$(since "$t")" "via $how + chroot${problems:+; not found:$problems}"
  t=$(now)
  problems=""
  chroot --userspec=10001:10001 "$root" /usr/local/bin/bistable-coordinator --help 2>&1 | grep -q '^bistable-coordinator:' \
    || problems+=" coordinator"
  chroot --userspec=10001:10001 "$root" /usr/local/bin/bistable-worker --help 2>&1 | grep -q '^bistable-worker:' \
    || problems+=" worker"
  [ -z "$problems" ] && r=PASS || r=FAIL
  record "--help (rootfs)" "$r" "$(since "$t")" "coordinator and worker --help as uid 10001 in chroot${problems:+; failed:$problems}"
  print_table
  if failed; then exit 1; fi
  if [ "$rootfs_only" -eq 1 ]; then reason="containers not run (--rootfs-only)"; else reason=$engine_detail; fi
  echo "SKIP: $reason; tested the image's root filesystem ($how + chroot) instead"
  exit 77
fi

run() { podman run --rm --network none "$@"; }

# ---- 3. libraries, user, entrypoint -------------------------------------------------------------------
t=$(now)
# shellcheck disable=SC2016  # the container's shell expands "$@"
if out=$(run --entrypoint /bin/sh "$image" -c 'for b in "$@"; do echo "== $b"; ldd "$b" || echo "ldd failed: $b"; done' \
           sh "${binaries[@]}" 2>&1) && ! grep -q 'not found\|ldd failed' <<< "$out"; then
  record "ldd in image" PASS "$(since "$t")" "3 binaries, $(grep -c '=>' <<< "$out") libraries resolved, none not found"
else
  record "ldd in image" FAIL "$(since "$t")" "$(grep 'not found\|ldd failed' <<< "$out" | awk '{print $1}' | sort -u | paste -sd' ' -)"
  printf '%s\n' "$out" >&2
fi

t=$(now)
user=$(podman image inspect --format '{{.Config.User}}' "$image")
uid=$(run --entrypoint /usr/bin/id "$image" -u 2>&1 || true)
write=$(run --entrypoint /bin/sh "$image" -c 'touch /var/lib/bistable/.probe && echo ok' 2>&1 || true)
if [ "$uid" != 0 ] && [[ $uid =~ ^[0-9]+$ ]] && [[ ${user%%:*} =~ ^[1-9][0-9]*$ ]] && [ "$write" = ok ]; then
  record "non-root" PASS "$(since "$t")" "id -u = $uid, USER $user (numeric: runAsNonRoot can verify), /var/lib/bistable writable"
else
  record "non-root" FAIL "$(since "$t")" "id -u = $uid, USER '$user', write to /var/lib/bistable: $write"
fi

t=$(now)
e_coord=$(run "$image" coordinator --help 2>&1 | head -n 1 || true)
e_work=$(run "$image" worker --help 2>&1 | head -n 1 || true)
e_cli=$(run "$image" --version 2>&1 | head -n 1 || true)
if [[ $e_coord == bistable-coordinator:* && $e_work == bistable-worker:* && $e_cli == bistable\ * ]]; then
  record "entrypoint" PASS "$(since "$t")" "coordinator → bistable-coordinator, worker → bistable-worker, else CLI ($e_cli)"
else
  record "entrypoint" FAIL "$(since "$t")" "coordinator: '$e_coord', worker: '$e_work', --version: '$e_cli'"
fi

# gnuplot renders the default plots of an embedded run as uid 10001 on a read-only root filesystem.
t=$(now)
cat > "$tmp/plot.toml" <<'SPEC'
name = "container test: plots"
model = "coupled"
[axes]
alpha = { linspace = [0.1, 2.0, 12] }
omega = { linspace = [0.2, 2.0, 12] }
[integration]
t_end = 100.0
t_keep = 50.0
[output]
plots = ["frf_db", "lle", "motion", "edr_t"]
SPEC
chmod 0644 "$tmp/plot.toml"
# shellcheck disable=SC2016  # the container's shell expands these
pngs=$(run --read-only -v "$tmp/plot.toml:/spec/plot.toml:ro" --entrypoint /bin/sh "$image" -c '
  bistable-entrypoint run /spec/plot.toml --data /var/lib/bistable/p --quiet >/dev/null || exit 1
  for f in /var/lib/bistable/p/sweeps/*/*.png; do [ "$(head -c 4 "$f" | tail -c 3)" = PNG ] && echo "$f"; done' 2>&1 || true)
npng=$(grep -c '\.png$' <<< "$pngs" || true)
if [ "$npng" -eq 4 ]; then
  record "plots (gnuplot)" PASS "$(since "$t")" "bistable run rendered 4 PNG plots (read-only root, uid 10001)"
else
  record "plots (gnuplot)" FAIL "$(since "$t")" "$npng of 4 PNG plots: $(tail -n 1 <<< "$pngs")"
fi

# ---- 4. coordinator, two workers and a client on a podman network, TLS and tokens ---------------------
# The reference: the host's embedded run of the same spec.
t=$(now)
if ! "$host_bistable" run "$spec" --data "$tmp/host" --no-plots --quiet --json > "$tmp/host.json" 2> "$tmp/host.log"; then
  record "host embedded run" FAIL "$(since "$t")" "$host_bistable run failed: $(tail -n 1 "$tmp/host.log")"
  print_table; exit 1
fi
json() { /usr/bin/python3 -c 'import json,sys; d=json.load(open(sys.argv[1])); print(eval(sys.argv[2], {}, {"d": d}))' "$@"; }
host_id=$(json "$tmp/host.json" 'd["id"]')
host_map=$(json "$tmp/host.json" 'd["files"][0]')
case "$(grep -s '^BISTABLE_NATIVE:' "$(dirname "$host_bistable")/../CMakeCache.txt" || true)" in
  *=ON) host_march="-march=native" ;;
  *=OFF) host_march="-march=x86-64-v3" ;;
  *) host_march="" ;;
esac
record "host embedded run" PASS "$(since "$t")" "sweep $host_id, $(json "$tmp/host.json" 'd["items"]') items (${host_march:-host build})"

t_sweep=$(now)
podman network create "$net" >/dev/null
network_made=1
subnet=$(podman network inspect --format '{{range .Subnets}}{{.Subnet}} {{end}}' "$net" | tr ' ' '\n' | grep -m1 '\.')
net_addr=${subnet%/*}
ip="${net_addr%.*}.$(( ${net_addr##*.} + 10 ))"

# A throwaway CA naming the coordinator (DNS name and IP), and three tokens (worker, client, admin)
# minted by the image; secrets are readable by uid 10001 only and mounted read-only.
mkdir -p "$tmp/ca" "$tmp/tls" "$tmp/secrets"
"$repo/tests/make_test_certs.sh" "$tmp/ca" coordinator "$ip"
cp "$tmp/ca/ca.pem" "$tmp/ca/server.pem" "$tmp/ca/server.key" "$tmp/tls/"
: > "$tmp/secrets/tokens"
for role in worker client admin; do
  out=$(run "$image" token --role "$role" --name "container-test-$role")
  sed -n 's/^token: //p' <<< "$out" > "$tmp/secrets/$role.token"
  sed -n 's/^tokens-file line: //p' <<< "$out" >> "$tmp/secrets/tokens"
  [ -s "$tmp/secrets/$role.token" ] || { echo "test-image: bistable token printed no token: $out" >&2; exit 1; }
done
own 10001:10001 "$tmp/tls"/* "$tmp/secrets"/*
chmod 0400 "$tmp/tls/server.key" "$tmp/secrets"/*
chmod 0444 "$tmp/tls/ca.pem" "$tmp/tls/server.pem"
mounts=(-v "$tmp/tls:/tls:ro" -v "$tmp/secrets:/secrets:ro")
# The services run as compose.yaml runs them: read-only root filesystem, no capabilities, no privilege gain.
hardened=(--read-only --cap-drop=all --security-opt=no-new-privileges)
dial=(--network "$net" --add-host "coordinator:$ip")
remote=(--coordinator coordinator:50051 --tls-ca /tls/ca.pem)

coord="$prefix-coordinator"
containers+=("$coord")
podman run -d --name "$coord" --network "$net" --ip "$ip" "${hardened[@]}" "${mounts[@]}" "$image" \
  coordinator --listen 0.0.0.0:50051 --data /var/lib/bistable --job-seconds 0.25 \
  --tls-cert /tls/server.pem --tls-key /tls/server.key --tokens /secrets/tokens >/dev/null
listening=0
for _ in $(seq 1 100); do
  if podman logs "$coord" 2>&1 | grep -q 'listening on'; then listening=1; break; fi
  [ "$(podman inspect --format '{{.State.Running}}' "$coord")" = true ] || break
  sleep 0.2
done
if [ "$listening" -ne 1 ]; then
  record "distributed sweep" FAIL "$(since "$t_sweep")" "coordinator did not start: $(podman logs "$coord" 2>&1 | tail -n 1)"
  print_table; exit 1
fi
for i in 1 2; do
  w="$prefix-worker$i"
  containers+=("$w")
  podman run -d --name "$w" "${dial[@]}" "${hardened[@]}" "${mounts[@]}" "$image" \
    worker "${remote[@]}" --token-file /secrets/worker.token --threads 1 --name "container-worker-$i" >/dev/null
done
client=(podman run --rm "${dial[@]}" "${mounts[@]}" -v "$spec:/spec/sweep.toml:ro" "$image")
sweep_ok=0
if "${client[@]}" submit /spec/sweep.toml "${remote[@]}" --token-file /secrets/client.token --json > "$tmp/submit.json" 2> "$tmp/submit.log"; then
  id=$(json "$tmp/submit.json" 'd["id"]')
  timeout 600 "${client[@]}" status "$id" "${remote[@]}" --token-file /secrets/client.token --watch > "$tmp/watch.log" 2>&1 || true
  "${client[@]}" status "$id" "${remote[@]}" --token-file /secrets/client.token --json > "$tmp/status.json" 2>&1 || true
  "${client[@]}" workers "${remote[@]}" --token-file /secrets/admin.token --json > "$tmp/workers.json" 2>&1 || true
  state=$(json "$tmp/status.json" 'd["state"]' 2>/dev/null || echo "?")
  shares=$(json "$tmp/workers.json" '" ".join("%s:%d" % (w["name"], w["items_done"]) for w in sorted(d, key=lambda w: w["name"]))' 2>/dev/null || echo "?")
  busy=$(json "$tmp/workers.json" 'sum(1 for w in d if w["items_done"] > 0)' 2>/dev/null || echo 0)
  if [ "$state" = "done" ] && [ "$busy" -ge 2 ] && [ "$id" = "$host_id" ]; then
    sweep_ok=1
    record "distributed sweep" PASS "$(since "$t_sweep")" "TLS + tokens, read-only, no caps; sweep $id done; items per worker: $shares"
  else
    record "distributed sweep" FAIL "$(since "$t_sweep")" "sweep ${id:-?} (host $host_id) state $state; items per worker: $shares; $(tail -n 1 "$tmp/watch.log")"
  fi
else
  record "distributed sweep" FAIL "$(since "$t_sweep")" "submit failed: $(tail -n 1 "$tmp/submit.log")"
fi

# ---- 5. the map, bit for bit --------------------------------------------------------------------------
t=$(now)
if [ "$sweep_ok" -eq 1 ]; then
  file=$(json "$tmp/status.json" 'd["file"]')
  if podman cp "$coord:/var/lib/bistable/$file" "$tmp/container.h5" 2> "$tmp/cp.log" &&
     /usr/bin/python3 "$here/../compare-maps.py" "$host_map" "$tmp/container.h5" > "$tmp/compare.log" 2>&1; then
    record "map = embedded run" PASS "$(since "$t")" "$(tail -n 1 "$tmp/compare.log"); image x86-64-v3 vs host ${host_march:-build}"
  else
    record "map = embedded run" FAIL "$(since "$t")" "$(tail -n 1 "$tmp/compare.log" 2>/dev/null || tail -n 1 "$tmp/cp.log")"
    cat "$tmp/compare.log" >&2 || true
  fi
else
  record "map = embedded run" SKIP 0 "no finished sweep to compare"
fi

# ---- 6. SIGTERM reaches PID 1 -------------------------------------------------------------------------
t=$(now)
stops=""
stop_ok=1
for c in "$prefix-worker1" "$prefix-worker2" "$coord"; do
  ts=$(now)
  podman stop -t 20 "$c" >/dev/null 2>&1 || true
  code=$(podman inspect --format '{{.State.ExitCode}}' "$c")
  took=$(since "$ts")
  stops+=" ${c#"$prefix-"}:exit $code in ${took}s"
  if [ "$code" = 137 ] || awk -v s="$took" 'BEGIN { exit !(s >= 15) }'; then stop_ok=0; fi
done
if [ "$stop_ok" -eq 1 ]; then
  record "SIGTERM stop" PASS "$(since "$t")" "${stops# }"
else
  record "SIGTERM stop" FAIL "$(since "$t")" "${stops# } (137 or ~20 s: SIGTERM was not handled)"
fi
if failed; then
  for c in "${containers[@]}"; do echo "--- logs of $c" >&2; podman logs "$c" 2>&1 | tail -n 20 >&2 || true; done
fi

print_table
if failed; then exit 1; fi
exit 0
