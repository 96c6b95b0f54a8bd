#!/bin/sh
# bistable-entrypoint: one image for every role. The first argument picks the program:
#   coordinator ARGS...  -> bistable-coordinator ARGS...
#   worker ARGS...       -> bistable-worker ARGS...
#   anything else        -> bistable (the CLI) with all arguments: run, submit, status, map, token, ...
# exec replaces this shell, so the program is PID 1 and receives SIGTERM from `podman stop` / Kubernetes.
set -eu
case "${1-}" in
  coordinator) shift; exec /usr/local/bin/bistable-coordinator "$@" ;;
  worker) shift; exec /usr/local/bin/bistable-worker "$@" ;;
  *) exec /usr/local/bin/bistable "$@" ;;
esac
