#!/usr/bin/env bash
# Every C++ source of the project follows .clang-format (Google style, 120 columns): `clang-format -i` on a
# file fixes what this reports. Exit 77 (skipped, with the reason) where clang-format is not installed
# (scripts/setup.sh installs it).
set -euo pipefail
root=${1:?usage: check_format.sh SOURCE_DIR}
command -v clang-format >/dev/null || { echo "clang-format not installed: skipped"; exit 77; }
cd "$root"
mapfile -t files < <(find base dynamics engine identify design storage net proto server worker client python tests bench \
                        \( -name '*.cc' -o -name '*.h' \) | sort)
bad=0
for f in "${files[@]}"; do
  if ! clang-format --style=file --dry-run -Werror "$f" >/dev/null 2>&1; then
    echo "not formatted: $f (clang-format --style=file -i $f)"
    bad=$((bad + 1))
  fi
done
echo "format: ${#files[@]} files checked, $bad not formatted"
[ "$bad" -eq 0 ]
