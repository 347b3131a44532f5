#!/usr/bin/env bash
# The simulated clock against the GL client (docs/gpu.md, "Simulated vs GPU"): for each trace, the
# same virtual texture streamed by `vtsim gl replay` (llvmpipe or a GPU, the real clock, REPS runs)
# and replayed by `vtsim replay` in the simulated clock with the GPU's feedback model, with the
# GPU's measurement (pop-in at every full-resolution pixel: view.popin_divisor = 1) and the GPU's
# readback latency (view.feedback_latency = K, the GL client's too). Prints, per trace, blurry mean
# and p95, tiles uploaded and latency p50 / p95 (ms and frames) of both, and the simulated figure
# relative to the GL runs' median.
# Traces (640x360, 60 Hz): walk and drive of the plane (10 s), the town walk (10 s), and an
# OpenArena level walk (20 s of oa_dm1; scripts/fetch_levels.sh installs openarena-data).
# Usage: scripts/sim_vs_gl.sh [OUT_DIR] [REPS] [K]      (default build/sim_vs_gl, 3, 2; needs build/vtsim
#        with GL). VTSIM_SIM_VS_GL_TRACES="walk drive town level" picks traces; VTSIM_SIM_VS_GL_FPS
#        (default 60) the frame rate both replay at (run.fps): latencies in ms agree only while the GL
#        client holds it (its summary's gl.frames_per_s); in frames they agree at any rate.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$here/build/sim_vs_gl}
reps=${2:-3}
k=${3:-2}
[[ $reps =~ ^[1-9][0-9]*$ ]] || { echo "sim_vs_gl: REPS must be a positive integer" >&2; exit 2; }
[[ $k =~ ^[0-9]+$ ]] || { echo "sim_vs_gl: K must be a non-negative integer" >&2; exit 2; }
vtsim=${VTSIM:-$here/build/vtsim}
[ -x "$vtsim" ] || { echo "sim_vs_gl: $vtsim not built (bash scripts/setup.sh build)" >&2; exit 2; }
traces=${VTSIM_SIM_VS_GL_TRACES:-walk drive town level}
mkdir -p "$out"
cd "$out"
export LP_NUM_THREADS=${LP_NUM_THREADS:-2}

# Stores of 4096² and 8192² texels (the town's faces need the larger at 2 texels/m), 128-texel
# pages with 4-texel borders, one zstd layer.
store() { [ -f "t$1.vts" ] || "$vtsim" store gen -o "t$1.vts" --size "$2x$2" --tile 128 --border 4 --layers albedo:zstd --feature 1024 >/dev/null; }
fps=${VTSIM_SIM_VS_GL_FPS:-60}
common=(--set view.lod_model=gpu --set view.popin_divisor=1 --set "view.feedback_latency=$k" --set "run.fps=$fps")
declare -A sets
for t in $traces; do
  s=4k
  case $t in
    walk)  [ -f walk.csv ] || "$vtsim" trace gen walk -o walk.csv --duration 10 --start 64,64 --image 640x360
           sets[$t]="--set texture.texels_per_m=32" ;;
    drive) [ -f drive.csv ] || "$vtsim" trace gen drive -o drive.csv --duration 10 --start 14,64 --speed 10 --image 640x360
           sets[$t]="--set texture.texels_per_m=32" ;;
    town)  [ -f town.csv ] || "$vtsim" trace gen walk -o town.csv --duration 10 --start 30,8 --image 640x360
           s=8k; sets[$t]="--set scene.kind=town --set texture.texels_per_m=2" ;;
    level) bash "$here/scripts/fetch_levels.sh" -o levels oa_dm1 >/dev/null
           if [ ! -f level.csv ]; then
             "$vtsim" trace level-walk levels/oa_dm1.bsp --mesh levels/oa_dm1.pk3 -o level_full.csv --image 640x360 2>/dev/null
             "$vtsim" trace cut level_full.csv -o level.csv --from 0 --to 20
           fi
           sets[$t]="--set scene.kind=mesh --set scene.file=$out/levels/oa_dm1.pk3 --set scene.mesh_unit_m=0.0254" ;;
    *) echo "sim_vs_gl: unknown trace '$t' (walk drive town level)" >&2; exit 2 ;;
  esac
  if [ $s = 8k ]; then store 8k 8192; else store 4k 4096; fi
  # shellcheck disable=SC2086
  "$vtsim" replay -q --system vt -t "$t.csv" --store "t$s.vts" ${sets[$t]} "${common[@]}" --summary "${t}_sim.json" 2>/dev/null
  for ((i = 1; i <= reps; ++i)); do
    # shellcheck disable=SC2086
    "$vtsim" gl replay -t "$t.csv" --store "t$s.vts" ${sets[$t]} "${common[@]}" --summary "${t}_gl$i.json" >/dev/null 2>"${t}_gl$i.log"
  done
done

python3 - "$reps" $traces <<'PY'
import json, statistics, sys
reps, traces = int(sys.argv[1]), sys.argv[2:]
def fig(s):
    p, l, lf = s["popin"], s["latency_ms"], s["latency_ms"].get("frames", {})
    return {"blurry mean": p["blurry_fraction_mean"], "blurry p95": p["blurry_fraction_p95"],
            "tiles uploaded": s["bandwidth"]["uploads"], "latency p50 ms": l["p50"], "latency p95 ms": l["p95"],
            "latency p50 frames": lf.get("p50"), "latency p95 frames": lf.get("p95")}
print(f"| trace | figure | simulated | GL median of {reps} (min–max) | simulated / GL |")
print("|---|---|---:|---:|---:|")
for t in traces:
    sim = fig(json.load(open(f"{t}_sim.json")))
    gls = [fig(json.load(open(f"{t}_gl{i}.json"))) for i in range(1, reps + 1)]
    for key, v in sim.items():
        g = [x[key] for x in gls]
        if v is None or None in g: continue
        med = statistics.median(g)
        ratio = f"{v / med:.3f}" if med else ("1 (both 0)" if v == 0 else "—")
        fmt = (lambda x: f"{x:.5f}") if "blurry" in key else (lambda x: f"{x:.4g}")
        print(f"| {t} | {key} | {fmt(v)} | {fmt(med)} ({fmt(min(g))}–{fmt(max(g))}) | {ratio} |")
PY
