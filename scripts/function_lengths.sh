#!/usr/bin/env bash
# Function and file lengths of the project's own code outside the tests (issue 40: no non-test file over 900 lines
# and no function over 120 lines, or a sentence in the file saying why).
#   scripts/function_lengths.sh [LIMIT]   the C++ functions longer than LIMIT lines (default 120), longest first:
#                                         "LINES FILE:LINE NAME"
#   scripts/function_lengths.sh --check   the test (ctest -R Hygiene): exit 1 when a function is longer than 120
#                                         lines or a source file longer than 900, unless it says why (the allowed
#                                         list below, of exemptions without a reason, is empty). Exit 77 (skipped)
#                                         without universal-ctags.
# A function says why with a comment holding the words "longer than" in the comment block just above it or in its
# body; a file with such a comment in its first 30 lines. Functions are measured by universal-ctags (its `end:`
# field: from the line of the name to the closing brace); tests/, *_test.* and bench/ are not measured.
set -euo pipefail

MAX_FUNCTION=120
MAX_FILE=900
# Functions over the limit that may stay so for a while without saying why (one "FILE NAME" a line): none. The
# list is kept for work that must land before a long function can be split; a function that should stay long
# says why in a comment instead.
ALLOWED="
"

mode=list
limit=$MAX_FUNCTION
case "${1:-}" in
  --check) mode=check ;;
  "") ;;
  *[!0-9]*) echo "usage: scripts/function_lengths.sh [LIMIT | --check]" >&2; exit 2 ;;
  *) limit=$1 ;;
esac

cd "$(dirname "$0")/.."
if ! ctags --version 2>/dev/null | grep -q "Universal Ctags"; then
  echo "universal-ctags not installed (scripts/setup.sh --tests installs it): skipped"
  exit 77
fi

# The project's files: git's list, or in a tree that is no git checkout every file (build/ left out).
files() {
  if git rev-parse --is-inside-work-tree >/dev/null 2>&1; then
    git ls-files "$@"
  else
    local args=() p
    for p in "$@"; do args+=(-o -name "$p"); done
    find . -path ./build -prune -o \( -false "${args[@]}" \) -type f -print | sed 's|^\./||' | sort
  fi
}
mapfile -t cpp < <(files '*.cc' '*.h' | grep -v -E '^(tests|bench)/|_test\.' || true)
# "LINES FILE START END NAME" for every function definition over `limit` lines.
long_functions() {
  ctags --kinds-c++=f --fields=+ne -f - "${cpp[@]}" 2>/dev/null |
    awk -F'\t' -v lim="$1" '{
      s = ""; e = ""
      for (i = 4; i <= NF; i++) {
        if ($i ~ /^line:/) s = substr($i, 6)
        if ($i ~ /^end:/) e = substr($i, 5)
      }
      if (s != "" && e != "" && e - s + 1 > lim) print e - s + 1, $2, s, e, $1
    }' | sort -k1,1rn -k2,2 -k3,3n
}

if [ "$mode" = list ]; then
  long_functions "$limit" | awk '{ print $1, $2 ":" $3, $5 }'
  exit 0
fi

# Whether lines [from, to] of a file, or the comment block just above `from`, hold a comment saying "longer than".
says_why() {
  awk -v from="$2" -v to="$3" '
    { line[NR] = $0 }
    END {
      top = from
      while (top > 1 && line[top - 1] ~ /^[ \t]*(\/\/|template)/) top--
      for (i = top; i <= to; i++)
        if (line[i] ~ /\/\/.*longer than/) exit 0
      exit 1
    }' "$1"
}

bad=0
while read -r n file start end name; do
  if grep -qx "$file $name" <<<"$ALLOWED"; then
    echo "allowed: $file:$start $name is $n lines (on the list in scripts/function_lengths.sh)"
  elif says_why "$file" "$start" "$end"; then
    echo "says why: $file:$start $name is $n lines"
  else
    echo "too long: $file:$start $name is $n lines (at most $MAX_FUNCTION, or a comment saying why it is longer than that)"
    bad=$((bad + 1))
  fi
done < <(long_functions "$MAX_FUNCTION")

mapfile -t sources < <(files '*.cc' '*.h' '*.py' '*.sh' '*.js' '*.html' '*.css' '*.proto' '*.cmake' \
                         '*CMakeLists.txt' | grep -v -E '^(tests|bench)/|_test\.' || true)
while read -r n file; do
  [ "$file" = total ] && continue
  if [ "$n" -gt "$MAX_FILE" ]; then
    if says_why "$file" 1 30; then
      echo "says why: $file is $n lines"
    else
      echo "too long: $file is $n lines (at most $MAX_FILE, or a comment in its first 30 lines saying why it is longer than that)"
      bad=$((bad + 1))
    fi
  fi
done < <(wc -l "${sources[@]}")

echo "lengths: ${#cpp[@]} C++ files measured, ${#sources[@]} sources counted, $bad too long"
[ "$bad" -eq 0 ]
