#!/usr/bin/env bash
# Installs vtsim's build dependencies from Debian if any is missing (idempotent), then configures
# and builds one build tree.  Usage: scripts/setup.sh [BUILD_DIR] [extra cmake args...]
#   scripts/setup.sh --packages-only      -> installs the packages only
#   scripts/setup.sh build --target vtsim -> builds that target only (the demo)
#   scripts/setup.sh                      -> build/ (Release), produces build/vtsim
#   scripts/setup.sh build-asan -DVTSIM_SANITIZE=address -DCMAKE_BUILD_TYPE=RelWithDebInfo
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
cd "$here"

# pybind11-dev python3-dev python3-numpy: the Python module (docs/python.md; its results are numpy arrays).
# openimageio-tools: Debian's OpenImageIOTargets.cmake references /usr/bin/iconvert etc., and
# --no-install-recommends would leave them out, failing find_package(OpenImageIO).
PKGS=(build-essential cmake pkg-config git
      libopenimageio-dev openimageio-tools libglm-dev doctest-dev libcli11-dev nlohmann-json3-dev
      libtomlplusplus-dev libfmt-dev libzstd-dev liblz4-dev liburing-dev libassimp-dev zlib1g-dev libxxhash-dev fio python3 ninja-build
      libepoxy-dev libegl-dev libegl-mesa0 libgl1-mesa-dri
      pybind11-dev python3-dev python3-numpy)

. scripts/packages.sh
ensure_packages "${PKGS[@]}"
[ "${1:-}" != --packages-only ] || exit 0

build=${1:-build}
shift || true
# --target T (repeatable) builds only those targets; everything else goes to cmake.
cmake_args=() targets=()
while (($#)); do
  if [ "$1" = --target ] && [ $# -ge 2 ]; then targets+=(--target "$2"); shift 2
  else cmake_args+=("$1"); shift; fi
done
set -- "${cmake_args[@]}"
gen=()
command -v ninja >/dev/null 2>&1 && gen=(-G Ninja)
if [ ! -f "$build/CMakeCache.txt" ]; then
  cmake -S . -B "$build" "${gen[@]}" -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
else
  cmake -S . -B "$build" "$@" >/dev/null
fi
cmake --build "$build" -j"$(nproc)" "${targets[@]}"
