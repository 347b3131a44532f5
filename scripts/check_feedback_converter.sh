#!/usr/bin/env bash
# The converter of docs/feedback.md: an Unreal-style (frame, page id, count) dump converts to a
# feedback trace that `vtsim replay --feedback` reads and replays, with every sample counted.
# Usage: scripts/check_feedback_converter.sh VTSIM_BINARY; exits 77 (skipped) without python3.
set -euo pipefail
vtsim=$1
root=$(cd "$(dirname "$0")/.." && pwd)
command -v python3 >/dev/null || { echo "python3 not found: skipped"; exit 77; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# Two frames: level 2 page (3, 4) and level 10 page (0, 0); then level 0 pages (5, 1) and (7, 1);
# one pair of another space (dropped). Packed: x | y << 12 | level << 24 | space << 28.
{
  echo "frame,page_id,count"
  echo "0,$(( 3 | 4 << 12 | 2 << 24 )),40"
  echo "0,$(( 10 << 24 )),3"
  echo "1,$(( 5 | 1 << 12 )),12"
  echo "1,$(( 7 | 1 << 12 )),5"
  echo "1,$(( 7 | 1 << 12 | 1 << 28 )),9"
} > "$tmp/dump.csv"
python3 "$root/scripts/feedback_from_unreal.py" "$tmp/dump.csv" "$tmp/t.vtfb" --texture 4096x4096 --tile 128 --fps 30
"$vtsim" replay -q --feedback "$tmp/t.vtfb" --system vt --set texture.width=4096 --set texture.height=4096 \
  --summary "$tmp/s.json" --frames "$tmp/f.csv"
python3 - "$tmp/s.json" "$tmp/f.csv" <<'PY'
import csv, json, sys
s = json.load(open(sys.argv[1]))
rows = list(csv.DictReader(open(sys.argv[2])))
assert s["trace"]["frames"] == 2, s["trace"]
samples = [int(r["samples"]) for r in rows]
assert samples == [40 + 3, 12 + 5], samples
print("converted dump replayed:", len(rows), "frames, samples", samples)
PY
# A corrupt trace is refused with exit 2.
head -c 100 "$tmp/t.vtfb" > "$tmp/cut.vtfb"
set +e
"$vtsim" replay -q --feedback "$tmp/cut.vtfb" --system vt --set texture.width=4096 --set texture.height=4096 2> "$tmp/err"
rc=$?
set -e
[ "$rc" = 2 ] || { echo "a cut trace gave exit $rc, not 2"; cat "$tmp/err"; exit 1; }
grep -q "cut.vtfb:frame 0" "$tmp/err" || { echo "no file:frame in:"; cat "$tmp/err"; exit 1; }
echo "ok"
