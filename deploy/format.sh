#!/usr/bin/env bash
# The C++ sources' layout, by clang-format and the .clang-format at the root:
#
#   deploy/format.sh           rewrites every tracked .cc and .h that differs
#   deploy/format.sh --check   changes nothing: lists the files that differ
#                              and exits 1 if there are any (CI runs this)
#
# Needs clang-format 14 (Debian's clang-format, which deploy/setup-debian.sh
# installs); other versions lay some constructs out differently.
set -euo pipefail
cd "$(dirname "$0")/.."

check=0
case "${1:-}" in
  --check) check=1 ;;
  "") ;;
  *) sed -n '2,/^set -euo/p' "$0" | sed -e '$d' -e 's/^# \{0,1\}//' >&2; exit 2 ;;
esac
format=$(command -v clang-format-14 || true)
if [ -z "$format" ]; then
  echo "format.sh: clang-format-14 is not installed (apt-get install clang-format)" >&2
  exit 1
fi

mapfile -t files < <(git ls-files '*.cc' '*.h')
differ=()
for f in "${files[@]}"; do
  if ! "$format" --style=file --dry-run --Werror "$f" >/dev/null 2>&1; then differ+=("$f"); fi
done
if ((check)); then
  if ((${#differ[@]})); then
    printf 'format.sh: %s\n' "${differ[@]/%/ is not laid out as .clang-format says}" >&2
    echo "format.sh: ${#differ[@]} of ${#files[@]} files differ; deploy/format.sh fixes them" >&2
    exit 1
  fi
  echo "format.sh: all ${#files[@]} C++ files are laid out as .clang-format says"
  exit 0
fi
if ((${#differ[@]})); then "$format" --style=file -i "${differ[@]}"; fi
echo "format.sh: reformatted ${#differ[@]} of ${#files[@]} files"
