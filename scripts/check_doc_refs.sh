#!/usr/bin/env bash
# Every docs/*.md file that the code, tests, benchmarks, scripts and docs point at exists, and so
# does every heading they cite in it. The citation forms in use:
#   docs/x.md "Heading"   docs/x.md, "Heading"   docs/x.md "A", "B"   (a heading's text, or the
#                         start of one up to a word boundary; backticks and ** are ignored)
#   docs/x.md §3          docs/x.md §7a          (a numbered heading: "## 3. ...", "## 7a. ...")
#   docs/x.md#anchor      [text](x.md#anchor)    (GitHub's anchor of a heading)
# Headings inside ``` fences do not count. A citation may wrap across lines (and comment lines).
# Usage: scripts/check_doc_refs.sh [repo root]; prints each missing file or heading with where it
# is named, exits 1 if any is missing. scripts/check_doc_refs.sh --self-test runs the check on a
# small tree of good and broken citations of every form and exits 0 only if it reports exactly the
# broken ones (ctest: doc_references_self_test).
set -euo pipefail
if [ "${1:-}" = "--self-test" ]; then
  tmp=$(mktemp -d)
  trap 'rm -rf "$tmp"' EXIT
  mkdir -p "$tmp/docs" "$tmp/src"
  printf '# T\n\n## 3. Three\n\n## Real heading here\n\n```\n## Fenced\n```\n' >"$tmp/docs/a.md"
  {
    echo '// good: docs/a.md "Real heading", docs/a.md §3, docs/a.md#real-heading-here, docs/a.md, "Real'
    echo '// heading here" (wrapped)'
    echo '// broken: docs/a.md "Fenced" docs/a.md §4 docs/a.md#nope docs/b.md docs/a.md, "Real'
    echo '// nothing"'
  } >"$tmp/src/x.h"
  printf 'see [x](a.md#3-three) and [y](a.md#missing)\n' >"$tmp/docs/c.md"
  want='missing docs/b.md, named in:
  src/x.h:3
missing heading docs/a.md "Fenced", named in:
  src/x.h:3
missing heading docs/a.md "Real nothing", named in:
  src/x.h:3
missing heading docs/a.md §4, named in:
  src/x.h:3
missing heading docs/a.md#missing, named in:
  docs/c.md:1
missing heading docs/a.md#nope, named in:
  src/x.h:3'
  got=$(bash "${BASH_SOURCE[0]}" "$tmp" || true)
  if [ "$got" != "$want" ]; then
    printf 'check_doc_refs self-test: expected\n%s\ngot\n%s\n' "$want" "$got" >&2
    exit 1
  fi
  echo "check_doc_refs self-test: every broken citation found, no good one flagged"
  exit 0
fi
root=${1:-$(cd "$(dirname "$0")/.." && pwd)}
cd "$root"
command -v python3 >/dev/null || { echo "check_doc_refs: python3 not found (scripts/setup.sh installs it)" >&2; exit 2; }
python3 - <<'PY'
import bisect, os, re, sys

exts = ('.h', '.cpp', '.md', '.sh', '.txt', '.toml', '.py')
roots = ['src', 'tests', 'bench', 'scripts', 'docs', 'README.md', 'CMakeLists.txt']
files = []
for r in roots:  # this script's own examples (docs/x.md) are skipped below
    if os.path.isfile(r):
        files.append(r)
        continue
    for d, dirs, names in os.walk(r):
        dirs.sort()
        for n in sorted(names):
            if n.endswith(exts):
                files.append(os.path.join(d, n))

def norm(t):
    return re.sub(r'\s+', ' ', t.replace('`', '').replace('**', '')).strip()

def slug(t):  # GitHub's heading anchor
    t = norm(t).lower()
    t = re.sub(r'[^\w\- ]', '', t)
    return t.replace(' ', '-')

headings = {}
def heads(path):
    if path not in headings:
        hs, fence = [], False
        with open(path, encoding='utf-8') as f:
            for line in f:
                if line.lstrip().startswith('```'):
                    fence = not fence
                    continue
                m = None if fence else re.match(r'#{1,6}\s+(.*?)\s*#*\s*$', line)
                if m:
                    hs.append(norm(m.group(1)))
        headings[path] = hs
    return headings[path]

def has_heading(path, text):
    t = norm(text)
    if not t:
        return False
    for h in heads(path):
        if h == t:
            return True
        if h.startswith(t) and not (t[-1].isalnum() and h[len(t)].isalnum()):
            return True
    return False

def has_number(path, num):
    return any(re.match(re.escape(num) + r'[.)]?(\s|$)', h) for h in heads(path))

def has_anchor(path, a):
    return a.lower() in {slug(h) for h in heads(path)}

ref = re.compile(r'docs/([A-Za-z0-9_./-]+\.md)'
                 r'((?:,?\s"[^"\s][^"]{0,119}")(?:,\s?"[^"\s][^"]{0,119}")*|\s?§\s?[0-9]+[a-z]?|#[A-Za-z0-9_-]+)?')
link = re.compile(r'\]\(([A-Za-z0-9_./-]+\.md)#([A-Za-z0-9_-]+)\)')
bad = {}
for src in files:
    if src == 'scripts/check_doc_refs.sh':
        continue
    try:
        lines = open(src, encoding='utf-8').read().split('\n')
    except UnicodeDecodeError:
        continue
    # One text per file, each line's comment marker (//, #, *) dropped and the lines joined by a
    # space, so that a citation wrapped across comment lines is read whole; starts[i] is where
    # line i + 1 begins in it.
    parts, starts, pos = [], [], 0
    for i, line in enumerate(lines):
        piece = line.strip()
        if i > 0:
            piece = re.sub(r'^(?://+|#+|\*+)\s?', '', piece)
        starts.append(pos)
        parts.append(piece)
        pos += len(piece) + 1
    text = ' '.join(parts)
    found = []
    for m in ref.finditer(text):
        found.append((m.start(), 'docs/' + m.group(1), m.group(2)))
    if src.endswith('.md'):
        for m in link.finditer(text):
            p = os.path.normpath(os.path.join(os.path.dirname(src), m.group(1)))
            found.append((m.start(), p, '#' + m.group(2)))
    for at, path, cite in found:
        where = f'{src}:{bisect.bisect_right(starts, at)}'
        if not os.path.isfile(path):
            bad.setdefault(f'missing {path}', []).append(where)
            continue
        if not cite:
            continue
        cite = cite.strip()
        if cite.startswith('#'):
            if not has_anchor(path, cite[1:]):
                bad.setdefault(f'missing heading {path}{cite}', []).append(where)
        elif cite.startswith('§'):
            num = cite[1:].strip()
            if not has_number(path, num):
                bad.setdefault(f'missing heading {path} §{num}', []).append(where)
        else:
            for q in re.findall(r'"([^"]+)"', cite):
                if not has_heading(path, q):
                    bad.setdefault(f'missing heading {path} "{q}"', []).append(where)
for k in sorted(bad):
    print(f'{k}, named in:')
    for w in bad[k]:
        print(f'  {w}')
if bad:
    sys.exit(1)
print('every docs/*.md reference and cited heading resolves')
PY
