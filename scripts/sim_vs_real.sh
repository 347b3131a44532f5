#!/usr/bin/env bash
# The calibration check of docs/real-engine.md §6: does the simulated clock, with this machine's
# calibrated profile, predict the real clock (latency p50 / p95, disk bandwidth) within 15%?
#   scripts/sim_vs_real.sh [OUT_DIR] [RUNS]      (default out/sim_vs_real, 3 real runs per trace)
# Makes a 16384² store (albedo zstd + normal lz4; ~2 min) if OUT_DIR has none, calibrates
# (`vtsim calibrate`), then replays two traces in both clocks with the same config (the profile)
# and prints the table. Extra replay options: VTSIM_SETS="--set k=v ...". Extra calibrate options:
# VTSIM_CALIBRATE="--engine io_uring --queue-depth 16" (the profile then sets io.engine and
# io.queue_depth, so the real runs read with io_uring and the simulated disk has that depth).
# VTSIM_SYSTEM=clipmap (default): no border, the standard walk and drive traces (§6).
# VTSIM_SYSTEM=vt: pages with a 4-texel border, the town walk at 1× and 4× (§7a).
# VTSIM_SYSTEM=terrain: the terrain (docs/examples/terrain.toml), no store: the [produce]
# keys fitted to the tiles of a real-clock calibration walk (another walk than the one compared),
# then production per frame and per tile on traces/walk.csv (docs/produced.md, "Calibrating from
# the replay's own tiles").
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
vtsim=$here/build/vtsim
out=${1:-$here/out/sim_vs_real}
runs=${2:-3}
[ -x "$vtsim" ] || { echo "sim_vs_real: build first (bash scripts/setup.sh build)" >&2; exit 2; }
command -v fio >/dev/null || true
mkdir -p "$out"
system=${VTSIM_SYSTEM:-clipmap}
case $system in
  clipmap) border=0 ;;
  vt) border=4 ;;
  terrain) border=0 ;;
  *) echo "sim_vs_real: VTSIM_SYSTEM must be clipmap, vt or terrain" >&2; exit 2 ;;
esac
if [ "$system" = terrain ]; then
  # shellcheck disable=SC2206  # VTSIM_SETS is a word list
  common=(--config "$here/docs/examples/terrain.toml" -q ${VTSIM_SETS:-})
  # The calibration walk: 20 s from another start and heading than traces/walk.csv (the default
  # walk: east from the terrain's centre), so the fit is not checked on the tiles it was made from.
  "$vtsim" trace gen walk --start 2000,6000 --heading 120 --duration 20 -o "$out/calib_walk.csv"
  "$vtsim" replay --clock real --trace "$out/calib_walk.csv" "${common[@]}" --produce-samples "$out/calib_tiles.csv" \
    --summary "$out/calib.real.json"
  "$vtsim" calibrate --samples "$out/calib_tiles.csv" -o "$out/profile.toml" -q
  # The fitted profile read after the terrain's own config (its [produce] keys override).
  "$vtsim" replay --clock sim --trace "$here/traces/walk.csv" "${common[@]}" --config "$out/profile.toml" \
    --summary "$out/walk.sim.json"
  for i in $(seq 1 "$runs"); do
    "$vtsim" replay --clock real --trace "$here/traces/walk.csv" "${common[@]}" --summary "$out/walk.real.$i.json"
  done
  python3 - "$out" "$runs" <<'PY'
import json, statistics, sys
out, runs = sys.argv[1], int(sys.argv[2])
def get(d):
    p = d["resources"]["produce_ms_per_frame"]
    return p["mean"], p["p95"], d["produce"]["mean_ms_per_tile"], d["produce"]["produced"]
sim = get(json.load(open(f"{out}/walk.sim.json")))
real = [get(json.load(open(f"{out}/walk.real.{i}.json"))) for i in range(1, runs + 1)]
print(f"{'metric':22} {'simulated':>10} {'real (median of %d)' % runs:>20} {'real runs':>26} {'error':>7}")
worst = 0
for k, name in enumerate(("produce ms/frame mean", "produce ms/frame p95", "produce ms/tile", "tiles produced")):
    vals = [r[k] for r in real]
    med = statistics.median(vals)
    err = (sim[k] - med) / med if med else 0.0
    if k < 3: worst = max(worst, abs(err))
    print(f"{name:22} {sim[k]:10.3f} {med:20.3f} {' '.join(f'{v:.3f}' for v in vals):>26} {100*err:+6.1f}%")
print(f"worst error {100*worst:.1f}% (target 15%; production per frame and per tile)")
PY
  exit 0
fi
store=$out/terrain16k-b$border.vts
if [ ! -f "$store" ]; then
  "$vtsim" store gen -o "$store" --size 16384x16384 --tile 128 --border $border --layers albedo:zstd,normal:lz4 --seed 1
fi
# shellcheck disable=SC2086  # VTSIM_CALIBRATE is a word list
"$vtsim" calibrate --store "$store" -o "$out/profile.toml" -q ${VTSIM_CALIBRATE:-}
# shellcheck disable=SC2206  # VTSIM_SETS is a word list
common=(--system "$system" --store "$store" --config "$out/profile.toml" -q ${VTSIM_SETS:-})
if [ "$system" = clipmap ]; then
  # The store covers 512 m x 512 m at 32 texels/m around the traces' start (4096, 4096); the
  # drive (400 m east) stays inside it.
  common+=(--set texture.texels_per_m=32 --set texture.origin_x_m=4040 --set texture.origin_y_m=3840)
  names=(walk drive); traces=("$here/traces/walk.csv" "$here/traces/drive.csv"); extra=("" "")
else
  # The test town's faces fit 16384² texels at 4 texels/m.
  common+=(--set scene.kind=town --set texture.texels_per_m=4)
  names=(town_walk town_walk_x4); traces=("$here/tests/data/town_walk.csv" "$here/tests/data/town_walk.csv")
  extra=("" "--speed 4")
fi
for k in 0 1; do
  t=${names[$k]}
  # shellcheck disable=SC2086  # extra is a word list
  "$vtsim" replay --clock sim --trace "${traces[$k]}" "${common[@]}" ${extra[$k]} --summary "$out/$t.sim.json"
  for i in $(seq 1 "$runs"); do
    # shellcheck disable=SC2086
    "$vtsim" replay --clock real --trace "${traces[$k]}" "${common[@]}" ${extra[$k]} --summary "$out/$t.real.$i.json"
  done
done
python3 - "$out" "$runs" "${names[@]}" <<'PY'
import json, statistics, sys
out, runs, names = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
def get(d):
    return d["latency_ms"]["p50"], d["latency_ms"]["p95"], d["bandwidth"]["disk_read_MBps"]
print(f"{'trace':12} {'metric':16} {'simulated':>10} {'real (median of %d)' % runs:>20} {'real runs':>26} {'error':>7}")
worst = 0
for t in names:
    sim = get(json.load(open(f"{out}/{t}.sim.json")))
    real = [get(json.load(open(f"{out}/{t}.real.{i}.json"))) for i in range(1, runs + 1)]
    for k, name in enumerate(("latency p50 ms", "latency p95 ms", "disk MB/s")):
        vals = [r[k] for r in real]
        med = statistics.median(vals)
        err = (sim[k] - med) / med if med else 0.0
        worst = max(worst, abs(err))
        print(f"{t:12} {name:16} {sim[k]:10.2f} {med:20.2f} {' '.join(f'{v:.1f}' for v in vals):>26} {100*err:+6.1f}%")
print(f"worst error {100*worst:.1f}% (target 15%)")
PY
