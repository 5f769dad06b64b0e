#!/usr/bin/env bash
# Set up what is missing, then run every test (ruff and mypy included). Extra args go to pytest.
set -eo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
. "$ROOT/scripts/setup.sh"
cd "$ROOT"
python -m ruff check src test bench
python -m mypy
python -m pytest "$@"
