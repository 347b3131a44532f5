#!/usr/bin/env bash
# Every docs/*.md file that the code, tests, benchmarks, scripts and docs point at exists.
# Usage: scripts/check_doc_refs.sh [repo root]; prints each missing file with where it is named,
# exits 1 if any is missing.
set -euo pipefail
root=${1:-$(cd "$(dirname "$0")/.." && pwd)}
cd "$root"
missing=0
while IFS= read -r ref; do
  if [ ! -f "$ref" ]; then
    echo "missing $ref, named in:"
    grep -rnF --include='*.h' --include='*.cpp' --include='*.md' --include='*.sh' --include='*.txt' "$ref" \
      src tests bench scripts docs README.md CMakeLists.txt | sed 's/^/  /'
    missing=1
  fi
done < <(grep -rhoE --include='*.h' --include='*.cpp' --include='*.md' --include='*.sh' --include='*.txt' \
           'docs/[A-Za-z0-9_.-]+\.md' src tests bench scripts docs README.md CMakeLists.txt | sort -u)
[ "$missing" = 0 ] && echo "every docs/*.md reference resolves"
exit "$missing"
