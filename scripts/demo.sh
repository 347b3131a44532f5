#!/usr/bin/env bash
# README's main job: installs what is missing, builds, runs the default replay (a clipmap streaming
# a 2^20 x 2^20 texel terrain texture while the standard walk trace plays, NVMe-class disk, simulated
# clock), prints its summary and writes the report to out/ (report.html, summary.json, frames.csv).
# Extra arguments go to `vtsim replay` (e.g. --trace traces/drive.csv --set disk.preset=hdd).
# Builds the CLI only (the tests and benchmarks build when scripts/test.sh or bench/run needs them);
# the build's progress goes to stderr, ninja's [n/N] lines.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
cd "$here"
echo "demo: installing what is missing and building build/vtsim (progress below)" >&2
bash scripts/setup.sh build --target vtsim >&2
mkdir -p out
./build/vtsim replay --trace traces/walk.csv --summary out/summary.json --frames out/frames.csv --report out/report.html "$@"
echo "report: out/report.html (charts), out/summary.json (every metric, docs/metrics.md), out/frames.csv (one row per frame)"
