#!/usr/bin/env bash
# Set up what is missing, then run every test (ruff, the import contracts and mypy included).
# Extra args go to pytest.
set -eo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
. "$ROOT/scripts/setup.sh"
cd "$ROOT"
python -m ruff check src test bench
python scripts/check_sizes.py  # issue 15: files <= 600 lines in src/, classes <= 400, functions <= 80
lint-imports  # the architecture contracts of pyproject.toml [tool.importlinter]
python -m mypy
python -m pytest "$@"
