#!/usr/bin/env bash
# A VT replay through a real level (issue 28, docs/performance.md "Real levels"): fetches an
# OpenArena level (scripts/fetch_levels.sh), walks its spawn points and items (vtsim trace
# level-walk), then replays the walk through the virtual texture in the simulated clock at feedback
# divisor 8, REPS times on one core (view.render_threads = 0) and REPS times with the feedback
# rendered ahead on every core (view.render_threads = -1), alternating, and prints the median ×
# real time of each (trace duration / wall time; real time is the reference) and their ratio.
# The two runs' metrics must agree (render-ahead changes no result): the script checks it.
# Usage: scripts/bench_level.sh [MAP] [REPS]      (default oa_dm1, 5; needs build/vtsim)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
map=${1:-oa_dm1}
reps=${2:-5}
[[ $reps =~ ^[1-9][0-9]*$ ]] || { echo "bench_level: REPS must be a positive integer" >&2; exit 2; }
vtsim=${VTSIM:-$here/build/vtsim}
[ -x "$vtsim" ] || { echo "bench_level: $vtsim not built (bash scripts/setup.sh build)" >&2; exit 2; }
dir=$here/build/levels
bash "$here/scripts/fetch_levels.sh" -o "$dir" "$map" >/dev/null
walk=$dir/${map}_walk.csv
"$vtsim" trace level-walk "$dir/$map.bsp" --mesh "$dir/$map.pk3" -o "$walk" 2>/dev/null
sets=(--set scene.kind=mesh --set "scene.file=$dir/$map.pk3" --set scene.mesh_unit_m=0.0254 --set view.divisor=8)
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
for ((i = 0; i < reps; ++i)); do
  for rt in 0 -1; do
    "$vtsim" replay -q --system vt -t "$walk" "${sets[@]}" --set "view.render_threads=$rt" \
      --summary "$out/s_${rt}_$i.json" 2>/dev/null
  done
done
python3 - "$out" "$reps" "$map" <<'PY'
import json, statistics, sys
out, reps, name = sys.argv[1], int(sys.argv[2]), sys.argv[3]
def load(rt, i): return json.load(open(f"{out}/s_{rt}_{i}.json"))
x = {rt: statistics.median(load(rt, i)["run"]["x_realtime"] for i in range(reps)) for rt in ("0", "-1")}
a, b = load("0", 0), load("-1", 0)
for s in (a, b): s.pop("run"); s.pop("provenance", None); s["config"].pop("view.render_threads", None)
if a != b: sys.exit("bench_level: render-ahead changed the replay's metrics")
t = load("0", 0)
print(f"{name}: {t['trace']['poses']} frames, {t['trace']['poses_duration_s']:.1f} s; median of {reps}:")
print(f"  one core (render_threads 0):  {x['0']:.1f}x real time")
print(f"  render-ahead (every core):    {x['-1']:.1f}x real time ({x['-1'] / x['0']:.2f}x one core)")
PY
