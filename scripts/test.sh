#!/usr/bin/env bash
# The test command: installs what is missing, builds, and runs the suite in three builds —
# Release (-Werror) and ASan+UBSan run all of ctest; TSan runs the doctest suite "threads" (the
# threaded code). Idempotent; exits non-zero on any failure.
# VTSIM_TEST_VARIANTS="release asan tsan" selects variants (all three by default).
#
# Phases overlap where a core would otherwise idle (docs/bench.md, "CI time"): the packages only
# the tests need (Slurm, munge, Chromium) install in the background while the first variant builds,
# and each further variant compiles at a lower priority (nice 10) while the previous variant's tests
# run, which leave a core idle for long stretches (serial tests, a browser, a Slurm job, the
# install test's configure). A variant's tests start only once its own build has finished; a build
# failure fails the run with its log. Logs of background steps: out/test-logs/.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
cd "$here"
variants=${VTSIM_TEST_VARIANTS:-"release asan tsan"}
jobs=$(nproc)
# CPU seconds (user+sys) of this script's finished children so far, for the phase lines: on a shared
# machine CPU time is the steadier figure (wall time depends on what else runs).
tck=$(getconf CLK_TCK)
cpu() { local s; read -ra s < /proc/$$/stat; echo $(( (s[15] + s[16]) / tck )); }
phase() { echo "== $1 at $(date -u +%T), ${SECONDS}s into the run, $(cpu)s CPU"; }

# Sanitizer builds at -O1 with line tables only (-g1): ASan+UBSan at -O2 -g compiled 2x slower
# (37.6 s vs 18.7 s for src/sim/compare/compare.cpp) for stack traces that -g1 already gives file:line.
# ASan+UBSan compiles with clang (Debian's clang 14); Release and TSan with GCC: under ASan+UBSan clang
# took 51 s against GCC's 81 s of CPU for the largest library batch at -O1, 17-18 s against 31-34 s
# for a test batch at -O0 (docs/bench.md, "CI time"). Two compilers also see more warnings.
san=(-DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1")
dirs=() ; argsets=()
for v in $variants; do
  case $v in
    release) dirs+=(build);      argsets+=("") ;;
    asan)    dirs+=(build-asan); argsets+=("-DVTSIM_SANITIZE=address") ;;
    # TSan builds what its phase runs: the threaded test files, the corpus runner (and the CLI and
    # image module the tests call); not the GL client.
    tsan)    dirs+=(build-tsan); argsets+=("-DVTSIM_SANITIZE=thread -DVTSIM_TESTS_THREADS_ONLY=ON -DVTSIM_BUILD_GL=OFF --target vtsim_tests --target vtsim_fuzz_corpus") ;;
    *) echo "test.sh: unknown variant '$v' (release|asan|tsan)" >&2; exit 2 ;;
  esac
done
vs=($variants)
# build I [nice]: configure and build variant I (scripts/setup.sh).
build() {
  local i=$1 extra=() pre=()
  read -ra extra <<< "${argsets[$i]}"
  [ "${vs[$i]}" = release ] || extra+=("${san[@]}")
  [ -z "${2:-}" ] || pre=(setsid nice -n 10)
  # clang when installed (root runs install it; GCC otherwise); takes effect at the first configure.
  # TSan stays on GCC until its clang build is checked (its suppressions name GCC's runtime paths).
  if [ "${vs[$i]}" = asan ] && command -v clang++ >/dev/null; then pre=(env CC=clang CXX=clang++ "${pre[@]}"); fi
  "${pre[@]}" bash scripts/setup.sh "${dirs[$i]}" "${extra[@]}"
}
logs=out/test-logs
mkdir -p "$logs"
bg=()
# Background steps run in their own process groups (setsid): a failing run stops them whole.
trap 'for p in "${bg[@]}"; do kill -- "-$p" 2>/dev/null || true; done' EXIT

# The build's own packages first, then, in the background while the first variant builds, those
# only tests use: the ctest sweep_slurm starts a local Slurm cluster (scripts/slurm_local.sh; root
# only), report_browser renders the reports in Debian's chromium, python_module makes a pandas
# DataFrame of a sweep's rows, the gl tests encode a video with ffmpeg; and clang with its sanitizer
# runtimes for the ASan and TSan builds (waited for before they start).
pkg_pid=
bg_pkgs="slurm-wlm munge chromium python3-pandas ffmpeg clang libclang-rt-dev"
if [ "$(id -u)" -eq 0 ]; then
  phase "packages"
  bash scripts/setup.sh --packages-only
  setsid bash -c ". scripts/packages.sh; ensure_packages $bg_pkgs" > "$logs/packages.log" 2>&1 &
  pkg_pid=$!; bg+=("$pkg_pid")
fi
wait_packages() {
  [ -n "$pkg_pid" ] || return 0
  wait "$pkg_pid" || { cat "$logs/packages.log" >&2; echo "test.sh: installing $bg_pkgs failed" >&2; exit 1; }
  pkg_pid=
}

export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
export LSAN_OPTIONS=suppressions=$here/scripts/lsan.supp:print_suppressions=0
export TSAN_OPTIONS=halt_on_error=1:second_deadlock_stack=1:suppressions=$here/scripts/tsan.supp:print_suppressions=0

phase "${vs[0]}: build (${dirs[0]})"
[ "${vs[0]}" = release ] || wait_packages
build 0
for ((i = 0; i < ${#vs[@]}; i++)); do
  v=${vs[$i]} dir=${dirs[$i]} next_pid=
  # The next variant compiles, niced, while this one's tests run.
  wait_packages  # the tests (Slurm, Chromium, pandas, ffmpeg) and the next build (clang) need them
  if ((i + 1 < ${#vs[@]})); then
    phase "${vs[i+1]}: build (${dirs[i+1]}) starts beside the ${v} tests"
    build $((i + 1)) nice > "$logs/${vs[i+1]}-build.log" 2>&1 &
    next_pid=$!; bg+=("$next_pid")
  fi
  phase "$v: tests ($dir)"
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
  if [ -n "$next_pid" ]; then
    if ! wait "$next_pid"; then
      cat "$logs/${vs[i+1]}-build.log" >&2
      echo "test.sh: the ${vs[i+1]} build failed (log above: $logs/${vs[i+1]}-build.log)" >&2
      exit 1
    fi
    phase "${vs[i+1]}: build done"
  fi
done
phase "all test variants passed: $variants"
