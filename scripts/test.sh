#!/usr/bin/env bash
# The test command: installs what is missing, builds, and runs the suite in three builds —
# Release (-Werror) and ASan+UBSan run all of ctest; TSan runs the doctest suite "threads" (the
# threaded code). Idempotent; exits non-zero on any failure.
# VTSIM_TEST_VARIANTS="release asan tsan" selects variants (all three by default).
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
cd "$here"
variants=${VTSIM_TEST_VARIANTS:-"release asan tsan"}
jobs=$(nproc)
# CPU seconds (user+sys) of this script's finished children so far, for the phase lines: on a shared
# machine CPU time is the steadier figure (wall time depends on what else runs).
tck=$(getconf CLK_TCK)
cpu() { local s; read -ra s < /proc/$$/stat; echo $(( (s[15] + s[16]) / tck )); }
# The ctest sweep_slurm starts a local Slurm cluster (scripts/slurm_local.sh), as root only: its
# packages are installed here, before ctest runs tests in parallel; so is Debian's chromium, in
# which the ctest report_browser renders the HTML reports.
if [ "$(id -u)" -eq 0 ] && [[ $variants == *release* || $variants == *asan* ]]; then
  . scripts/packages.sh
  ensure_packages slurm-wlm munge chromium
fi
# Sanitizer builds at -O1 with line tables only (-g1): ASan+UBSan at -O2 -g compiled 2x slower
# (37.6 s vs 18.7 s for src/sim/run/compare.cpp) for stack traces that -g1 already gives file:line.
san=(-DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1" -DVTSIM_BUILD_BENCH=OFF)
for v in $variants; do
  case $v in
    release) dir=build;      args=() ;;
    asan)    dir=build-asan; args=(-DVTSIM_SANITIZE=address "${san[@]}") ;;
    tsan)    dir=build-tsan; args=(-DVTSIM_SANITIZE=thread  "${san[@]}" -DVTSIM_TESTS_THREADS_ONLY=ON) ;;
    *) echo "test.sh: unknown variant '$v' (release|asan|tsan)" >&2; exit 2 ;;
  esac
  echo "== $v: build ($dir) at $(date -u +%T), ${SECONDS}s into the run, $(cpu)s CPU"
  bash scripts/setup.sh "$dir" "${args[@]}"
  echo "== $v: ctest at $(date -u +%T), ${SECONDS}s into the run, $(cpu)s CPU"
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  export LSAN_OPTIONS=suppressions=$here/scripts/lsan.supp:print_suppressions=0
  export TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1:suppressions=$here/scripts/tsan.supp:print_suppressions=0
  if [ "$v" = tsan ]; then
    # TSan checks the threaded code: the doctest suite "threads" (IO and decode pools, threaded
    # executor, faults, real clock, store builder and generator) and the fuzz corpus of the
    # threaded targets. Release and ASan run everything.
    (cd "$dir/tests" && ./vtsim_tests --test-suite=threads --no-intro=true)
    # The fuzz corpus of the targets that run threads (docs/robustness.md).
    "$dir/tests/fuzz/vtsim_fuzz_corpus" tests/fuzz/corpus config store_replay
  else
    ctest --test-dir "$dir" --output-on-failure -j"$jobs" --timeout 600
  fi
done
echo "== all test variants passed: $variants (${SECONDS}s, $(cpu)s CPU)"
