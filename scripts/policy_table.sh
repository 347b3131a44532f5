#!/usr/bin/env bash
# The policy table of docs/cache.md ("The policy table"): every replacement policy of the VT page
# pool at three pool sizes, on the standard traces and the real recordings, through the full
# pipeline with metrics.opt (the same accesses replayed offline and Belady's bound beside).
#   scripts/policy_table.sh [--vtsim PATH] [OUT]        (default OUT: out/policy-table)
# Writes OUT/plane and OUT/town (two sweeps: the plane's traces and the town's walk differ in
# scene, so in view) and prints the Markdown tables docs/cache.md quotes.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
vtsim=$here/build/vtsim
if [ "${1:-}" = --vtsim ]; then vtsim=$(realpath "$2"); shift 2; fi
out=${1:-out/policy-table}
mkdir -p "$out/traces"
real=$here/../shared/traces-real
# The real recordings onto the terrain, as docs/performance.md imports them: handheld (TUM
# fr1_xyz, room scale) and drone (EuRoC V1_02, 10x larger).
"$vtsim" trace import --recenter --offset 4096,4096,1.7 "$real/tum_fr1_xyz_groundtruth.txt" -o "$out/traces/handheld.csv" >/dev/null
"$vtsim" trace import --scale 10 --recenter --offset 4096,4096,30 "$real/euroc_V1_02_groundtruth.csv" -o "$out/traces/drone.csv" >/dev/null
cp "$here/traces/turn.csv" "$here/traces/drive.csv" "$here/traces/flight.csv" "$here/traces/orbit.csv" "$here/traces/walk.csv" "$out/traces/"
cp "$here/tests/data/town_walk.csv" "$out/traces/"
policies='["lru", "clock", "s3fifo", "arc", "level_lru"]'
cat > "$out/plane.toml" <<SPEC
name = "VT pool policies, plane"
set = ["run.system=vt", "metrics.opt=true", "texture.border=4", "disk.preset=hdd"]
traces = ["traces/turn.csv", "traces/drive.csv", "traces/flight.csv", "traces/orbit.csv", "traces/walk.csv", "traces/handheld.csv", "traces/drone.csv"]
metrics = ["vt.pool.misses", "vt.pool.bounds.policy_offline_misses", "vt.pool.bounds.opt_misses", "popin.blurry_fraction_mean", "popin.time_to_sharp_s.mean"]
[grid]
"vt.pool_pages" = [128, 192, 256]
"vt.pool_policy" = $policies
SPEC
cat > "$out/town.toml" <<SPEC
name = "VT pool policies, town"
set = ["run.system=vt", "scene.kind=town", "metrics.opt=true"]
traces = ["traces/town_walk.csv"]
metrics = ["vt.pool.misses", "vt.pool.bounds.policy_offline_misses", "vt.pool.bounds.opt_misses", "popin.blurry_fraction_mean", "popin.time_to_sharp_s.mean"]
[grid]
"vt.pool_pages" = [250, 300, 400]
"vt.pool_policy" = $policies
SPEC
for s in plane town; do "$vtsim" sweep "$out/$s.toml" -o "$out/$s" -q; done
for s in plane town; do
  "$vtsim" sweep table "$out/$s" --rows trace_file,vt.pool_pages --col vt.pool_policy --digits 3 \
    --metric vt.pool.misses --metric vt.pool.bounds.policy_offline_misses --metric vt.pool.bounds.opt_misses \
    --metric popin.blurry_fraction_mean --metric popin.time_to_sharp_s.mean
done
