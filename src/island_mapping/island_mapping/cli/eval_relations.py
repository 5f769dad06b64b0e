"""`islands eval-relations`: islands built offline on a CARMEN log, scored on Kuemmerle relations.

  islands eval-relations --log intel.gfs.log --relations intel.relations --out DIR
                         [--beams 180|24|16] [--localize-beams 24|16] [--place-recognition]
                         [--seed N] [--bridge-s S] [--max-scans N]

Writes DIR/metrics.json (covered_relations, mean/median translation error [m], mean/median
rotation error [deg] inside islands, the GMapping trajectory on the same relations and on all of
them, island count; plus the same with relation times bridged to the nearest localized scan by
raw odometry) and DIR/islands.png (each island's line model in its own frame, like the paper's
Fig. 5b). The pipeline is deterministic; --seed is recorded for the record only.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np

from island_mapping.cli import CliError
from island_mapping.core import relations as rel
from island_mapping.core.builder.passive import IslandRun
from island_mapping.logs import islands as offline

# Default bridging limit: about half the Intel log's median scan interval (3.35 s), so every
# relation time can reach the nearer of its two neighbouring scans [s].
DEFAULT_BRIDGE_S = 1.7


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--log", required=True, help="CARMEN log (FLASER/ODOM), e.g. intel.gfs.log")
    parser.add_argument("--relations", required=True, help="Kuemmerle relations file")
    parser.add_argument("--out", required=True, help="output directory")
    parser.add_argument("--beams", type=int, default=180, choices=offline.SUPPORTED_BEAMS,
                        help="180 = the laser; 24 or 16 = sonar-like mode (beams kept per scan)")
    parser.add_argument("--localize-beams", type=int, default=0,
                        choices=(0, *offline.SUPPORTED_BEAMS),
                        help="beams used to localize scans in the islands (0 = --beams): "
                             "--beams 180 --localize-beams 24 localizes sonar-like scans in "
                             "laser-built islands")
    parser.add_argument("--place-recognition", action="store_true",
                        help="a lost robot first searches every island's model for its scan "
                             "(re-enters islands on revisits; slower)")
    parser.add_argument("--seed", type=int, default=0,
                        help="recorded only: the pipeline has no random step")
    parser.add_argument("--bridge-s", type=float, default=DEFAULT_BRIDGE_S,
                        help="bridged scoring: a relation time at most this far from a localized "
                             "scan takes its fix plus raw odometry [s] (0 = off)")
    parser.add_argument("--max-scans", type=int, default=None,
                        help="use only the first N scans (quick runs)")


def _stats(score: rel.RelationScore) -> dict[str, Any]:
    return {
        "covered_relations": int(np.sum(score.covered)),
        "relations_with_pose_at_both_ends": score.ends_at_scans,
        "unresolvable_relations": score.unresolvable,
        **{k: v for k, v in score.islands.as_dict().items() if k != "count"},
        "gmapping_same_relations": score.gmapping_covered.as_dict(),
        "covered_islands": sorted({int(i) for i in score.island[score.covered]}),
    }


# A relation joining poses farther apart in time than this is a revisit (after a loop) [s].
REVISIT_S = 100.0
# Progress goes to stderr every this many scans (a full Intel run takes a few minutes).
PROGRESS_EVERY_SCANS = 100


def _progress(scan: int, scans: int, islands: int) -> None:
    if scan % PROGRESS_EVERY_SCANS == 0:
        print(f"islands eval-relations: scan {scan}/{scans}, {islands} islands", file=sys.stderr,
              flush=True)


def evaluate(args: argparse.Namespace) -> dict[str, Any]:
    """Run the evaluation and return metrics (no files written)."""
    from island_mapping.logs.carmen import carmen_log, pose_track, read_carmen_records
    from island_mapping.logs.errors import LogFormatError
    from island_mapping.logs.relations import read_relations

    if args.max_scans is not None and args.max_scans < 2:
        raise CliError(f"--max-scans: need at least 2 scans, got {args.max_scans}")
    if not (math.isfinite(args.bridge_s) and args.bridge_s >= 0):
        raise CliError(f"--bridge-s: expected a number >= 0, got {args.bridge_s}")
    try:
        records = read_carmen_records(args.log)
        log, track = carmen_log(records), pose_track(records)
        relations = read_relations(args.relations)
    except LogFormatError as exc:
        raise CliError(str(exc)) from None
    if not np.array_equal(track.times_s[track.scan_rows], log.times_s):
        raise CliError(f"{args.log}: scan times of the pose track and the CARMEN reader differ")
    if len(relations) == 0:
        raise CliError(f"{args.relations}: no relations")
    n = log.n_scans if args.max_scans is None else min(args.max_scans, log.n_scans)
    base = offline.sonar_like_config(args.beams)
    cfg = dataclasses.replace(
        base, localize_beams=args.localize_beams,
        islands=dataclasses.replace(base.islands, place_recognition=args.place_recognition))
    run = offline.build_islands_offline(log.ranges_m[:n], log.raw_odometry[:n], log.times_s[:n],
                                        cfg, progress=_progress)
    scan_t = log.times_s[:n]
    strict = rel.score_relations(run, scan_t, relations, track)
    bridged = rel.score_relations(run, scan_t, relations, track, bridge_s=args.bridge_s)
    metrics: dict[str, Any] = {
        **_stats(strict),
        "island_count": len(run.islands),
        "gmapping_all_relations": strict.gmapping_all.as_dict(),
        "bridged": {"bridge_s": args.bridge_s, **_stats(bridged)},
        "relations": len(relations),
        "scans": n,
        "localized_scans": int(np.sum(run.scan_island >= 0)),
        "attempts": len(run.attempts),
        "accepted_by": {t: sum(1 for i in run.islands if i.island.model_type.value == t)
                        for t in ("line", "fisher")},
        "beams": args.beams,
        "localize_beams": args.localize_beams or args.beams,
        "place_recognition": args.place_recognition,
        "revisit_relations_covered": int(np.sum(
            bridged.covered & (np.abs(relations.t2_s - relations.t1_s) > REVISIT_S))),
        "seed": args.seed,
        "scan_match_tolerance_s": rel.SCAN_MATCH_TOLERANCE_S,
        "config": _config_summary(cfg),
        "islands": [
            {
                "id": i.island.id,
                "anchor_scan": i.anchor_scan,
                "built_at_s": round(i.island.built_at_s, 3),
                "model_type": i.island.model_type.value,
                "normalized_measure": round(i.island.r, 4),
                "segments": len(i.island.model),
                "localized_scans": int(np.sum(run.scan_island == i.island.id)),
            }
            for i in run.islands
        ],
    }
    metrics["_run"] = run
    return metrics


def _config_summary(cfg: offline.OfflineConfig) -> dict[str, Any]:
    def clean(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, float | int | bool | str) or v is None:
            return v
        return str(v)

    return {k: clean(v) for k, v in dataclasses.asdict(cfg).items()}


def run(args: argparse.Namespace) -> int:
    from island_msgs_py.json_io import atomic_write_text

    from island_mapping.viz.realdata import plot_islands

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise CliError(f"--out {out}: exists and is not a directory")
    metrics = evaluate(args)
    island_run: IslandRun = metrics.pop("_run")
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "metrics.json", json.dumps(metrics, indent=1) + "\n")
    mode = "laser" if args.beams == 180 else f"sonar-like, {args.beams} beams"
    if args.localize_beams and args.localize_beams != args.beams:
        mode += f"; scans localized from {args.localize_beams} beams"
    plot_islands(island_run.islands, out / "islands.png",
                 f"{len(island_run.islands)} islands on the Intel log ({mode})")
    print(json.dumps({k: metrics[k] for k in (
        "covered_relations", "mean_trans_err_m", "median_trans_err_m", "mean_rot_err_deg",
        "island_count")}))
    return 0
