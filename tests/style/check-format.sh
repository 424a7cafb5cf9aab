#!/usr/bin/env bash
# Checks that every C++ file in the repository is formatted as .clang-format
# says; lists the files that are not. To fix them:
#   git ls-files '*.cpp' '*.hpp' | xargs clang-format -i
set -euo pipefail
case "${1:-}" in
  -h|--help) sed -n '2,5p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
esac
cd "$(dirname "$0")/../.."
command -v clang-format >/dev/null || { echo "check-format: clang-format not found (package clang-format)" >&2; exit 2; }
bad=()
while IFS= read -r -d '' file; do
  clang-format --dry-run --Werror "$file" >/dev/null 2>&1 || bad+=("$file")
done < <(git ls-files -z '*.cpp' '*.hpp' '*.h')
if [ "${#bad[@]}" -gt 0 ]; then
  echo "check-format: ${#bad[@]} file(s) not formatted as .clang-format says:" >&2
  printf '  %s\n' "${bad[@]}" >&2
  echo "check-format: fix with: clang-format -i FILE..." >&2
  exit 1
fi
echo "check-format: $(git ls-files '*.cpp' '*.hpp' '*.h' | wc -l) files formatted"
