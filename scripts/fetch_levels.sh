#!/usr/bin/env bash
# Extracts real game levels for the benchmarks and docs (docs/levels.md): OpenArena's Quake 3
# levels from Debian's openarena-data (installed when missing: apt-get as root, or sudo). For each
# map NAME writes OUT_DIR/NAME.bsp and OUT_DIR/NAME.pk3, a zip holding only maps/NAME.bsp, stored
# uncompressed (the form assimp's Quake 3 importer reads, and vtsim's entity reader). A map in a
# later pak (pak6-patch085.pk3) replaces the one in an earlier pak, as in the game. Idempotent:
# files already equal are left alone. Tests never need this (they make their own small levels).
# Usage: scripts/fetch_levels.sh [-o OUT_DIR] [MAP...]   (default: build/levels, oa_dm1 oa_minia)
#        scripts/fetch_levels.sh --list                   (the maps the packs hold)
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
out=$here/build/levels
list=0
maps=()
while (($#)); do
  case $1 in
    -o) out=${2:?fetch_levels: -o needs a directory}; shift 2 ;;
    --list) list=1; shift ;;
    -h|--help) sed -n '2,9p' "$0"; exit 0 ;;
    -*) echo "fetch_levels: unknown option $1" >&2; exit 2 ;;
    *) maps+=("$1"); shift ;;
  esac
done
((${#maps[@]})) || maps=(oa_dm1 oa_minia)
base=/usr/share/games/openarena/baseoa
# shellcheck source=scripts/packages.sh
. "$here/scripts/packages.sh"
for p in openarena-data python3; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" &&
     [ "$(id -u)" -ne 0 ] && ! command -v sudo >/dev/null; then
    echo "fetch_levels: the Debian package $p is needed (openarena-data: ~350 MB); install it as root:" >&2
    echo "  apt-get install $p" >&2
    exit 2
  fi
done
ensure_packages openarena-data python3
mkdir -p "$out"
python3 - "$base" "$out" "$list" "${maps[@]}" <<'PY'
import glob, io, os, sys, zipfile
base, out, list_only, maps = sys.argv[1], sys.argv[2], sys.argv[3] == "1", sys.argv[4:]
where = {}  # map name -> the last pak (in name order) holding it
for pak in sorted(glob.glob(os.path.join(base, "*.pk3"))):
    with zipfile.ZipFile(pak) as z:
        for n in z.namelist():
            if n.startswith("maps/") and n.endswith(".bsp") and n.count("/") == 1:
                where[n[5:-4]] = pak
if list_only:
    for m in sorted(where):
        print(f"{m}\t{os.path.basename(where[m])}")
    sys.exit(0)
bad = [m for m in maps if m not in where]
if bad:
    sys.exit(f"fetch_levels: no map {', '.join(bad)} in {base} (--list shows them)")
def put(path, data):
    if os.path.exists(path) and open(path, "rb").read() == data:
        print(f"up to date: {path}")
        return
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(data)
    os.replace(tmp, path)
    print(f"wrote {path} ({len(data)} bytes)")
for m in maps:
    with zipfile.ZipFile(where[m]) as z:
        bsp = z.read(f"maps/{m}.bsp")
    put(os.path.join(out, m + ".bsp"), bsp)
    pk3 = os.path.join(out, m + ".pk3")
    # A fixed timestamp: the same map gives the same pk3 bytes every run.
    info = zipfile.ZipInfo(f"maps/{m}.bsp", date_time=(1980, 1, 1, 0, 0, 0))
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_STORED) as z:
        z.writestr(info, bsp)
    put(pk3, buf.getvalue())
    print(f"  from {os.path.basename(where[m])}")
PY
