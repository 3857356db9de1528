#!/usr/bin/env bash
# Installs the Debian packages named after LABEL that are not installed yet (the setup
# scripts' one way to apt-get):
#
#   scripts/apt-install.sh LABEL PACKAGE...      # e.g. scripts/apt-install.sh setup-gl libgl1
#
# Idempotent: with every package installed it only checks (dpkg-query) and touches nothing.
# Needs root, or sudo, and apt-get; says what it installs on stderr, prefixed with LABEL.
set -euo pipefail

label="$1"
shift
missing=()
for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
((${#missing[@]})) || exit 0
if ! command -v apt-get >/dev/null; then
    echo "$label: no apt-get to install ${missing[*]}; install them by hand" >&2
    exit 1
fi
sudo=""
[[ $(id -u) == 0 ]] || sudo="sudo"
echo "$label: apt-get install ${missing[*]}" >&2
$sudo apt-get update -qq >&2
DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >&2
