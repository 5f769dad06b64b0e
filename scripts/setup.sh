#!/usr/bin/env bash
# Create .venv (if missing) and install what is missing into it; idempotent and quiet when done.
# Sourced by demo.sh and test.sh; can also be run on its own.
set -eo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
PY="${PYTHON:-python3.11}"
command -v "$PY" >/dev/null 2>&1 || PY=python3
if [ ! -x "$ROOT/.venv/bin/python" ]; then
    "$PY" -m venv "$ROOT/.venv" || {
        echo "setup: '$PY -m venv' failed; on Debian: apt-get install python3-venv" >&2; exit 1; }
fi
VPY="$ROOT/.venv/bin/python"
# Reinstall only when the pinned requirements or package metadata change.
STAMP="$ROOT/.venv/.islands-setup-stamp"
WANT="$(cat "$ROOT"/requirements*.txt "$ROOT"/src/*/setup.py "$ROOT"/src/*/setup.cfg | sha256sum | cut -d' ' -f1)"
if [ "$(cat "$STAMP" 2>/dev/null)" != "$WANT" ]; then
    "$VPY" -m pip install --quiet --disable-pip-version-check -r "$ROOT/requirements.txt" -r "$ROOT/requirements-dev.txt"
    "$VPY" -m pip install --quiet --disable-pip-version-check --no-deps \
        -e "$ROOT/src/island_msgs_py" -e "$ROOT/src/island_sim" -e "$ROOT/src/island_mapping"
    echo "$WANT" > "$STAMP"
fi
# shellcheck source=scripts/env.sh
. "$ROOT/scripts/env.sh"
