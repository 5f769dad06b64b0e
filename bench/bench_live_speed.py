"""The live main job's speed, old tree against new, side by side in one run (issue 16).

  python bench/bench_live_speed.py [--old main] [--new WORKTREE] [--world paper_fig4] \
      [--policies exits hall_following] [--seeds 1 2] [--sim-seconds 300] [--repeats 1] \
      [--no-record] [--deliveries]

For every (policy, seed, repeat) it runs `islands explore --routes 0` once on each tree, the
two one right after the other (their order alternating between repeats), each in its own
process: `--old` and `--new` are git revisions (`git archive`d to a temporary directory and
imported ahead of the editable install) or WORKTREE, the tree this script is in. Printed per
run: simulated s, exploration wall s and real-time factor (what summary.json says), the
process's CPU s, what the robot decided (attempts, islands, revisits, wall contacts) and
whether the builder's events equal the other tree's run of the same seed (kind, time and
odometric pose of each; live runs are not bit-reproducible: which of two answers to one scan
wins at a hand-over is up to DDS, so a difference there is not by itself a regression). Then
per tree and policy the medians and new/old ratios, and the messages per simulated second of
every recorded topic (from run_bag/, unless --no-record). `--deliveries` first measures what
one message delivery costs on the events executor: nav_msgs/Odometry typed against raw
(serialized bytes), and rosgraph_msgs/Clock, to 1 and 5 subscribers. Every line carries the
1-minute load average (the machine is shared: compare ratios measured side by side, not
figures of different runs).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import resource
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
WORKTREE = "WORKTREE"
PACKAGES = ("island_msgs_py", "island_sim", "island_mapping")
# Run in the child: the tree's packages ahead of the editable install (whose finders come after
# the path finder on sys.meta_path), then the CLI.
_BOOT = f"""
import sys
tree = sys.argv[1]
if tree:
    for pkg in {PACKAGES!r}:
        sys.path.insert(0, f"{{tree}}/src/{{pkg}}")
import island_mapping
if tree and not island_mapping.__file__.startswith(tree):
    sys.exit(f"imported {{island_mapping.__file__}}, not the tree {{tree}}")
from island_mapping.cli import main
sys.exit(main(sys.argv[2:]))
"""
EVENT_KEYS = ("kind", "t_s", "odom_pose", "measure", "island_id")
"""What makes two runs' builder events the same decisions (truth_pose is the observer's)."""


def _load() -> float:
    return round(os.getloadavg()[0], 2)


def export_tree(rev: str, into: Path) -> str:
    """The source tree of `rev` under `into` ('' for the working tree itself)."""
    if rev == WORKTREE:
        return ""
    data = subprocess.run(["git", "archive", "--format=tar", rev, "src"], cwd=REPO,
                          capture_output=True, check=True).stdout
    dest = into / rev.replace("/", "_")
    with tarfile.open(fileobj=io.BytesIO(data)) as tar:
        tar.extractall(dest, filter="data")
    return str(dest)


def run_once(tree: str, policy: str, seed: int, args: argparse.Namespace, out: Path
             ) -> dict[str, Any]:
    """One `islands explore` in a child process; its figures and decisions."""
    cmd = [sys.executable, "-c", _BOOT, tree, "explore", "--world", args.world, "--policy",
           policy, "--seed", str(seed), "--sim-seconds", str(args.sim_seconds), "--routes",
           "0", "--quiet", "--out", str(out)] + (["--no-record"] if args.no_record else [])
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.monotonic()
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    wall = time.monotonic() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if proc.returncode != 0:
        return {"error": f"exit {proc.returncode}: {proc.stderr.strip()[-400:]}"}
    s = json.loads((out / "summary.json").read_text())
    return {
        "sim_s": round(s["sim_seconds"], 1), "explore_wall_s": s["wall_seconds"],
        "rtf": s["real_time_factor"], "process_wall_s": round(wall, 1),
        "process_cpu_s": round(cpu, 1), "attempts": s["attempts"], "islands": s["islands"],
        "revisits": s["revisits"], "contacts": s["collisions"],
        "timeouts": s["lockstep_timeouts"],
        "events": [{k: e.get(k) for k in EVENT_KEYS} for e in s["builder_events"]],
        "topics": _topic_rates(out / "run_bag", s["sim_seconds"]) if not args.no_record else {},
    }


def _topic_rates(bag: Path, sim_s: float) -> dict[str, float]:
    """Messages per simulated second of every recorded topic."""
    from island_mapping.bag.reader import open_bag

    topics = open_bag(bag).topics
    return {name: round(info.message_count / sim_s, 2) for name, info in sorted(topics.items())}


def _print_run(label: str, policy: str, seed: int, r: dict[str, Any], same: bool | None) -> None:
    if "error" in r:
        print(f"{label:4s} {policy:15s} {seed:4d}  {r['error']}", flush=True)
        return
    print(f"{label:4s} {policy:15s} {seed:4d} {r['sim_s']:7.1f} {r['explore_wall_s']:8.2f} "
          f"{r['rtf']:6.2f} {r['process_cpu_s']:7.1f} {r['attempts']:5d} {r['islands']:5d} "
          f"{r['revisits']:5d} {r['contacts']:5d} {r['timeouts']:4d} "
          f"{'-' if same is None else ('yes' if same else 'no'):>5s} {_load():5.2f}",
          flush=True)


def compare(args: argparse.Namespace) -> dict[tuple[str, str], list[dict[str, Any]]]:
    """Every run, old and new side by side; the runs by (tree label, policy)."""
    results: dict[tuple[str, str], list[dict[str, Any]]] = {}
    with tempfile.TemporaryDirectory(prefix="bench_live_speed_") as tmp:
        trees = {"old": export_tree(args.old, Path(tmp)), "new": export_tree(args.new, Path(tmp))}
        print(f"old = {args.old}, new = {args.new}; {args.world}, {args.sim_seconds:g} sim s, "
              f"recording {'off' if args.no_record else 'on'}, {os.cpu_count()} cores")
        print("tree policy          seed   sim s   wall s    RTF   CPU s  att.  isl. revis cont. "
              "tout  same  load")
        k = 0
        for rep in range(args.repeats):
            for policy in args.policies:
                for seed in args.seeds:
                    order = ("old", "new") if (rep + k) % 2 == 0 else ("new", "old")
                    k += 1
                    pair: dict[str, dict[str, Any]] = {}
                    for label in order:
                        out = Path(tmp) / f"{label}_{policy}_{seed}_{rep}"
                        pair[label] = run_once(trees[label], policy, seed, args, out)
                    same = None
                    if all("error" not in r for r in pair.values()):
                        same = pair["old"]["events"] == pair["new"]["events"]
                    for label in ("old", "new"):
                        _print_run(label, policy, seed, pair[label], same)
                        results.setdefault((label, policy), []).append(pair[label])
    return results


def summarize(results: dict[tuple[str, str], list[dict[str, Any]]]) -> None:
    """Medians per tree and policy, the new/old ratios, and the topics' message rates."""
    print("\nmedians: tree policy  exploration wall s  real-time factor  CPU s")
    med: dict[tuple[str, str], dict[str, float]] = {}
    for (label, policy), runs in sorted(results.items()):
        ok = [r for r in runs if "error" not in r]
        if not ok:
            continue
        med[(label, policy)] = {k: statistics.median(r[k] for r in ok)
                                for k in ("explore_wall_s", "rtf", "process_cpu_s")}
        m = med[(label, policy)]
        print(f"  {label:4s} {policy:15s} {m['explore_wall_s']:8.2f} {m['rtf']:8.2f} "
              f"{m['process_cpu_s']:8.1f}")
    for policy in sorted({p for _, p in med}):
        if ("old", policy) in med and ("new", policy) in med:
            o, n = med[("old", policy)], med[("new", policy)]
            print(f"  {policy}: real-time factor new/old {n['rtf'] / o['rtf']:.2f}, "
                  f"CPU old/new {o['process_cpu_s'] / n['process_cpu_s']:.2f}")
    rates: dict[str, dict[str, float]] = {}
    for (label, _policy), runs in results.items():
        for r in runs:
            if r.get("topics") and label not in rates:
                rates[label] = r["topics"]
    if rates:
        print("\nmessages per simulated second (first recorded run of each tree):")
        for topic in sorted(set().union(*(set(t) for t in rates.values()))):
            print(f"  {topic:28s} " + "  ".join(f"{label} {rates[label].get(topic, 0):7.2f}"
                                                for label in sorted(rates)))


def deliveries() -> None:
    """What one delivery costs on the events executor [us]: typed vs raw Odometry, Clock."""
    code = subprocess.run([sys.executable, str(Path(__file__).with_name("bench_deliveries.py"))],
                          check=False)
    if code.returncode != 0:
        print(f"bench_deliveries.py failed (exit {code.returncode})")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--old", default="main", help="git revision, or WORKTREE")
    p.add_argument("--new", default=WORKTREE, help="git revision, or WORKTREE (this tree)")
    p.add_argument("--world", default="paper_fig4")
    p.add_argument("--policies", nargs="+", default=["exits", "hall_following"])
    p.add_argument("--seeds", nargs="+", type=int, default=[1])
    p.add_argument("--sim-seconds", type=float, default=300.0)
    p.add_argument("--repeats", type=int, default=1)
    p.add_argument("--no-record", action="store_true", help="runs without run_bag/")
    p.add_argument("--deliveries", action="store_true",
                   help="first measure the cost of one message delivery (bench_deliveries.py)")
    args = p.parse_args()
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    if args.deliveries:
        deliveries()
    summarize(compare(args))


if __name__ == "__main__":
    main()
