#!/usr/bin/env bash
# Makes a throwaway CA and a coordinator certificate naming the coordinator (tests and deploy examples).
#   tests/make_test_certs.sh DIR NAME [NAME ...]   → DIR/ca.pem, DIR/server.pem, DIR/server.key
# Each NAME that is an IPv4 or IPv6 address becomes an IP: subjectAltName, any other a DNS: one
# (clients verify the name they dial against these).
set -euo pipefail
if [ "$#" -lt 2 ]; then
  echo "usage: $0 DIR NAME [NAME ...]  (IPv4/IPv6 addresses become IP: SANs, other names DNS: SANs)" >&2
  exit 2
fi
dir=$1; shift

is_ipv4() {
  local IFS=. part
  local -a parts
  [[ $1 =~ ^[0-9]{1,3}(\.[0-9]{1,3}){3}$ ]] || return 1
  read -r -a parts <<<"$1"
  for part in "${parts[@]}"; do [ "$((10#$part))" -le 255 ] || return 1; done
}
is_ipv6() {
  # Hex groups and colons (with at most one '::'), optionally ending in a dotted IPv4; no zone index.
  [[ $1 == *:* && $1 =~ ^[0-9A-Fa-f:.]+$ ]] || return 1
  local rest=${1#*::}
  [[ $rest != *::* ]] || return 1
  [[ $1 != *:::* ]]
}
is_dns() { [[ $1 =~ ^[A-Za-z0-9*]([A-Za-z0-9.-]*[A-Za-z0-9])?$ ]]; }

san=""
for name in "$@"; do
  if is_ipv4 "$name" || is_ipv6 "$name"; then
    san+="IP:$name,"
  elif [[ ! $name =~ ^[0-9.]+$ ]] && is_dns "$name"; then
    san+="DNS:$name,"
  else
    echo "make_test_certs.sh: '$name' is neither an IP address nor a DNS name" >&2
    exit 2
  fi
done
san=${san%,}

mkdir -p "$dir"
openssl req -x509 -newkey rsa:2048 -nodes -keyout "$dir/ca.key" -out "$dir/ca.pem" -days 2 -subj "/CN=bistable-test-ca" 2>/dev/null
openssl req -newkey rsa:2048 -nodes -keyout "$dir/server.key" -out "$dir/server.csr" -subj "/CN=bistable-coordinator" 2>/dev/null
printf 'subjectAltName=%s\n' "$san" > "$dir/ext.cnf"
openssl x509 -req -in "$dir/server.csr" -CA "$dir/ca.pem" -CAkey "$dir/ca.key" -CAcreateserial -out "$dir/server.pem" \
  -days 2 -extfile "$dir/ext.cnf" 2>/dev/null
