#!/usr/bin/env bash
# The CI regression baselines (docs/compare.md): short deterministic replays in the simulated clock,
# each compared with its committed summary in tests/baselines/ by `vtsim compare --strict`.
#   scripts/baselines.sh check  [--vtsim PATH] [--out DIR] [--quick] [NAME...]
#   scripts/baselines.sh update [--vtsim PATH] [NAME...]      (scripts/update_baselines.sh)
# check: exit 0 when every summary matches its baseline (timings `run.*` and the build ignored,
# everything else exact, floats within max(1e-12, 1e-9 relative)), 1 on any difference (a regression, or an improvement whose baseline was not updated),
# 2 on a usage error or a missing baseline. --quick runs only the cases marked quick (the
# sanitizer builds: the same code paths, less time). update: rewrites the baselines; review
# `git diff tests/baselines` and commit them with the change that explains them.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
cd "$here"

# One line per case: name, system, quick (1: also in sanitizer builds), trace, then --set overrides.
# Adding a case (e.g. the VT system: "walk_vt  vt  1  traces/walk.csv") is one line here, then
# scripts/update_baselines.sh walk_vt.
CASES=(
  "walk_clipmap         clipmap  1  traces/walk.csv"
  "turn_clipmap         clipmap  0  traces/turn.csv"
  "teleport_clipmap     clipmap  0  traces/teleport.csv"
  "flight_clipmap       clipmap  0  traces/flight.csv"
  "drive_hdd_clipmap    clipmap  1  traces/drive.csv  disk.preset=hdd"
  "walk_faults_clipmap  clipmap  0  traces/walk.csv   io.fault_rate=0.02"
  "flight_vt            vt       1  traces/flight.csv vt.pool_pages=160 texture.border=4 throttle.policy=rage_watermarks"
  "town_walk_vt         vt       1  tests/data/town_walk.csv scene.kind=town"
  "town_walk_unreal_vt  vt       0  tests/data/town_walk.csv scene.kind=town vt.pool_pages=96 texture.border=4 throttle.policy=unreal_bias"
)
dir=tests/baselines
tolerances=$dir/tolerances.toml

usage() { sed -n '2,11p' "$0" | sed 's/^# \{0,1\}//'; }
mode=${1:-}
case $mode in
  check | update) shift ;;
  -h | --help) usage; exit 0 ;;
  *) usage >&2; exit 2 ;;
esac
vtsim=build/vtsim
out=build/baselines
quick=0
only=()
while (($#)); do
  case $1 in
    --vtsim | --out)
      [ $# -ge 2 ] || { echo "baselines: $1 needs a value" >&2; exit 2; }
      if [ "$1" = --vtsim ]; then vtsim=$2; else out=$2; fi
      shift 2 ;;
    --quick) quick=1; shift ;;
    -h | --help) usage; exit 0 ;;
    -*) echo "baselines: unknown option '$1'" >&2; exit 2 ;;
    *) only+=("$1"); shift ;;
  esac
done
if [ ! -x "$vtsim" ]; then
  echo "baselines: no vtsim at '$vtsim' (build it: bash scripts/setup.sh build)" >&2
  exit 2
fi
for name in "${only[@]}"; do
  printf '%s\n' "${CASES[@]}" | awk '{print $1}' | grep -qx -- "$name" || { echo "baselines: no case '$name'" >&2; exit 2; }
done

mkdir -p "$out"
passed=0 failed=0 skipped=0
for line in "${CASES[@]}"; do
  read -r name system in_quick trace sets <<<"$line"
  if ((${#only[@]})) && ! printf '%s\n' "${only[@]}" | grep -qx -- "$name"; then continue; fi
  if [ "$mode" = check ] && ((quick)) && [ "$in_quick" != 1 ]; then skipped=$((skipped + 1)); continue; fi
  args=(replay --quiet --trace "$trace" --system "$system")
  for s in $sets; do args+=(--set "$s"); done
  if [ "$mode" = update ]; then
    "$vtsim" "${args[@]}" --summary "$out/$name.json"
    # The run's own cost (run.*) differs on every run, the build (provenance: version, commit,
    # compiler) with every commit; neither is compared: leave them out so that the reviewed diff
    # shows only behaviour (and the run's config and trace identity).
    python3 - "$out/$name.json" "$dir/$name.json" <<'PY'
import json, sys
with open(sys.argv[1]) as f:
    d = json.load(f)
d.pop("run", None)
d.pop("provenance", None)
with open(sys.argv[2], "w") as f:
    json.dump(d, f, indent=2)
    f.write("\n")
PY
    echo "baselines: wrote $dir/$name.json"
    continue
  fi
  if [ ! -f "$dir/$name.json" ]; then
    echo "baselines: $dir/$name.json is missing: run scripts/update_baselines.sh $name and commit it" >&2
    exit 2
  fi
  echo "== $name: vtsim ${args[*]}"
  "$vtsim" "${args[@]}" --summary "$out/$name.json"
  if "$vtsim" compare --strict --tolerances "$tolerances" "$dir/$name.json" "$out/$name.json"; then
    passed=$((passed + 1))
  else
    rc=$?
    ((rc == 1)) || exit "$rc"
    failed=$((failed + 1))
  fi
done
if [ "$mode" = update ]; then
  echo "baselines: review with 'git diff $dir' and commit"
  exit 0
fi
echo "baselines: $passed passed, $failed failed, $skipped skipped (not in --quick)"
if ((failed)); then
  echo "baselines: a simulated metric changed. If the change is intended, run scripts/update_baselines.sh," >&2
  echo "baselines: review 'git diff $dir' and commit the new baselines with the change." >&2
  exit 1
fi
