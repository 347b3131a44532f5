#!/usr/bin/env bash
# Regenerates the CI regression baselines tests/baselines/*.json (all cases, or the NAMEs given)
# with build/vtsim; review `git diff tests/baselines` and commit them with the change that
# explains them. Usage: scripts/update_baselines.sh [--vtsim PATH] [NAME...]  (docs/compare.md)
set -euo pipefail
exec bash "$(dirname "$0")/baselines.sh" update "$@"
