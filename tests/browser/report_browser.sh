#!/usr/bin/env bash
# ctest report_browser (label browser): the HTML reports rendered in headless Chromium. Writes a
# replay report of each system (clipmap, vt) and a `vtsim report` of both runs, opens each with
# `?check` (report_check_script in src/sim/report/report_html.h measures every chart text's bounding
# box in the DOM) and fails on overlapping texts, a text outside its chart, or a console error;
# writes a full-page screenshot of each next to it, for a person to open:
#   WORKDIR/{clipmap,vt,runs}.html and .png
# Exit 77 (skipped) when chromium is missing and cannot be installed (scripts/test.sh installs
# Debian's chromium as root).
#   tests/browser/report_browser.sh VTSIM SRCDIR WORKDIR
set -euo pipefail
[ $# -eq 3 ] || { echo "usage: $0 VTSIM SRCDIR WORKDIR" >&2; exit 2; }
vtsim=$(realpath "$1")
src=$(cd "$2" && pwd)
mkdir -p "$3"
work=$(cd "$3" && pwd)
browser=$(command -v chromium || command -v chromium-browser || true)
if [ -z "$browser" ]; then
  echo "report_browser: chromium is not installed (scripts/test.sh installs it as root); skipped" >&2
  exit 77
fi
# A profile of its own: no first-run state, no lock shared with another chromium.
profile=$work/profile
rm -rf "$profile"
run_browser() {
  timeout 120 "$browser" --headless --disable-gpu --no-sandbox --no-first-run --disable-extensions \
    --user-data-dir="$profile" --hide-scrollbars --virtual-time-budget=5000 "$@" 2>>"$work/chromium.log"
}

# The default walk: a report of each system, and the two side by side.
"$vtsim" replay -t "$src/traces/walk.csv" --summary "$work/clipmap.json" --frames "$work/clipmap.csv" --report "$work/clipmap.html" -q
"$vtsim" replay -t "$src/traces/walk.csv" --system vt --opt --summary "$work/vt.json" --frames "$work/vt.csv" --report "$work/vt.html" -q
"$vtsim" report "$work/clipmap.json" "$work/vt.json" --names clipmap,vt --frames "$work/clipmap.csv,$work/vt.csv" -o "$work/runs.html"

# The checker itself: a page with two overlapping texts and a console error must fail it.
sed -e 's|</body>|<svg class="chart" width="200" height="40" aria-label="bad"><text x="5" y="20">overlapping</text><text x="9" y="22">texts</text></svg><script>console.error("planted")</script></body>|' \
  "$work/runs.html" >"$work/planted.html"

fail=0
for page in planted clipmap vt runs; do
  html=$work/$page.html
  dom=$(run_browser --dump-dom "file://$html?check")
  result=$(printf '%s\n' "$dom" | sed -n '/<pre id="vtsim-check">/,/<\/pre>/p' | sed -e 's/<pre id="vtsim-check">//' -e 's/<\/pre>.*//')
  first=$(printf '%s\n' "$result" | head -n 1)
  if [[ $first != VTSIM-CHECK* ]]; then
    echo "report_browser: $page.html: the check script left no result (see $work/chromium.log)" >&2
    fail=1
    continue
  fi
  echo "$page.html: $first"
  if [ "$page" = planted ]; then
    if [[ $first != *" overlaps=1 console_errors=1"* ]]; then
      echo "report_browser: the check missed the planted overlap or console error: $first" >&2
      fail=1
    fi
    continue
  fi
  charts=$(sed -n 's/.*charts=\([0-9]*\).*/\1/p' <<<"$first")
  if [[ $first != *" overlaps=0 console_errors=0"* ]] || [ "${charts:-0}" -lt 3 ]; then
    printf '%s\n' "$result" | sed 's/^/  /' >&2
    fail=1
  fi
  # The window holds the whole page: charts in two columns, table rows of ~21 px, the config.
  rows=$(grep -o '<tr' "$html" | wc -l)
  height=$(( charts * 130 + rows * 21 + 1200 ))
  run_browser --screenshot="$work/$page.png" --window-size=1400,"$height" "file://$html" >/dev/null
  [ -s "$work/$page.png" ] || { echo "report_browser: no screenshot $work/$page.png" >&2; fail=1; }
done
[ "$fail" -eq 0 ] && echo "report_browser: screenshots in $work/*.png"
exit "$fail"
