#!/usr/bin/env bash
# Prints the Debian packages that hold every shared library the given binaries load, one per line, sorted:
# ldd lists the libraries (transitively), dpkg -S names their packages. The Containerfile's build stage
# runs it on the three binaries and the runtime stage installs exactly this list.
#   deploy/container/runtime-packages.sh BINARY...
# Fails, naming the library, if ldd reports one "not found" or if no installed package owns one.
set -euo pipefail

if [ "$#" -eq 0 ]; then
  echo "usage: $0 BINARY..." >&2
  exit 2
fi

# ldd prints the path it loaded, which may be a symlink that no package ships (update-alternatives:
# liblapack.so.3, libblas.so.3) or the other spelling of a path under merged /usr (/lib/... vs /usr/lib/...):
# a library's candidates are the path, its target, and both spellings of each, tried in that order.
candidates() {
  local p real
  real=$(readlink -f -- "$1")
  for p in "$1" "$real"; do
    printf '%s\n' "$p"
    case "$p" in
      /usr/*) printf '%s\n' "${p#/usr}" ;;
      *) printf '%s\n' "/usr$p" ;;
    esac
  done
}

libs=()
failed=0
for bin in "$@"; do
  if ! out=$(ldd -- "$bin" 2>&1); then
    echo "runtime-packages: ldd $bin failed: $out" >&2
    exit 1
  fi
  while IFS= read -r line; do
    line=${line#"${line%%[![:space:]]*}"}
    case "$line" in
      *"not found"*) echo "runtime-packages: $bin: $line" >&2; failed=1 ;;
      *" => /"*) path=${line#* => }; libs+=("${path%% (*}") ;;   # libfoo.so.1 => /lib/.../libfoo.so.1 (0x...)
      /*) libs+=("${line%% (*}") ;;                             # /lib64/ld-linux-x86-64.so.2 (0x...)
      *) ;;                                                     # linux-vdso.so.1 (0x...): the kernel's
    esac
  done <<< "$out"
done

# One dpkg -S for every candidate (it is slow per call): "libfoo1:amd64: /path" or "a, b: /path" per owned
# path, errors for the others; "diversion by ..." lines are skipped.
declare -A owner=()
mapfile -t all < <(for lib in "${libs[@]}"; do candidates "$lib"; done | LC_ALL=C sort -u)
while IFS= read -r line; do
  case "$line" in diversion\ *) continue ;; esac
  path=${line#*: }
  pkg=${line%%: *}
  pkg=${pkg%%,*}
  owner[$path]=${pkg%%:*}
done < <(dpkg -S -- "${all[@]}" 2>/dev/null || true)

declare -A packages=()
for lib in "${libs[@]}"; do
  found=""
  while IFS= read -r c; do
    if [ -n "${owner[$c]-}" ]; then found=${owner[$c]}; break; fi
  done < <(candidates "$lib")
  if [ -n "$found" ]; then
    packages[$found]=1
  else
    echo "runtime-packages: no installed package owns $lib" >&2
    failed=1
  fi
done
if [ "$failed" -ne 0 ] || [ "${#packages[@]}" -eq 0 ]; then
  exit 1
fi
printf '%s\n' "${!packages[@]}" | LC_ALL=C sort
