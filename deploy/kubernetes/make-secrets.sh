#!/usr/bin/env bash
# Writes the three Secrets of deploy/kubernetes/bistable.yaml as one manifest (secrets.yaml) in DIR:
# a CA and a coordinator certificate naming every DNS name a pod may dial the coordinator by
# (bistable-coordinator, .bistable, .bistable.svc, .bistable.svc.cluster.local, and the StatefulSet pod's
# name under its headless Service), a worker token, and the tokens file (hashes only). Keep DIR private.
#   deploy/kubernetes/make-secrets.sh DIR [NAMESPACE] [CLUSTER_DOMAIN] [--client NAME ...]
#   kubectl apply -f DIR/secrets.yaml && kubectl apply -k deploy/kubernetes
# BISTABLE (the CLI, default `bistable` on PATH) mints the tokens; each --client NAME gets a client
# token in DIR/NAME.token.
set -euo pipefail
dir=${1:?usage: make-secrets.sh DIR [NAMESPACE] [CLUSTER_DOMAIN] [--client NAME ...]}
shift
ns=bistable
domain=cluster.local
if [ $# -gt 0 ] && [ "${1#--}" = "$1" ]; then ns=$1; shift; fi
if [ $# -gt 0 ] && [ "${1#--}" = "$1" ]; then domain=$1; shift; fi
clients=()
while [ $# -gt 0 ]; do
  case $1 in
    --client) clients+=("${2:?--client needs a name}"); shift 2 ;;
    *) echo "make-secrets.sh: unknown argument '$1'" >&2; exit 2 ;;
  esac
done
[[ $ns =~ ^[a-z0-9]([-a-z0-9]*[a-z0-9])?$ ]] || { echo "make-secrets.sh: namespace '$ns' is not a DNS label" >&2; exit 2; }
[[ $domain =~ ^[a-z0-9]([-a-z0-9.]*[a-z0-9])?$ ]] || { echo "make-secrets.sh: cluster domain '$domain' is not a DNS name" >&2; exit 2; }
here=$(cd "$(dirname "$0")" && pwd)
bistable=${BISTABLE:-bistable}
umask 077
mkdir -p "$dir/tls"
svc=bistable-coordinator
pod=bistable-coordinator-0.bistable-coordinator-pods
"$here/../../tests/make_test_certs.sh" "$dir/tls" \
  "$svc" "$svc.$ns" "$svc.$ns.svc" "$svc.$ns.svc.$domain" "$pod.$ns.svc" "$pod.$ns.svc.$domain" localhost 127.0.0.1

mint() {  # role name → sets token and line
  local out
  out=$("$bistable" token --role "$1" --name "$2")
  token=$(sed -n 's/^token: //p' <<<"$out")
  line=$(sed -n 's/^tokens-file line: //p' <<<"$out")
}
mint worker pool
printf '%s\n' "$token" > "$dir/worker.token"
printf '%s\n' "$line" > "$dir/tokens"
for c in "${clients[@]}"; do
  [[ $c =~ ^[A-Za-z0-9._-]{1,64}$ ]] || { echo "make-secrets.sh: client name '$c' must be 1-64 of [A-Za-z0-9._-]" >&2; exit 2; }
  mint client "$c"
  printf '%s\n' "$token" > "$dir/$c.token"
  printf '%s\n' "$line" >> "$dir/tokens"
done

b64() { base64 -w0 < "$1"; }
secret() {  # name key=file...
  local name=$1; shift
  printf -- '---\napiVersion: v1\nkind: Secret\nmetadata:\n  name: %s\n  namespace: %s\ntype: Opaque\ndata:\n' "$name" "$ns"
  local kv
  for kv in "$@"; do printf '  %s: %s\n' "${kv%%=*}" "$(b64 "${kv#*=}")"; done
}
{
  secret bistable-tls "server.pem=$dir/tls/server.pem" "server.key=$dir/tls/server.key" "ca.pem=$dir/tls/ca.pem"
  secret bistable-tokens "tokens=$dir/tokens"
  secret bistable-worker-token "worker.token=$dir/worker.token"
} > "$dir/secrets.yaml"
echo "wrote $dir/secrets.yaml (namespace $ns; certificate for $svc, $svc.$ns.svc.$domain, ...)"
