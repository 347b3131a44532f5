# Sourced by the scripts that need Debian packages: ensure_packages P... installs those of P that
# are not installed (apt-get as root, or through sudo), quietly; a no-op when all are there.
ensure_packages() {
  local missing=() p
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  ((${#missing[@]})) || return 0
  echo "$(basename "$0"): installing ${missing[*]}" >&2
  local sudo=()
  [ "$(id -u)" -eq 0 ] || sudo=(sudo)
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -qq
  # A line every 25 packages fetched or set up: a fresh machine's install takes minutes, and a
  # silent one reads as a hang.
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${missing[@]}" 2>&1 |
    awk '/^(Get:|Setting up )/ { n++; if (n % 25 == 0) { printf "  apt: %d packages fetched or set up\n", n; fflush() } }
         /^(E:|W:)/ { print; fflush() }' >&2
  local rc=${PIPESTATUS[0]}
  ((rc == 0)) || { echo "$(basename "$0"): apt-get install failed (exit $rc)" >&2; return "$rc"; }
}
