#!/usr/bin/env bash
# Fails when a file of the repository refers to a path outside it, or is too large to commit, so
# that a user's clone keeps working with nothing beside it (issue 37). Run by the test suite
# (tests/CMakeLists.txt) as "repository: ...", and by hand from anywhere:
#   scripts/check_self_contained.sh [ROOT]
# What counts as pointing outside:
#   - the team's work folder beside the repository (`..` followed by `/shared`);
#   - an absolute path into a build machine's home or work folders (/home/, /root/, /work/,
#     /Users/, /builds/, /mnt/, /media/, /srv/, /scratch/);
#   - a CMake path that climbs out of the source tree (a source or root variable followed by /..).
# The files are those git tracks (or, outside a git checkout, every file but build outputs);
# this script is left out, since it names the patterns.
set -uo pipefail
root=$(cd "${1:-$(dirname "$0")/..}" && pwd)
cd "$root" || exit 2
self="scripts/check_self_contained.sh"

if git -C "$root" rev-parse --is-inside-work-tree >/dev/null 2>&1; then
  mapfile -d '' files < <(git ls-files -z --cached --others --exclude-standard)
else
  mapfile -d '' files < <(find . -type f -not -path './.git/*' -not -path './build*' -not -path './out/*' \
                            -printf '%P\0')
fi
kept=()
for f in "${files[@]}"; do [ "$f" != "$self" ] && [ -f "$f" ] && kept+=("$f"); done

status=0
dotdot='\.\.'
patterns=(
  "${dotdot}/shared"
  '(^|[^A-Za-z0-9_.~$-])/(home|root|work|Users|builds|mnt|media|srv|scratch)/'
  '(ROOT|SOURCE_DIR|CURRENT_LIST_DIR)\}/\.\.'
)
for pattern in "${patterns[@]}"; do
  if hits=$(printf '%s\0' "${kept[@]}" | xargs -0 grep -nIE -- "$pattern" 2>/dev/null); then
    echo "refers to a path outside the repository (pattern $pattern):"
    echo "$hits" | head -20
    status=1
  fi
done

limit=$((5 * 1024 * 1024))
for f in "${kept[@]}"; do
  size=$(stat -c %s "$f")
  if [ "$size" -gt "$limit" ]; then
    echo "$f: $size bytes, over the 5 MB a committed file may have"
    status=1
  fi
done

[ $status -eq 0 ] && echo "${#kept[@]} files checked: none refers to a path outside the repository, none over 5 MB"
exit $status
