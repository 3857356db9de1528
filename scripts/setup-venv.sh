#!/usr/bin/env bash
# Creates .venv at the repo root (if missing or made from a different Python), installs
# the pinned requirements.txt into it and puts cosim-examples/ on its path (a .pth file:
# the `ehsv` package of the examples and tests, editable in place). Idempotent: a stamp file holds the hash of the
# requirements and the Python version, so a second run does nothing and takes well under
# a second. Usage: scripts/setup-venv.sh   (PYTHON=python3.11 to choose the interpreter)
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
REQ="$ROOT/requirements.txt"
STAMP="$VENV/.requirements.stamp"
PYTHON="${PYTHON:-python3}"

if ! command -v "$PYTHON" >/dev/null 2>&1; then
    echo "setup-venv: '$PYTHON' not found: install Python 3.11 (Debian: apt-get install python3)" >&2
    exit 1
fi

pyver="$("$PYTHON" -c 'import sys; print("%d.%d.%d" % sys.version_info[:3])')"
want="$( (sha256sum "$REQ" | cut -d' ' -f1; echo "python $pyver") | sha256sum | cut -d' ' -f1)"

# The ehsv package (cosim-examples/ehsv) on the venv's path, like `pip install -e
# cosim-examples` but without a build step; rewritten each time (the clone may have moved).
link_package() {
    local site
    site="$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')"
    echo "$ROOT/cosim-examples" > "$site/ehsv-examples.pth"
}

if [[ -x "$VENV/bin/python" && -f "$STAMP" && "$(cat "$STAMP")" == "$want" ]] \
        && "$VENV/bin/python" -c 'import fmpy, numpy, pytest' >/dev/null 2>&1; then
    link_package
    exit 0  # up to date
fi

make_venv() {
    rm -rf "$VENV"
    "$PYTHON" -m venv "$VENV"
}

if ! make_venv 2>/tmp/setup-venv.err.$$; then
    cat /tmp/setup-venv.err.$$ >&2
    rm -f /tmp/setup-venv.err.$$
    # Debian splits venv/ensurepip into python3-venv (python3.X-venv).
    pkg="python3.${pyver#3.}"; pkg="${pkg%.*}-venv"
    if [[ $(id -u) == 0 ]] && command -v apt-get >/dev/null 2>&1; then
        echo "setup-venv: '$PYTHON -m venv' failed; installing $pkg / python3-venv with apt-get" >&2
        apt-get update -qq >&2
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "$pkg" >&2 \
            || DEBIAN_FRONTEND=noninteractive apt-get install -y -qq python3-venv >&2
        make_venv
    else
        echo "setup-venv: '$PYTHON -m venv' does not work here. On Debian/Ubuntu install it with" >&2
        echo "    sudo apt-get install python3-venv   (or $pkg)" >&2
        exit 1
    fi
fi
rm -f /tmp/setup-venv.err.$$

echo "setup-venv: installing requirements into $VENV" >&2
"$VENV/bin/python" -m pip install --quiet --disable-pip-version-check -r "$REQ" >&2
link_package
"$VENV/bin/python" -c 'import fmpy, numpy, pytest, matplotlib, mujoco, ehsv' >&2
echo "$want" > "$STAMP"
echo "setup-venv: ready ($VENV, Python $pyver)" >&2
