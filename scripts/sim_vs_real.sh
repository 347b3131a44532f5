#!/usr/bin/env bash
# The calibration check of docs/real-engine.md §6: does the simulated clock, with this machine's
# calibrated profile, predict the real clock (latency p50 / p95, disk bandwidth) within 15%?
#   scripts/sim_vs_real.sh [OUT_DIR] [RUNS]      (default out/sim_vs_real, 3 real runs per trace)
# Makes a 16384² store (albedo zstd + normal lz4; ~2 min) if OUT_DIR has none, calibrates
# (`vtsim calibrate`), then replays two traces in both clocks with the same config (the profile)
# and prints the table. Extra replay options: VTSIM_SETS="--set k=v ...".
# VTSIM_SYSTEM=clipmap (default): no border, the standard walk and drive traces (§6).
# VTSIM_SYSTEM=vt: pages with a 4-texel border, the town walk at 1× and 4× (§7a).
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
  *) echo "sim_vs_real: VTSIM_SYSTEM must be clipmap or vt" >&2; exit 2 ;;
esac
store=$out/terrain16k-b$border.vts
if [ ! -f "$store" ]; then
  "$vtsim" store gen -o "$store" --size 16384x16384 --tile 128 --border $border --layers albedo:zstd,normal:lz4 --seed 1
fi
"$vtsim" calibrate --store "$store" -o "$out/profile.toml" -q
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
