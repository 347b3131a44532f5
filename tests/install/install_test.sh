#!/usr/bin/env bash
# Installs the build tree into a fresh prefix, then configures and builds tests/install/consumer
# (a separate project: find_package(vtsim), vtsim::lib) against it alone and runs it: its replay
# through the library must equal the installed CLI's summary section by section. Also checks that
# the installed CLI runs from the prefix (its image module found in lib/vtsim).
# With PYTHON (the interpreter the module was built for) and PY_DIR (its install directory under the
# prefix), also imports the module vtsim from the prefix and checks its replay against the CLI's.
# Usage: install_test.sh BUILD_DIR SOURCE_DIR WORK_DIR [PYTHON PY_DIR]
set -euo pipefail
build=$1 src=$2 work=$3 python=${4:-} py_dir=${5:-}
rm -rf "$work" && mkdir -p "$work"
prefix=$work/prefix
cmake --install "$build" --prefix "$prefix" >"$work/install.log"
for f in bin/vtsim lib/cmake/vtsim/vtsimConfig.cmake include/vtsim/sim/run/replay.h share/vtsim/traces/walk.csv; do
  [ -e "$prefix/$f" ] || { echo "install_test: $prefix/$f was not installed" >&2; exit 1; }
done
ls "$prefix"/lib*/vtsim/libvtsim_image.so >/dev/null
if [ -e "$prefix/include/vtsim/core/toml_text.h" ] || [ -d "$prefix/include/vtsim/cli" ]; then
  echo "install_test: library-internal headers were installed" >&2; exit 1
fi
gen=()
command -v ninja >/dev/null && gen=(-G Ninja)
cmake -S "$src/tests/install/consumer" -B "$work/consumer" "${gen[@]}" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$prefix" -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF >"$work/configure.log"
cmake --build "$work/consumer" >"$work/build.log" 2>&1 || { cat "$work/build.log" >&2; exit 1; }

trace=$work/walk.csv
"$prefix/bin/vtsim" trace gen walk --duration 3 -o "$trace"
sets=(texture.width=65536 texture.height=65536)
set_args=()
for s in "${sets[@]}"; do set_args+=(--set "$s"); done
# The installed CLI, away from its build tree: a replay, and a PNG (written through the image
# module, which it must find in the prefix's lib/vtsim).
"$prefix/bin/vtsim" replay --trace "$trace" "${set_args[@]}" --summary "$work/cli.json" -q
# LD_DEBUG=files names the module the loader opened: the prefix's, not the build tree's.
VTSIM_IMAGE_MODULE= LD_DEBUG=files "$prefix/bin/vtsim" view --size 64x36 -o "$work/view.png" >/dev/null 2>"$work/ld.log"
[ -s "$work/view.png" ] || { echo "install_test: the installed vtsim wrote no PNG" >&2; exit 1; }
grep -q "file=$prefix/lib[^ ]*/vtsim/libvtsim_image.so " "$work/ld.log" ||
  { echo "install_test: the installed vtsim did not load its image module from $prefix:" >&2; grep libvtsim_image "$work/ld.log" >&2; exit 1; }
"$work/consumer/vtsim_consumer" "$trace" "$work/cli.json" "${sets[@]}"

if [ -n "$python" ]; then
  ls "$prefix/$py_dir"/vtsim*.so >/dev/null
  # The summary but the run's own cost equals the installed CLI's (its config set through a dict).
  PYTHONPATH="$prefix/$py_dir" PYTHONDONTWRITEBYTECODE=1 "$python" - "$prefix" "$trace" "$work/cli.json" <<'PY'
import json, os, sys
import vtsim
prefix, trace, cli_json = sys.argv[1:4]
if not os.path.realpath(vtsim.__file__).startswith(os.path.realpath(prefix)):
    sys.exit(f"install_test: vtsim imported from {vtsim.__file__}, not from {prefix}")
r = vtsim.replay(trace=trace, config={"texture": {"width": 65536, "height": 65536}})
want = json.load(open(cli_json))
got = r["summary"]
for s in (got, want):
    s.pop("run")
    s["provenance"].pop("vtsim_commit")  # module and CLI may be linked at different commits of the tree
if got != want:
    sys.exit("install_test: the installed module's summary differs from the installed CLI's in: " +
             ", ".join(k for k in want if got.get(k) != want[k]))
print(f"install_test: the module {vtsim.__file__} replays as the CLI ({len(r['frames']['frame'])} frames)")
PY
fi
