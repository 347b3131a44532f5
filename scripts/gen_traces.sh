#!/usr/bin/env bash
# Regenerates the standard traces in traces/ (20 s at 60 Hz each, defaults in docs/traces.md)
# with the built CLI. Long traces are made on demand, e.g.:
#   build/vtsim trace gen flight --duration 600 -o flight_10min.csv
# Usage: scripts/gen_traces.sh [VTSIM_BINARY] [OUT_DIR]
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
vtsim=${1:-$here/build/vtsim}
out=${2:-$here/traces}
if [ ! -x "$vtsim" ]; then
  echo "gen_traces: $vtsim not found; build first (bash scripts/setup.sh build)" >&2
  exit 2
fi
mkdir -p "$out"
for kind in walk walk_diagonal run drive flight turn teleport orbit static; do
  "$vtsim" trace gen "$kind" -o "$out/$kind.csv"
done
