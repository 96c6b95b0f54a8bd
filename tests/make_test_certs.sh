#!/usr/bin/env bash
# Makes a throwaway CA and a coordinator certificate for the given IPs (tests and deploy examples).
#   tests/make_test_certs.sh DIR IP [IP ...]   → DIR/ca.pem, DIR/server.pem, DIR/server.key
set -euo pipefail
dir=$1; shift
mkdir -p "$dir"
san=$(printf 'IP:%s,' "$@"); san=${san%,}
openssl req -x509 -newkey rsa:2048 -nodes -keyout "$dir/ca.key" -out "$dir/ca.pem" -days 2 -subj "/CN=bistable-test-ca" 2>/dev/null
openssl req -newkey rsa:2048 -nodes -keyout "$dir/server.key" -out "$dir/server.csr" -subj "/CN=bistable-coordinator" 2>/dev/null
printf 'subjectAltName=%s\n' "$san" > "$dir/ext.cnf"
openssl x509 -req -in "$dir/server.csr" -CA "$dir/ca.pem" -CAkey "$dir/ca.key" -CAcreateserial -out "$dir/server.pem" \
  -days 2 -extfile "$dir/ext.cnf" 2>/dev/null
