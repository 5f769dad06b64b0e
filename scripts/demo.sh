#!/usr/bin/env bash
# Set up what is missing, then run the main job on the built-in default world (paper_fig4).
# Output goes to out/ (or the directory given as the first argument).
set -eo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
. "$ROOT/scripts/setup.sh"
cd "$ROOT"
OUT="${1:-out}"
islands explore --world paper_fig4 --out "$OUT" --seed 1
echo "demo: results in $OUT/"
