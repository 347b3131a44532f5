#!/usr/bin/env bash
# ctest sweep_slurm (label slurm): a sweep run as a 4-task Slurm job array on a real single-node
# cluster on this machine (scripts/slurm_local.sh), its shards merged, gives byte for byte the
# outputs of the same sweep run unsharded: rows.jsonl, rows.csv and report.html (sweep.json holds
# timings and may differ). Exit 77 (skipped) when not root: the cluster's daemons run as root.
#   tests/slurm/sweep_slurm.sh VTSIM SRCDIR WORKDIR
set -euo pipefail
[ $# -eq 3 ] || { echo "usage: $0 VTSIM SRCDIR WORKDIR" >&2; exit 2; }
if [ "$(id -u)" -ne 0 ]; then
  echo "sweep_slurm: needs root for the local Slurm cluster (scripts/slurm_local.sh); skipped" >&2
  exit 77
fi
vtsim=$(realpath "$1")
src=$(cd "$2" && pwd)
mkdir -p "$3"
work=$(cd "$3" && pwd)
cluster=$work/cluster
slurm_local=$src/scripts/slurm_local.sh
t0=$SECONDS

# A cluster left by an earlier run that was killed (a ctest timeout sends SIGKILL: no trap runs).
bash "$slurm_local" stop "$cluster" >/dev/null
rm -rf "$work"/local "$work"/merged "$work"/shard-* "$work"/logs "$work"/traces
mkdir -p "$work"/logs "$work"/traces
stop_cluster() { bash "$slurm_local" stop "$cluster" >/dev/null || true; }
trap stop_cluster EXIT
trap 'exit 130' INT TERM HUP

# 2 x 2 config points on 2 traces of 20 s: 8 rows, a few seconds under ASan.
cp "$src"/traces/walk.csv "$src"/traces/turn.csv "$work"/traces/
spec=$work/spec.toml
cat >"$spec" <<'TOML'
name = "slurm shards"
traces = ["traces/walk.csv", "traces/turn.csv"]
[grid]
"upload.tiles_per_frame" = [4, 16]
"ram.capacity_MiB" = [64, 256]
TOML

"$vtsim" sweep "$spec" -o "$work"/local --quiet
echo "sweep_slurm: local sweep done ($((SECONDS - t0)) s)"

t1=$SECONDS
bash "$slurm_local" start "$cluster"
export SLURM_CONF=$cluster/slurm.conf
echo "sweep_slurm: cluster up ($((SECONDS - t1)) s)"

# Each array task runs its shard; sbatch --wait returns when all have ended, non-zero if any
# failed. The job gets this environment (ASAN_OPTIONS and all).
t2=$SECONDS
job="exec $(printf '%q' "$vtsim") sweep $(printf '%q' "$spec") --shard slurm"
job+=" -o $(printf '%q' "$work")/shard-\$SLURM_ARRAY_TASK_ID --quiet"
if ! sbatch --array=0-3 --wait --quiet --job-name=vtsim-sweep --time=10 --chdir="$work" \
     --output="$work/logs/shard-%a.out" --wrap "$job"; then
  echo "sweep_slurm: the job array failed; its logs:" >&2
  for f in "$work"/logs/*.out; do echo "---- $f" >&2; tail -n 20 "$f" >&2; done
  exit 1
fi
echo "sweep_slurm: job array done ($((SECONDS - t2)) s)"
for i in 0 1 2 3; do
  [ -f "$work/shard-$i/shard.json" ] || { echo "sweep_slurm: shard-$i has no shard.json" >&2; exit 1; }
done

"$vtsim" sweep merge -o "$work"/merged "$work"/shard-0 "$work"/shard-1 "$work"/shard-2 "$work"/shard-3

fail=0
for f in rows.jsonl rows.csv report.html; do
  if ! cmp "$work/local/$f" "$work/merged/$f"; then
    fail=1
    echo "sweep_slurm: $f differs between the unsharded sweep and the merged shards:" >&2
    diff -u "$work/local/$f" "$work/merged/$f" | head -n 40 >&2 || true
  fi
done
[ "$fail" = 0 ] || exit 1
echo "sweep_slurm: rows.jsonl, rows.csv, report.html identical ($((SECONDS - t0)) s in all)"
