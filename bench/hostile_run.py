"""The project's hostile-input run (issue 17): every `islands` subcommand, every node and the
graph store, fed what an attacker would. Counts what must stay zero.

  python bench/hostile_run.py [--only cli|nodes] [--json OUT]

For each case it records the exit code, the wall time and the peak memory of the process (its
own and its waited-for children's, from wait4). Counted:
- tracebacks: a Python traceback on stderr, or an exit code other than 0 (accepted) and 2
  (refused as bad input);
- internal errors: exit 1 with "internal error" (a bug, reported in one line with its log);
- slow: a command not finished or refused within SLOW_S (it is killed);
- over memory: peak RSS above MEMORY_LIMIT_MIB;
and for the nodes (bench/hostile_nodes.py): node deaths, nodes that stop answering or
publishing, and their peak memory.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import struct
import subprocess
import sys
import tempfile
import time
import zlib
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

SLOW_S = 60.0
"""Every command must finish or refuse within this wall time [s]."""
MEMORY_LIMIT_MIB = 1024.0
"""Peak memory of any one case [MiB]."""
ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"


@dataclass
class Result:
    case: str
    rc: int | None
    seconds: float
    peak_mib: float
    traceback: bool
    internal: bool
    first_line: str


def run_case(name: str, argv: list[str], env: dict[str, str]) -> Result:
    """Run `islands ARGV`; exit code, wall time, peak RSS (wait4), traceback seen."""
    exe = str(Path(sys.prefix) / "bin" / "islands")
    t0 = time.monotonic()
    with tempfile.TemporaryFile() as err:
        proc = subprocess.Popen([exe, *argv], stdout=subprocess.DEVNULL, stderr=err,
                                stdin=subprocess.DEVNULL, env=env, start_new_session=True)
        rc: int | None = None
        usage = None
        while time.monotonic() - t0 < SLOW_S:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                rc = os.waitstatus_to_exitcode(status)
                break
            time.sleep(0.02)
        if rc is None:
            os.killpg(proc.pid, signal.SIGKILL)
            _, _, usage = os.wait4(proc.pid, 0)
        proc.returncode = rc if rc is not None else -9
        seconds = time.monotonic() - t0
        err.seek(0)
        text = err.read().decode("utf-8", "replace")
    peak = usage.ru_maxrss / 1024.0 if usage is not None else 0.0
    lines = [ln for ln in text.splitlines() if ln.strip()]
    return Result(name, rc, seconds, peak, "Traceback (most recent call last)" in text
                  or rc not in (0, 2), rc == 1 and "internal error" in text,
                  lines[-1][:160] if lines else "")


# ----------------------------------------------------------------------------- hostile files


def _png(width: int, height: int, body: bytes | None = None) -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return (struct.pack(">I", len(data)) + kind + data
                + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF))
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    idat = zlib.compress(body if body is not None else b"\x00" * 64)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat) + chunk(b"IEND", b"")


ALIAS_BOMB = "a: &a [x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{c}: &{c} [{', '.join(['*' + p] * 9)}]\n"
    for p, c in zip("abcdefgh", "bcdefghi", strict=True)) + "segments: *i\n"


def make_files(d: Path) -> dict[str, Path]:
    """Hostile inputs of every format, written into `d`."""
    from island_mapping.core.graph import GraphStore, TopoGraph
    from island_sim.core.world import save_world
    from island_sim.core.world_loader import load_world

    texts: dict[str, str | bytes] = {
        "deep.json": "[" * 200_000 + "]" * 200_000,
        "deep.yaml": "a: " + "[" * 100_000 + "]" * 100_000 + "\n",
        "bigint.json": '{"version": 2, "islands": [{"id": ' + "9" * 5000 + "}], \"edges\": []}",
        "bigint_world.yaml": "name: x\nsegments: [[0, 0, " + "9" * 5000 + ", 0]]\n",
        "far_world.yaml": "name: x\nsegments: [[0, 0, 1e308, 0], [0, 1, -1e308, 1]]\n",
        "alias.yaml": ALIAS_BOMB,
        "pytag.yaml": "!!python/object/apply:os.system ['true']\n",
        "nonutf8.yaml": b"name: \xff\xfe\x80\nsegments: []\n",
        "trunc.png": b"\x89PNG\r\n\x1a\n\x00\x00\x00",
        "huge.png": _png(40_000, 40_000),
        "huge.pgm": b"P5\n40000 40000\n255\n" + b"\x00" * 64,
        "longpath_map.yaml": "image: " + "a" * 5000 + ".pgm\nresolution: 0.1\n"
                             "origin: [0, 0, 0]\n",
        "bad_syntax.yaml": "a: [1, 2\nb: {\n",
        "carmen_1e12.log": "ODOM 0 0 0 0 0 0 1e12 pippo 1e12\n"
                           "FLASER 180 " + "1.0 " * 180 + "0 0 0 0 0 0 1e12 pippo 1e12\n",
        "bad.relations": "1 2 3\n",
        "bad_uci.data": "0.4," * 24 + "Move-Forward\n" + "nan," * 24 + "x\n",
        "geo_deep.geojson": '{"type": "FeatureCollection", "features": ' + "[" * 100_000 + "]"
                            * 100_000 + "}",
        "graphml_bigint.graphml": (
            '<?xml version="1.0"?><graphml xmlns="http://graphml.graphdrawing.org/xmlns">'
            '<graph edgedefault="directed"><node id="' + "9" * 5000 + '"/></graph></graphml>'),
    }
    files: dict[str, Path] = {}
    for name, text in texts.items():
        path = d / name
        if isinstance(text, bytes):
            path.write_bytes(text)
        else:
            path.write_text(text, encoding="utf-8")
        files[name] = path
    house = SHARED / "floorplans" / "house_expo_room_0000.json"
    if house.is_file():
        doc = json.loads(house.read_text())
        doc["verts"][1] = [2**31, 0.0]
        files["houseexpo_2e31.json"] = d / "houseexpo_2e31.json"
        files["houseexpo_2e31.json"].write_text(json.dumps(doc))
    files["world.yaml"] = save_world(load_world("t_junction"), d / "world.yaml")
    graph = TopoGraph.load_json(ROOT / "bags" / "example_graph.json")
    files["graph.json"] = graph.save_json(d / "graph.json")
    for variant in ("store", "store_trunc", "store_flip", "store_nodb"):
        store = GraphStore(d / variant)
        for island in graph.islands():
            store.put_island(island)
        for edge in graph.edges():
            store.put_edge(edge)
        store.close()
        files[variant] = d / variant
    db = next((d / "store_trunc").glob("*.sqlite3"))
    db.write_bytes(db.read_bytes()[: db.stat().st_size // 2])
    db = next((d / "store_flip").glob("*.sqlite3"))
    data = bytearray(db.read_bytes())
    data[len(data) // 2] ^= 0x10
    db.write_bytes(bytes(data))
    next((d / "store_nodb").glob("*.sqlite3")).unlink()
    bag = d / "bag_deep"
    bag.mkdir()
    (bag / "metadata.yaml").write_text("rosbag2_bagfile_information: " + "[" * 100_000)
    (bag / "x.mcap").write_bytes(b"\x89MCAP0\r\n" + b"\x00" * 100)
    files["bag_deep"] = bag
    run = d / "run_deep"
    run.mkdir()
    (run / "summary.json").write_text("{" + '"a":' * 100_000 + "1" + "}" * 100_000)
    (run / "graph.json").write_text(files["graph.json"].read_text())
    files["run_deep"] = run
    files["file_not_dir"] = d / "plain_file"
    files["file_not_dir"].write_text("x")
    return files


def cli_cases(f: dict[str, Path], out: Path) -> list[tuple[str, list[str]]]:
    """(name, argv) of every subcommand with hostile input."""
    w, g = str(f["world.yaml"]), str(f["graph.json"])
    nodir = str(f["file_not_dir"])
    cases: list[tuple[str, list[str]]] = []
    for name in ("deep.json", "deep.yaml", "bigint_world.yaml", "far_world.yaml", "alias.yaml",
                 "pytag.yaml", "nonutf8.yaml", "trunc.png", "huge.png", "huge.pgm",
                 "longpath_map.yaml", "bad_syntax.yaml", "houseexpo_2e31.json"):
        if name in f:
            cases.append((f"world {name}", ["world", str(f[name])]))
    cases += [
        ("world --save into a file's dir", ["world", w, "--save", f"{nodir}/x.yaml"]),
        ("world --save a directory", ["world", w, "--save", str(out)]),
        ("scan --seed -1", ["scan", "--world", w, "--pose", "1,1,0", "--seed", "-1"]),
        ("scan --pose 1e308", ["scan", "--world", w, "--pose", "1e308,1e308,0"]),
        ("scan --pose nan", ["scan", "--world", w, "--pose", "nan,1,0"]),
        ("scan world alias bomb", ["scan", "--world", str(f["alias.yaml"]), "--pose", "1,1,0"]),
        ("measure --at 1e308", ["measure", "--world", w, "--at", "1e308,1e308"]),
        ("measure --angular-res-deg 1e-9", ["measure", "--world", w, "--at", "1,1",
                                            "--angular-res-deg", "1e-9"]),
        ("measure --eps-step 1e-9", ["measure", "--world", w, "--at", "1,1", "--eps", "1",
                                     "--eps-step", "1e-9"]),
        ("measure --k 1e5000", ["measure", "--world", w, "--at", "1,1", "--k", "1e5000"]),
        ("fig3 --resolution 1e-9", ["fig3", "--world", w, "--out", str(out / "f"),
                                    "--resolution", "1e-9"]),
        ("fig3 --params deep", ["fig3", "--world", w, "--out", str(out / "f2"), "--params",
                                str(f["deep.json"])]),
        ("fig3 --out a file", ["fig3", "--world", w, "--out", nodir]),
        ("explore --seed -1", ["explore", "--world", w, "--out", str(out / "e"), "--seed", "-1"]),
        ("explore --domain-id 999", ["explore", "--world", w, "--out", str(out / "e"),
                                     "--domain-id", "999"]),
        ("explore --sim-seconds nan", ["explore", "--world", w, "--out", str(out / "e"),
                                       "--sim-seconds", "nan"]),
        ("explore --world deep", ["explore", "--world", str(f["deep.json"]), "--out",
                                  str(out / "e")]),
        ("explore --out a file", ["explore", "--world", w, "--out", nodir]),
        ("explore --builder-param bigint", ["explore", "--world", w, "--out", str(out / "e"),
                                            "--builder-param", "builder.e_min_m=" + "9" * 5000]),
        ("evaluate deep summary", ["evaluate", "--map", str(f["run_deep"])]),
        ("evaluate --start 1e308", ["evaluate", "--map", str(f["run_deep"]), "--start",
                                    "1e308,0,0"]),
    ]
    for name in ("deep.json", "bigint.json", "geo_deep.geojson", "graphml_bigint.graphml",
                 "store_trunc", "store_flip", "store_nodb", "nonutf8.yaml"):
        cases.append((f"graph info {name}", ["graph", "info", str(f[name])]))
    cases += [
        ("graph info /etc", ["graph", "info", "/etc"]),
        ("graph plan --from 2^63", ["graph", "plan", g, "--from", str(2**63), "--to", "1"]),
        ("graph plan --from 10^30", ["graph", "plan", g, "--from", str(10**30), "--to", "1"]),
        ("graph convert to a directory", ["graph", "convert", g, str(out)]),
        ("graph convert into a file's dir", ["graph", "convert", g, f"{nodir}/g.json"]),
        ("graph strategies store_flip", ["graph", "strategies", str(f["store_flip"])]),
        ("graph salvage store_trunc", ["graph", "salvage", str(f["store_trunc"]), "--out",
                                       str(out / "salvaged")]),
        ("bag info deep metadata", ["bag", "info", str(f["bag_deep"])]),
        ("bag echo deep metadata", ["bag", "echo", str(f["bag_deep"]), "--topic", "/x"]),
        ("bag play --wait-timeout nan", ["bag", "play", str(f["bag_deep"]),
                                         "--wait-timeout", "nan"]),
        ("bag play --rate 0", ["bag", "play", str(f["bag_deep"]), "--rate", "0"]),
        ("bag recover deep metadata", ["bag", "recover", str(f["bag_deep"]), "--out",
                                       str(out / "rec")]),
        ("bag import-carmen 1e12", ["bag", "import-carmen", str(f["carmen_1e12.log"]), "--out",
                                    str(out / "imp")]),
        ("bag import-carmen non-UTF-8", ["bag", "import-carmen", str(f["nonutf8.yaml"]),
                                         "--out", str(out / "imp2")]),
        ("topic echo --timeout nan", ["topic", "echo", "/x", "--timeout", "nan"]),
        ("topic echo --limit 10^50", ["topic", "echo", "/x", "--limit", str(10**50)]),
        ("topic list --wait -1", ["topic", "list", "--wait", "-1"]),
        ("eval-relations bad relations", ["eval-relations", "--log", str(f["carmen_1e12.log"]),
                                          "--relations", str(f["bad.relations"]), "--out",
                                          str(out / "rel")]),
        ("eval-relations --seed 10^30", ["eval-relations", "--seed", str(10**30)]),
        ("sonar-ring bad data", ["sonar-ring", "--data", str(f["bad_uci.data"]), "--out",
                                 str(out / "sr")]),
        ("sonar-ring --limit 0", ["sonar-ring", "--data", str(f["bad_uci.data"]), "--out",
                                  str(out / "sr"), "--limit", "0"]),
        ("replay deep metadata", ["replay", str(f["bag_deep"]), "--out", str(out / "rp")]),
        ("replay --tol nan", ["replay", str(f["bag_deep"]), "--out", str(out / "rp"),
                              "--tol", "nan"]),
        ("unknown subcommand", ["nosuch"]),
    ]
    return cases


def run_cli(report: Callable[[Result], None]) -> list[Result]:
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
               ROS_DOMAIN_ID=str(random.SystemRandom().randint(150, 200)))
    results = []
    with tempfile.TemporaryDirectory(prefix="hostile_") as tmp:
        d = Path(tmp)
        env["ISLANDS_LOG_DIR"] = str(d / "logs")
        (d / "in").mkdir()
        (d / "out").mkdir()
        files = make_files(d / "in")
        for name, argv in cli_cases(files, d / "out"):
            results.append(run_case(name, argv, env))
            report(results[-1])
    return results


def summary(results: list[Result]) -> dict[str, float | int]:
    return {
        "cases": len(results),
        "refused_exit_2": sum(r.rc == 2 for r in results),
        "tracebacks": sum(r.traceback for r in results),
        "internal_errors": sum(r.internal for r in results),
        "slow": sum(r.rc is None for r in results),
        "over_memory": sum(r.peak_mib > MEMORY_LIMIT_MIB for r in results),
        "peak_mib": round(max((r.peak_mib for r in results), default=0.0), 1),
        "max_seconds": round(max((r.seconds for r in results), default=0.0), 2),
    }


def _print(r: Result) -> None:
    flag = "TRACEBACK" if r.traceback else ("SLOW" if r.rc is None else "")
    print(f"{r.case:<36} rc={r.rc!s:<4} {r.seconds:6.2f} s {r.peak_mib:7.1f} MiB {flag:<9} "
          f"{r.first_line[:90]}", flush=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", choices=("cli", "nodes"), default=None)
    parser.add_argument("--json", default=None, help="write every result and the counts here")
    args = parser.parse_args()
    out: dict[str, object] = {}
    bad = 0
    if args.only in (None, "cli"):
        results = run_cli(_print)
        counts = summary(results)
        print("CLI:", json.dumps(counts), flush=True)
        out["cli"] = {"counts": counts, "cases": [asdict(r) for r in results]}
        bad += counts["tracebacks"] + counts["slow"] + counts["over_memory"]
    if args.only in (None, "nodes"):
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from hostile_nodes import run_nodes

        node_counts = run_nodes()
        print("nodes:", json.dumps(node_counts), flush=True)
        out["nodes"] = node_counts
        bad += int(node_counts["deaths"]) + int(node_counts["silent"]) + int(
            node_counts["over_memory"])
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=1) + "\n")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
