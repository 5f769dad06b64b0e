"""Does a damaged graph store ever read back as a different valid graph? (issue 17)

  python bench/store_bitflips.py [--stride N] [--graph bags/example_graph.json]

Writes the graph into a fresh GraphStore, then, for every N-th byte of its SQLite file, flips one
bit in a copy and reads the copy back. Each flip ends one of three ways: the same graph (the byte
was unused page space or padding), refused with an error, or a *different* graph read as valid
(silent damage: must be 0).
"""

from __future__ import annotations

import argparse
import shutil
import sys
import tempfile
from pathlib import Path

from island_mapping.core.graph import GraphStore, TopoGraph

ROOT = Path(__file__).resolve().parents[1]
FLIPPED_BIT = 0x10


def _store(graph: TopoGraph, directory: Path) -> Path:
    store = GraphStore(directory)
    for island in graph.islands():
        store.put_island(island)
    for edge in graph.edges():
        store.put_edge(edge)
    store.close()
    return next(directory.glob("*.sqlite3"))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stride", type=int, default=7, help="flip every N-th byte [bytes]")
    parser.add_argument("--graph", type=Path, default=ROOT / "bags" / "example_graph.json")
    args = parser.parse_args(argv)
    graph = TopoGraph.load_json(args.graph)
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        db = _store(graph, base / "store")
        reference = GraphStore.read(base / "store").to_json()
        original = db.read_bytes()
        counts = {"same": 0, "refused": 0, "silently different": 0}
        for pos in range(0, len(original), max(1, args.stride)):
            copy = base / "copy"
            shutil.rmtree(copy, ignore_errors=True)
            shutil.copytree(base / "store", copy)
            data = bytearray(original)
            data[pos] ^= FLIPPED_BIT
            (copy / db.name).write_bytes(bytes(data))
            try:
                got = GraphStore.read(copy).to_json()
            except Exception:  # any refusal counts; what must not happen is a silent change
                counts["refused"] += 1
                continue
            key = "same" if got == reference else "silently different"
            counts[key] += 1
            if key != "same":
                print(f"byte {pos}: read back as a different graph", file=sys.stderr)
    flips = sum(counts.values())
    tally = ", ".join(f"{k} {v}" for k, v in counts.items())
    print(f"{len(original)} bytes, {flips} flips: {tally}")
    return 1 if counts["silently different"] else 0


if __name__ == "__main__":
    sys.exit(main())
