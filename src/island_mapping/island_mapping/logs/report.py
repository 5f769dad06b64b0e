"""Islands over any recorded log, scored: the one evaluation behind `islands eval-relations`
(CARMEN logs) and `islands replay --passive` (MCAPs of LaserScan + Odometry).

A `RecordedLog` is what the pipeline needs of a recording: scan times, ranges and where the
beams point (`logs.geometry`), raw odometry at each scan, and optionally the log's lines as a
`PoseTrack` (bridging relation times between scans; a GMapping-corrected CARMEN log's own
corrected poses as the reference). `evaluate_log` builds islands with the builder's passive
mode (`logs.islands.build_islands_offline`) and scores them:

- on relations (Kuemmerle et al.), strict and bridged, the reference trajectory on the same
  relations beside them; the relations' time offset is found from the log
  (`core.relations.find_time_offset`) unless given; relations outside the log's time span are
  counted and left out;
- against a reference trajectory inside islands (`logs.reference.inside_islands`), islands
  per place (island origins placed by the reference, merged within 2 m as issue 16's yardstick
  merges places; the islands that duplicate a place are missed loop closures; without a
  reference this cannot be computed and says so) and the loop closures' errors;
- loop closure (live exploration's search and gate): recognitions tried, kept, refused by
  reason.

`headline(metrics)` is the console summary (the bridged figures first).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from island_mapping.core import relations as rel
from island_mapping.core.builder.passive import IslandRun
from island_mapping.logs import islands as offline
from island_mapping.logs import reference as refs
from island_mapping.logs.errors import LogFormatError
from island_mapping.logs.geometry import ScanGeometry
from island_mapping.logs.times import TimeReport

FloatArray = npt.NDArray[np.float64]

REVISIT_S = 100.0
"""A relation joining poses farther apart in time than this is a revisit (after a loop) [s]."""
REFERENCE_TOLERANCE_S = 0.05
"""A reference pose is taken for a scan when their times differ by at most this [s]."""
NO_REFERENCE_TRACK = "raw odometry (the log has no corrected poses)"
"""What the relations' "reference on the same" figures score when the log holds no reference
poses at its scans (its `gmapping_*` entries are then raw odometry's)."""


@dataclass(frozen=True, eq=False)
class RecordedLog:
    """A recording as the island pipeline reads it (see the module docstring)."""

    name: str
    times_s: FloatArray  # (S,) scan times [s]
    ranges_m: FloatArray  # (S, B) [m]
    geometry: ScanGeometry
    raw_odometry: FloatArray  # (S, 3) raw odometry at the scans [m, m, rad]
    mount: tuple[float, float, float] = (0.0, 0.0, 0.0)
    track: rel.PoseTrack | None = None
    track_name: str = ""  # what the track's poses are (e.g. the log's GMapping-corrected poses)
    times: TimeReport | None = None
    skipped: dict[str, int] = field(default_factory=dict)
    reference: refs.Reference | None = None  # recorded on the scans' clock (e.g. a topic)

    @property
    def n_scans(self) -> int:
        return int(self.times_s.shape[0])


@dataclass(frozen=True)
class Scoring:
    """What the islands are scored on (all optional)."""

    relations: rel.Relations | None = None
    time_offset_s: float | None = None  # None: found from the log
    bridge_s: float = 1.7
    reference: refs.Reference | None = None
    reference_offset_s: float | None = None  # None: found from the scan times


def _stats(score: rel.RelationScore, ref_key: str) -> dict[str, Any]:
    return {
        "covered_relations": int(np.sum(score.covered)),
        "relations_with_pose_at_both_ends": score.ends_at_scans,
        "unresolvable_relations": score.unresolvable,
        **{k: v for k, v in score.islands.as_dict().items() if k != "count"},
        ref_key: score.gmapping_covered.as_dict(),
        "covered_islands": sorted({int(i) for i in score.island[score.covered]}),
    }


def _log_lines(log: RecordedLog) -> FloatArray:
    return log.track.times_s if log.track is not None else log.times_s


def score_on_relations(log: RecordedLog, run: IslandRun, n: int, scoring: Scoring
                       ) -> dict[str, Any]:
    """Strict and bridged scores on the relations inside the log's time span."""
    relations = scoring.relations
    assert relations is not None
    lines = _log_lines(log)
    if scoring.time_offset_s is not None:
        offset = rel.TimeOffset(scoring.time_offset_s, 0, 0, "given (--time-offset-s)")
    else:
        offset = rel.find_time_offset(np.concatenate([relations.t1_s, relations.t2_s]), lines)
    inside = rel.in_span(relations, float(lines.min()), float(lines.max()), offset.offset_s)
    if not np.any(inside):
        raise LogFormatError(f"{log.name}: none of the {len(relations)} relations lies within "
                             f"the log's time span with offset {offset.offset_s:.3f} s")
    used = rel.subset(relations, inside)
    scan_t = log.times_s[:n]
    track = log.track
    strict = rel.score_relations(run, scan_t, used, track, offset_s=offset.offset_s)
    bridged = rel.score_relations(run, scan_t, used, track, bridge_s=scoring.bridge_s,
                                  offset_s=offset.offset_s)
    return {
        **_stats(strict, "gmapping_same_relations"),
        "gmapping_all_relations": strict.gmapping_all.as_dict(),
        "bridged": {"bridge_s": scoring.bridge_s, **_stats(bridged, "gmapping_same_relations")},
        "relations": len(used),
        "relations_reference": log.track_name or NO_REFERENCE_TRACK,
        "relations_outside_log": int(np.sum(~inside)),
        "time_offset": offset.as_dict(),
        "revisit_relations_covered": int(np.sum(
            bridged.covered & (np.abs(used.t2_s - used.t1_s) > REVISIT_S))),
        "scan_match_tolerance_s": rel.SCAN_MATCH_TOLERANCE_S,
    }


def reference_at_scans(log: RecordedLog, n: int, scoring: Scoring
                       ) -> tuple[FloatArray, npt.NDArray[np.bool_], str, dict[str, Any]] | None:
    """The reference pose at each of the first n scans: the given trajectory (its time offset
    found from the scan times unless given), else the log's own corrected poses, else the
    reference the recording holds (on the scans' clock; a scan without one within
    REFERENCE_TOLERANCE_S has none)."""
    if scoring.reference is not None:
        ref = scoring.reference
        if scoring.reference_offset_s is not None:
            off = rel.TimeOffset(scoring.reference_offset_s, 0, 0, "given")
        else:
            off = reference_offset(ref, log.times_s[:n], log.name)
        poses, ok = refs.at_times(ref, log.times_s[:n], off.offset_s, REFERENCE_TOLERANCE_S)
        return poses, ok, ref.name, off.as_dict()
    if log.track is not None and log.track_name:
        rows = log.track.scan_rows[:n]
        return log.track.gmapping[rows], np.ones(rows.size, dtype=bool), log.track_name, {}
    if log.reference is not None:
        poses, ok = refs.at_times(log.reference, log.times_s[:n], 0.0, REFERENCE_TOLERANCE_S)
        return poses, ok, log.reference.name, {}
    return None


def reference_offset(ref: refs.Reference, scan_times_s: FloatArray, log_name: str
                     ) -> rel.TimeOffset:
    """Reference time = scan time + offset [s], found so that most of the sparser of the two
    (the reference's poses or the scans) lie within REFERENCE_TOLERANCE_S of the other's
    times; LogFormatError naming the reference when no offset does (not this log's)."""
    try:
        if ref.times_s.size <= scan_times_s.size:
            return rel.find_time_offset(ref.times_s, scan_times_s, REFERENCE_TOLERANCE_S)
        back = rel.find_time_offset(scan_times_s, ref.times_s, REFERENCE_TOLERANCE_S)
    except rel.RelationsError:
        raise LogFormatError(
            f"{ref.name}: for no time offset do half of its {ref.times_s.size} poses (or of the "
            f"{scan_times_s.size} scans of {log_name}) lie within {REFERENCE_TOLERANCE_S * 1e3:g}"
            f" ms of the other's times: it is not a trajectory of this log") from None
    return rel.TimeOffset(-back.offset_s, back.matched, back.times, back.source)


def evaluate_log(log: RecordedLog, cfg: offline.OfflineConfig, scoring: Scoring,
                 max_scans: int | None = None,
                 progress: Callable[[int, int, int], None] | None = None
                 ) -> tuple[dict[str, Any], IslandRun]:
    """Islands over the log (the passive mode) and their scores (module docstring)."""
    n = log.n_scans if max_scans is None else min(max_scans, log.n_scans)
    cfg = offline.for_sensor(cfg, log.geometry)
    run = offline.build_islands_offline(
        log.ranges_m[:n], log.raw_odometry[:n], log.times_s[:n], cfg, progress=progress,
        angles_rad=log.geometry.angles(), mount=log.mount, origins_m=log.geometry.origins())
    metrics: dict[str, Any] = {"log": log.name, "geometry": log.geometry.as_dict(),
                               "mode": offline.mode_text(cfg, log.geometry)}
    if any(log.mount):
        x, y, th = log.mount
        metrics["geometry"]["mount_m_m_deg"] = [round(x, 4) + 0.0, round(y, 4) + 0.0,
                                                round(math.degrees(th), 3) + 0.0]
    if log.times is not None:
        metrics["times"] = log.times.as_dict()
    if log.skipped:
        metrics["skipped_lines"] = dict(log.skipped)
    if scoring.relations is not None:
        metrics.update(score_on_relations(log, run, n, scoring))
    metrics.update({
        "island_count": len(run.islands),
        "scans": n,
        "localized_scans": int(np.sum(run.scan_island >= 0)),
        "attempts": len(run.attempts),
        "accepted_by": {t: sum(1 for i in run.islands if i.island.model_type.value == t)
                        for t in ("line", "fisher")},
        "beams": cfg.beams,
        "localize_beams": cfg.localize_beams or cfg.beams,
        "place_recognition": cfg.islands.place_recognition,
        "loop_closure": run.loop_closure,
    })
    got = reference_at_scans(log, n, scoring)
    if got is not None:
        metrics.update(reference_metrics(run, *got))
    else:
        metrics["places"] = refs.no_places(
            "no reference trajectory (--reference, a corrected log's poses or /gmapping_pose): "
            "where island origins lie cannot be known from raw odometry")
    metrics["config"] = _config_summary(cfg)
    metrics["islands"] = [
        {"id": i.island.id, "anchor_scan": i.anchor_scan,
         "built_at_s": round(i.island.built_at_s, 3), "model_type": i.island.model_type.value,
         "normalized_measure": round(i.island.r, 4), "segments": len(i.island.model),
         "localized_scans": int(np.sum(run.scan_island == i.island.id))}
        for i in run.islands
    ]
    return metrics, run


def reference_metrics(run: IslandRun, poses: FloatArray, ok: npt.NDArray[np.bool_], name: str,
                      offset: dict[str, Any]) -> dict[str, Any]:
    """What the reference says of the islands: agreement inside them, places (islands per
    place, duplicates), and the loop closures' errors."""
    stats, n_isl = refs.inside_islands(run, poses, ok)
    placed = [i for i in run.islands if ok[i.anchor_scan]]
    places = refs.places([i.island.id for i in placed],
                         np.array([poses[i.anchor_scan] for i in placed]).reshape(-1, 3))
    places["islands_without_reference"] = len(run.islands) - len(placed)
    out: dict[str, Any] = {
        "reference": {"name": name, **({"time_offset": offset} if offset else {}),
                      "scans_with_pose": int(np.sum(ok)),
                      "inside_islands": {**stats.as_dict(), "islands": n_isl}},
        "places": places,
    }
    if run.loop_closure is not None:
        out["reference"]["loop_closures"] = refs.closure_errors(
            [(r.scan, r.island_id, r.pose) for r in run.revisits], poses, ok,
            {i.island.id: i.anchor_scan for i in run.islands})
    return out


def _config_summary(cfg: offline.OfflineConfig) -> dict[str, Any]:
    def clean(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, float | int | bool | str) or v is None:
            return v
        return str(v)

    return {k: clean(v) for k, v in dataclasses.asdict(cfg).items()}


def _fmt(stats: dict[str, Any]) -> str:
    if not stats.get("count") and not stats.get("mean_trans_err_m"):
        return "none"
    return (f"{stats['mean_trans_err_m']:.4f} / {stats['median_trans_err_m']:.4f} m, "
            f"{stats['mean_rot_err_deg']:.2f} / {stats['median_rot_err_deg']:.2f} deg")


def _errors(d: dict[str, Any]) -> dict[str, Any]:
    keys = ("mean_trans_err_m", "median_trans_err_m", "mean_rot_err_deg", "median_rot_err_deg")
    return {"count": d.get("covered_relations", 0), **{k: d.get(k) for k in keys}}


def headline(m: dict[str, Any]) -> list[str]:
    """The console summary: the log, islands, the bridged (headline) and strict figures beside
    the reference's on the same relations, the agreement with the reference, places."""
    g = m["geometry"]
    mount = ("" if "mount_m_m_deg" not in g else
             " mounted at ({:g} m, {:g} m, {:g} deg) on the robot".format(*g["mount_m_m_deg"]))
    out = [f"{m['log']}: {m['scans']} scans of {g['description']}{mount}; "
           f"{m['island_count']} islands ({m['mode']}), {m['localized_scans']} scans localized "
           f"in them"]
    if "bridged" in m:
        b, ref = m["bridged"], m.get("relations_reference", "reference")
        out.append(f"  relations (bridged, headline): {b['covered_relations']} covered, islands "
                   f"{_fmt(_errors(b))}; {ref} on the same "
                   f"{_fmt(b['gmapping_same_relations'])}")
        out.append(f"  relations (strict): {m['covered_relations']} covered, islands "
                   f"{_fmt(_errors(m))}; {ref} on the same "
                   f"{_fmt(m['gmapping_same_relations'])}")
        out.append(f"  {ref} on all {m['relations']} relations "
                   f"{_fmt(m['gmapping_all_relations'])}; {m['relations_outside_log']} relations "
                   f"outside the log left out; time offset {m['time_offset']['offset_s']:.3f} s "
                   f"({m['time_offset']['source']})")
    r = m.get("reference")
    if r is not None:
        ins = r["inside_islands"]
        out.append(f"  inside islands vs {r['name']}: {ins['count']} scan pairs in "
                   f"{ins['islands']} islands, {_fmt(ins)}")
    out.append(_places_line(m.get("places")))
    lc = m.get("loop_closure")
    if lc is not None:
        refused = ", ".join(f"{k} {v}" for k, v in lc["refused"].items()) or "none"
        errs = None if r is None else r.get("loop_closures")
        merged = "" if errs is None else (
            f"; {errs['false_merges']} false merges (origin > {errs['false_merge_m']:g} m "
            f"from the reference's)")
        out.append(f"  loop closure (live exploration's gate): {lc['accepted']} of "
                   f"{lc['tried']} recognitions kept{merged}; refused: {refused}; the "
                   f"tracker re-entered islands near by odometry {lc['tracker_reentries']} "
                   f"times ({lc['tracker_reentries_after_loop']} after a loop)")
    return out


def _places_line(pl: dict[str, Any] | None) -> str:
    if pl is None or not pl.get("computable"):
        why = "" if pl is None else f": {pl['why']}"
        return f"  islands per place: cannot be computed{why}"
    dups = ", ".join(f"{d['island']} (of {d['place_of']})" for d in pl["duplicates"]) or "none"
    return (f"  islands per place: {pl['islands_per_place']} ({pl['islands']} islands at "
            f"{pl['places']} places, origins merged within {pl['place_radius_m']:g} m); "
            f"islands duplicating a place: {dups}")


def from_carmen(path: str, override: Any = None, scan_lines: str | None = None) -> RecordedLog:
    """A CARMEN log as a RecordedLog: its scans (the lines of `scan_lines`, default the log's
    first laser, else its SONAR lines; geometry read from the data, `override` a
    `logs.geometry.GeometryOverride`), raw odometry, its lines as the track and their corrected
    poses as the reference (none for SONAR scans). LogFormatError (with its subclasses) on bad
    input."""
    from pathlib import Path

    from island_mapping.logs.carmen import carmen_log, pose_track, read_carmen_records

    records = read_carmen_records(path).with_scans(scan_lines)
    log, track = carmen_log(records, override), pose_track(records)
    if not np.array_equal(track.times_s[track.scan_rows], log.times_s):
        raise LogFormatError(f"{path}: scan times of the pose track and the CARMEN reader differ")
    assert log.geometry is not None
    return RecordedLog(
        name=Path(path).name, times_s=log.times_s, ranges_m=log.ranges_m, geometry=log.geometry,
        raw_odometry=log.raw_odometry, mount=log.mount, track=track,
        track_name=("the log's own scan poses (GMapping-corrected in a corrected log)"
                    if log.has_corrected else ""),
        times=log.times, skipped=log.skipped)
