#!/usr/bin/env bash
# Fuzzing (docs/robustness.md, "Fuzz targets"). Builds the libFuzzer targets of tests/fuzz with clang,
# ASan and UBSan in build-fuzz/, then runs each for SECONDS (default 60) starting from the
# checked-in corpus tests/fuzz/corpus/<target>/ (read only: new inputs go to fuzz-out/<target>/
# corpus/). Findings (crash-*, leak-*, timeout-*, oom-*) land in fuzz-out/<target>/; a finding of
# this run makes the exit status 1. To keep one as a regression input, copy it into the corpus directory:
# ctest fuzz_corpus then replays it in every build. Installs clang and libFuzzer if missing.
#   scripts/fuzz.sh [SECONDS] [TARGET...]      targets: the directories of tests/fuzz/corpus
#   scripts/fuzz.sh 600 obj                  (one target for ten minutes)
# The build is RelWithDebInfo at -O1 -g1 without -DNDEBUG: assertions stay on while fuzzing.
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
cd "$here"
usage() { echo "usage: scripts/fuzz.sh [SECONDS] [TARGET...] (targets: $(ls tests/fuzz/corpus | tr '\n' ' '))" >&2; exit 2; }
secs=${1:-60}
[[ $secs =~ ^[0-9]+$ ]] || usage
shift || true
targets=("$@")
((${#targets[@]})) || mapfile -t targets < <(ls tests/fuzz/corpus)
for t in "${targets[@]}"; do [ -d "tests/fuzz/corpus/$t" ] || usage; done

. scripts/packages.sh
ensure_packages clang libclang-rt-dev  # libFuzzer and the sanitizer runtimes of Debian's clang
# The other build dependencies, and the compiler choice only on the first configure.
CC=clang CXX=clang++ bash scripts/setup.sh build-fuzz -DVTSIM_SANITIZE=fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1" -DVTSIM_BUILD_TESTS=OFF -DVTSIM_BUILD_BENCH=OFF -DVTSIM_WERROR=OFF

export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
export LSAN_OPTIONS=suppressions=$here/scripts/lsan.supp:print_suppressions=0  # OpenImageIO's, as in test.sh
# The targets hand each input to the readers as a file (tests/fuzz/fuzz_util.cpp): on tmpfs, not the
# disk (trace_native spent 36 % of its CPU in the kernel with /tmp on disk).
if [ -d /dev/shm ] && [ -w /dev/shm ]; then export TMPDIR=/dev/shm; fi
status=0
stamp=$(mktemp)  # findings newer than this are this run's
trap 'rm -f "$stamp"' EXIT
for t in "${targets[@]}"; do
  exe=build-fuzz/fuzz/fuzz_$t
  [ -x "$exe" ] || { echo "fuzz: no target '$t'" >&2; exit 2; }
  out=fuzz-out/$t
  mkdir -p "$out/corpus"
  echo "== fuzz $t: ${secs}s"
  # -max_len: the store seeds are whole 4 KiB-aligned files (40 KiB); -timeout: one input taking
  # 10 s is a hang; -rss_limit_mb: the loaders' own limits must hold far below 2 GiB.
  if ! "$exe" -max_total_time="$secs" -timeout=10 -rss_limit_mb=2048 -max_len=65536 \
      -print_final_stats=1 \
      -artifact_prefix="$out/" "$out/corpus" "tests/fuzz/corpus/$t" > "$out/log.txt" 2>&1; then
    status=1
  fi
  grep -E "^(stat::number_of_executed_units|stat::peak_rss_mb)" "$out/log.txt" | tr '\n' ' ' || true
  echo
  found=$(find "$out" -maxdepth 1 -type f -newer "$stamp" \( -name 'crash-*' -o -name 'leak-*' -o -name 'timeout-*' -o -name 'oom-*' \) | wc -l)
  if [ "$found" -gt 0 ]; then
    status=1
    echo "fuzz $t: $found finding(s) in $out/ (log: $out/log.txt)"
  fi
done
exit $status
