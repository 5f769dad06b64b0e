#!/usr/bin/env bash
# Create .venv (if missing) and install what is missing into it; idempotent and quiet when done.
# Sourced by demo.sh and test.sh; can also be run on its own.
set -eo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PY="${PYTHON:-python3.11}"
command -v "$PY" >/dev/null 2>&1 || PY=python3
if [ ! -x "$ROOT/.venv/bin/python" ]; then
    if ! "$PY" -m venv "$ROOT/.venv" 2>/dev/null; then
        rm -rf "$ROOT/.venv"
        # Debian splits venv out of python3; install it when we may, else say what is missing.
        if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
            echo "setup: installing python3-venv with apt-get" >&2
            apt-get update -qq && apt-get install -y -qq python3-venv >/dev/null
            "$PY" -m venv "$ROOT/.venv"
        else
            echo "setup: '$PY -m venv' failed; install python3-venv (apt-get install python3-venv)" >&2
            exit 1
        fi
    fi
fi
VPY="$ROOT/.venv/bin/python"
PIP_VERSION=26.3
# Reinstall only when the pinned requirements or package metadata change.
STAMP="$ROOT/.venv/.islands-setup-stamp"
WANT="$( (echo "pip $PIP_VERSION"; cat "$ROOT"/requirements*.txt "$ROOT"/src/*/setup.py \
          "$ROOT"/src/*/setup.cfg) | sha256sum | cut -d' ' -f1)"
if [ "$(cat "$STAMP" 2>/dev/null)" != "$WANT" ]; then
    echo "setup: installing pinned packages into .venv (log: .venv/setup.log)" >&2
    LOG="$ROOT/.venv/setup.log"
    # A current pip first: Debian's venv pip (23.0) installs editable packages with the legacy
    # `setup.py develop`, which honours setup.cfg's [develop] script_dir (lib/<pkg>, for colcon)
    # and so leaves the console scripts off .venv/bin.
    if ! { "$VPY" -m pip install --disable-pip-version-check "pip==$PIP_VERSION" &&
           "$VPY" -m pip install --disable-pip-version-check -r "$ROOT/requirements.txt" \
                -r "$ROOT/requirements-dev.txt" &&
           "$VPY" -m pip install --disable-pip-version-check --no-deps \
                -e "$ROOT/src/island_msgs_py" -e "$ROOT/src/island_sim" -e "$ROOT/src/island_mapping"
         } > "$LOG" 2>&1; then
        tail -n 30 "$LOG" >&2
        echo "setup: pip install failed (full log: $LOG)" >&2
        exit 1
    fi
    echo "$WANT" > "$STAMP"
fi
# shellcheck source=scripts/env.sh
. "$ROOT/scripts/env.sh"
