"""The builder's passive mode: islands from a recording, where the robot cannot be driven (no star,
no docking), with the live builder's decision core.

Shared with the live builder (`machine.IslandBuilder`): eq. 3 (`epsilon`: eq3_bound,
normalized_measures, the `Measures` line fit and model evaluation of a `BuilderConfig`), the
islands' memory and recognition (`recognition.Recognizer`: where each island's origin lies in the
odometry frame, the islands near the odometric pose, the correlative place search), the events
and their counts. What a recording cannot do is replaced:

- the star's data: the scans of a window around the anchor scan (`half_window_scans` before and
  after it), placed by odometry and refined by localizing each against the anchor scan's own
  line model, thinned to one point per `voxel_m` cell; the island is accepted by eq. 3 at once
  (a failed attempt is retried `retry_scans` later);
- knowing where it is: every scan is localized in the island the robot is in (from the previous
  island-frame pose plus the odometry increment), and a trusted fix (`fix_ok`: converged, a
  small correction, enough inliers, within the coverage radius) restarts epsilon; a robot in no
  island tries the islands whose origin lies near by odometry, and (`place_recognition`) the
  place search of every island before it attempts a new one.
- loop closure (with `hooks`, e.g. `core.explore.loop_closure_hooks`: exploration's): before
  an attempt the `Recognizer` searches the known islands for the window's echoes as for a
  star's, with the hooks' revisit settings, and the hooks' gate decides
  (`passive_closure`); a recognition kept localizes the scan in that island. The Recognizer
  knows each island's origin where it was last known: at its anchor with the odometry's
  covariance then, and again at every trusted fix in it (as at a live dock), so the gate's
  covariance is the one propagated since; islands are linked as the live ledger links them.

A scan is decided once the `half_window_scans` scans after it have arrived (`on_scan`), or at
`finish`. Results: per scan the island it was localized in and its pose there, the loop
closures and their refusals (`run`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
from island_msgs_py.geometry import compose_poses, from_frame, relative_poses
from island_msgs_py.types import Island, LineModel, ModelType, Pose2D

from island_mapping.core.builder.config import BuilderError
from island_mapping.core.builder.diagnostics import Diagnostics
from island_mapping.core.builder.epsilon import (
    EvaluateFn,
    FitFn,
    Measures,
    OdometryTrack,
    eq3_bound,
    normalized_measures,
)
from island_mapping.core.builder.events import BuilderEvent, DismissReason, EventKind
from island_mapping.core.builder.hooks import (
    APPROACH_M,
    BuilderHooks,
    gate_refusal,
    hooked_config,
)
from island_mapping.core.builder.passive_closure import (
    PassiveRevisit,
    approach_polyline,
    closure_counts,
    recognition_points,
)
from island_mapping.core.builder.passive_config import PassiveConfig, replace_builder
from island_mapping.core.builder.places import PlaceSearch
from island_mapping.core.builder.recognition import PoseSnapshot, Recognizer
from island_mapping.core.lines import point_segment_distance
from island_mapping.core.localize import LocalizeConfig, localize

__all__ = [
    "MIN_FIX_POINTS", "IslandRun", "Localizer", "PassiveAttempt", "PassiveBuilder",
    "PassiveConfig", "PassiveIsland", "ScanFix", "core_localizer", "fix_ok", "inlier_fraction",
    "replace_builder", "voxel_thin",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

# A fix from fewer scan points is not trusted (3 points barely constrain x, y and theta).
MIN_FIX_POINTS = 5


@dataclass(frozen=True)
class ScanFix:
    """Outcome of localizing one scan against an island's line model (island frame)."""

    pose: FloatArray  # (3,) x [m], y [m], theta [rad] in the island frame
    residual_m: float
    converged: bool
    matched_fraction: float


Localizer = Callable[[LineModel, FloatArray, FloatArray], ScanFix]
"""(line model, (N, 2) scan points in the robot frame [m], initial pose (3,) in the island
frame) -> fix."""


def core_localizer(config: LocalizeConfig | None = None) -> Localizer:
    """Localizer backed by core.localize (Dudek-MacKenzie correction, with heading)."""
    cfg = config if config is not None else LocalizeConfig()

    def run(model: LineModel, points: FloatArray, initial: FloatArray) -> ScanFix:
        res = localize(model, points, Pose2D.from_array(initial), cfg)
        return ScanFix(res.pose.as_array(), float(res.residual_m), bool(res.converged),
                       float(res.matched_fraction))

    return run


@dataclass(frozen=True)
class PassiveAttempt:
    """One attempt to build an island at an anchor scan (eq. 3)."""

    scan: int
    epsilon_m: float
    bound: float  # E_min / epsilon (floored), the right side of eq. 3
    best_type: ModelType
    best_normalized: float  # max_i R_i / T_i
    measures: dict[str, float]
    segments: int
    accepted: bool


@dataclass(frozen=True, eq=False)
class PassiveIsland:
    """An island built from a recording: its line model in its own frame (origin = anchor)."""

    island: Island
    anchor_scan: int
    anchor_odom: FloatArray  # (3,) odometric pose of the anchor scan (its origin)


@dataclass(frozen=True, eq=False)
class IslandRun:
    """Islands built over a recording and every scan localized in them.

    scan_island: (S,) id of the island a scan was localized in, -1 if none; scan_pose: (S, 3)
    the scan's pose in that island's frame (NaN when none); epsilon_m: (S,) epsilon at each
    scan, after its odometry and before a fix restarts it.
    """

    islands: tuple[PassiveIsland, ...]
    attempts: tuple[PassiveAttempt, ...]
    scan_island: IntArray
    scan_pose: FloatArray
    epsilon_m: FloatArray
    config: PassiveConfig
    revisits: tuple[PassiveRevisit, ...] = ()
    loop_closure: dict[str, Any] | None = None  # `closure_counts`; None: no loop closure


def voxel_thin(points: FloatArray, cell_m: float) -> FloatArray:
    """One point (the cell's mean) per occupied square cell of side cell_m [m]; (M, 2)."""
    if cell_m <= 0 or points.shape[0] == 0:
        return points
    keys = np.floor(points / cell_m).astype(np.int64)
    _, inv = np.unique(keys, axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    counts = np.bincount(inv).astype(np.float64)
    xs = np.bincount(inv, weights=points[:, 0]) / counts
    ys = np.bincount(inv, weights=points[:, 1]) / counts
    return np.stack([xs, ys], axis=1)


def fix_ok(fix: ScanFix, guess: FloatArray, cfg: PassiveConfig, points: FloatArray,
           model: LineModel) -> bool:
    """A fix is trusted when it converged, moved the guess only a little, and enough of the
    scan's points lie on the model (points seeing past the island's model do not count
    against it, unlike in an RMS residual)."""
    if not fix.converged or points.shape[0] < MIN_FIX_POINTS or not np.all(np.isfinite(fix.pose)):
        return False
    if fix.residual_m > cfg.max_residual_m or fix.matched_fraction < cfg.min_matched_fraction:
        return False
    d = relative_poses(guess, fix.pose)[0]
    if math.hypot(d[0], d[1]) > cfg.max_correction_m:
        return False
    if abs(math.degrees(d[2])) > cfg.max_correction_deg:
        return False
    if cfg.min_inlier_fraction <= 0 or len(model) == 0:
        return True
    return inlier_fraction(fix.pose, points, model, cfg.inlier_dist_m) >= cfg.min_inlier_fraction


def inlier_fraction(pose: FloatArray, points: FloatArray, model: LineModel,
                    inlier_m: float) -> float:
    """The fraction of robot-frame points at `pose` within inlier_m [m] of the model."""
    dist = point_segment_distance(from_frame(points, pose), model.segments).min(axis=1)
    return float(np.mean(dist <= inlier_m))


@dataclass
class _Scan:
    """A scan waiting for its decision: robot-frame points for island models and for fixes,
    the odometric pose it was taken at, and the odometry messages up to it (pose, 3x3
    covariance) since the scan before."""

    t_s: float
    points: FloatArray
    fix_points: FloatArray
    odom: FloatArray  # (3,)
    odometry: list[tuple[Pose2D, FloatArray]]


class PassiveBuilder:
    """The passive mode (see the module docstring). Feed `on_odometry` and `on_scan` in time
    order, then `finish()`; `run()` gives the results."""

    def __init__(self, config: PassiveConfig | None = None, *, localizer: Localizer | None = None,
                 fit: FitFn | None = None, evaluate: EvaluateFn | None = None,
                 hooks: BuilderHooks | None = None) -> None:
        self.config = config if config is not None else PassiveConfig()
        cfg = self.config
        self.measures = Measures.of(cfg.builder, fit, evaluate)
        self.localize = localizer if localizer is not None else core_localizer(cfg.builder.localize)
        self.diagnostics = Diagnostics()
        # Loop closure (module docstring) only with hooks: without, the islands near by
        # odometry and the place search are all the passive mode re-enters.
        self.hooks = hooks
        self.recognizer = Recognizer(
            cfg.builder if hooks is None else hooked_config(cfg.builder, hooks), self.diagnostics)
        self.revisits: list[PassiveRevisit] = []
        self._tried = 0  # loop-closure recognitions tried
        self._path_m = 0.0  # odometric path [m]
        self._last: tuple[int, float] | None = None  # the island last localized in, path then
        self._seen_at: dict[int, float] = {}  # path when each island was last localized in [m]
        self._reentries = [0, 0]  # by the tracker (islands near by odometry): all, after a loop
        self.events: list[BuilderEvent] = []
        self.islands: list[PassiveIsland] = []
        self.attempts: list[PassiveAttempt] = []
        self._scans: dict[int, _Scan] = {}  # the window around the next scan to decide
        self._received = 0  # scans received
        self._decided = 0  # scans decided
        self._odom: FloatArray | None = None
        self._odometry: list[tuple[Pose2D, FloatArray]] = []  # messages since the last scan
        # epsilon (eq. 3), advanced as scans are decided; it feeds the calibration
        self._track = OdometryTrack(self.recognizer.calibration)
        self._current, self._pose = -1, np.zeros(3)  # the island tracked, the pose in it
        self._next_attempt = 0
        self._scan_island: list[int] = []
        self._scan_pose: list[FloatArray] = []
        self._eps_log: list[float] = []

    # ----- inputs -----

    def on_odometry(self, t_s: float, pose: Pose2D, cov3x3: npt.ArrayLike) -> None:
        """An odometry pose [m, rad] and its 3x3 covariance; a scan is paired with the latest."""
        cov = np.asarray(cov3x3, dtype=np.float64)
        if cov.shape != (3, 3) or not np.all(np.isfinite(cov)) or not math.isfinite(t_s):
            raise BuilderError(f"on_odometry: need a finite time and a finite 3x3 covariance, "
                               f"got t {t_s} and shape {cov.shape}")
        self._odom = np.array([pose.x, pose.y, pose.theta])
        self._odometry.append((pose, cov))

    def on_scan(self, t_s: float, points_m: FloatArray,
                fix_points_m: FloatArray | None = None) -> None:
        """A scan's robot-frame points (N, 2) [m] for island models, and those localized in
        islands (default: the same); the scans half_window_scans back are decided now."""
        if self._odom is None:
            raise BuilderError("on_scan: no odometry yet (feed on_odometry first)")
        pts = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
        fix = pts if fix_points_m is None else np.asarray(fix_points_m, np.float64).reshape(-1, 2)
        self._scans[self._received] = _Scan(t_s, pts, fix, self._odom.copy(), self._odometry)
        self._odometry = []
        self._received += 1
        while self._decided + self.config.half_window_scans < self._received:
            self._decide()

    def finish(self) -> IslandRun:
        """Decide the scans still waiting (their windows end with the recording); the run."""
        while self._decided < self._received:
            self._decide()
        return self.run()

    def run(self) -> IslandRun:
        """The islands, attempts and per-scan localizations so far."""
        n = len(self._scan_island)
        closure = None if self.hooks is None else closure_counts(
            self.diagnostics, self._tried, self.revisits,
            (self._reentries[0], self._reentries[1]))
        return IslandRun(tuple(self.islands), tuple(self.attempts),
                         np.asarray(self._scan_island, dtype=np.int64),
                         np.asarray(self._scan_pose, dtype=np.float64).reshape(n, 3),
                         np.asarray(self._eps_log, dtype=np.float64), self.config,
                         tuple(self.revisits), closure)

    # ----- the decision of one scan -----

    def _decide(self) -> None:
        i = self._decided
        scan = self._scans[i]
        prev = self._scans.get(i - 1)
        inc = relative_poses(prev.odom, scan.odom)[0] if prev is not None else np.zeros(3)
        self._scan_island.append(-1)
        self._scan_pose.append(np.full(3, np.nan))
        fixed = self._locate(i, inc)
        for pose, cov in scan.odometry:
            self._path_m += self._track.update(pose, cov)
        self._eps_log.append(self._track.rel.epsilon_m)
        if fixed is not None:
            self._record(i, self._current, fixed)
            self._track.rel.reset()
        elif self._track.rel.epsilon_m > self.config.builder.e_min_m and (
            i >= self._next_attempt
        ):
            self._lost(i)
        self._decided += 1
        self._scans.pop(i - self.config.half_window_scans - 1, None)

    def _locate(self, i: int, inc: FloatArray) -> FloatArray | None:
        """Scan i's fix in the island tracked (from the previous pose plus the increment), else
        in an island near by odometry (within relocalize_radius_m plus epsilon, nearest first)."""
        fixed: FloatArray | None = None
        if self._current >= 0:
            fixed = self._try_fix(self._current, i, compose_poses(self._pose, inc)[0])
            if fixed is None:
                self._current = -1
        if fixed is None and self.islands:
            odom = Pose2D(*(float(v) for v in self._scans[i].odom))
            radius = self.config.relocalize_radius_m + self._track.rel.epsilon_m
            for _, k, guess in self.recognizer.near(odom, radius):
                fixed = self._try_fix(k, i, guess)
                if fixed is not None:
                    self._count_reentry(k)
                    self._current = k
                    break
        return fixed

    def _count_reentry(self, k: int) -> None:
        """The tracker re-entered island k (near by odometry, a small correction): counted, and
        whether the robot had gone a loop's length (revisit.min_loop_m) since it was last there
        (a loop closed without the recognizer's search and gate)."""
        if self.hooks is None:
            return
        self._reentries[0] += 1
        since = self._path_m - self._seen_at.get(k, self._path_m)
        if since >= self.recognizer.config.revisit.min_loop_m:
            self._reentries[1] += 1

    def _try_fix(self, k: int, i: int, guess: FloatArray) -> FloatArray | None:
        """Scan i localized in island k from `guess` (island frame), if trusted and within the
        coverage radius."""
        pts = self._scans[i].fix_points
        model = self.islands[k].island.model
        fix = self.localize(model, pts, guess)
        if not fix_ok(fix, guess, self.config, pts, model):
            return None
        if math.hypot(fix.pose[0], fix.pose[1]) > self.config.coverage_radius_m:
            return None
        return fix.pose

    def _record(self, i: int, island: int, pose: FloatArray) -> None:
        self._current, self._pose = island, pose
        self._scan_island[i], self._scan_pose[i] = island, pose
        if self.hooks is not None and i == self._decided:
            # The robot knows where the island's origin is now (a live dock's remember).
            origin = Pose2D(*(float(v) for v in self._scans[i].odom)).compose(
                Pose2D(*(float(v) for v in pose)).inverse())
            self.recognizer.remember(island, origin, self._track.cov.copy())
            self._last = (island, self._path_m)
            self._seen_at[island] = self._path_m

    def _lost(self, i: int) -> None:
        """Scan i in no island, epsilon past E_min: a known place (loop closure, with hooks;
        the place search), else an attempt at a new island."""
        found = self._close_loop(i) if self.hooks is not None and self.islands else None
        if found is None and self.config.place_recognition and self.islands:
            found = self._recognize(i)
        if found is not None:
            self._record(i, *found)
            self._track.rel.reset()
            return
        self._attempt(i)

    def _close_loop(self, i: int) -> tuple[int, FloatArray] | None:
        """Live exploration's loop closure at scan i (module docstring): the island and the
        scan's pose in its frame, or None (refusals counted)."""
        assert self.hooks is not None
        rc = self.recognizer.config.revisit
        scan = self._scans[i]
        window = [(self._scans[j].points, self._scans[j].odom) for j in self._window_order(i)]
        pts = recognition_points(window, scan.odom, rc)
        if pts.shape[0] < rc.min_points:
            return None
        self._tried += 1
        at = Pose2D(*(float(v) for v in scan.odom))
        snap = self._snapshot(at)
        built = [isl.island for isl in self.islands]
        rec = self.recognizer.recognize(pts, at, snap, built, star=True)
        if rec is None:
            return None
        odoms = [self._scans[j].odom for j in sorted(self._scans) if j <= i]
        refusal = gate_refusal(self.hooks, rec, snap, built[rec.island_id], True,
                               approach_polyline(odoms, APPROACH_M), rec.pose)
        if refusal is not None:
            self.diagnostics.refuse(refusal)
            return None
        pose = rec.pose.as_array()
        self._link_from_last(rec.island_id, at.compose(rec.pose.inverse()))
        self.revisits.append(PassiveRevisit(i, rec.island_id, pose, rec.mahalanobis2,
                                            rec.residual_m))
        self._emit(EventKind.ISLAND_REVISITED, scan.t_s, at, self._track.rel.epsilon_m,
                   revisited_island_id=rec.island_id, island_pose=rec.pose,
                   residual_m=rec.residual_m)
        return rec.island_id, pose

    def _snapshot(self, odom: Pose2D) -> PoseSnapshot:
        """The robot's state for a recognition (the live builder's `snapshot`)."""
        track = self._track
        last, left_m = (None, 0.0) if self._last is None else self._last
        return PoseSnapshot(odom, track.cov.copy(), track.rel.epsilon_m,
                            track.rel.heading_sigma_rad, last, self._path_m - left_m)

    def _link_from_last(self, target: int, origin_odom: Pose2D) -> None:
        """Link the island last localized in to `target` (origin at origin_odom) with the
        error since, as the live ledger links an island to the last one."""
        if self._last is not None and self._last[0] != target:
            self.recognizer.link(self._last[0], target, origin_odom,
                                 self._track.rel.epsilon_m, self._track.rel.heading_sigma_rad)

    def _recognize(self, i: int) -> tuple[int, FloatArray] | None:
        """Place recognition for a lost robot: the island and island-frame pose of scan i, or
        None when no island explains the scan unambiguously."""
        cfg, pts = self.config, self._scans[i].fix_points
        if pts.shape[0] < MIN_FIX_POINTS:
            return None
        found = self.recognizer.place(pts, cfg.recognition_margin)
        if found is None:
            return None
        k, guess = found
        model = self.islands[k].island.model
        fix = self.localize(model, pts, guess)
        if not fix_ok(fix, guess, cfg, pts, model):
            return None
        if math.hypot(fix.pose[0], fix.pose[1]) > cfg.coverage_radius_m:
            return None
        if inlier_fraction(fix.pose, pts, model, cfg.inlier_dist_m) < cfg.recognition_min_inliers:
            return None
        return k, fix.pose

    def _attempt(self, i: int) -> None:
        """Eq. 3 at scan i: the window's model accepted when max_i R_i/T_i > E_min/epsilon."""
        cfg, bcfg = self.config, self.config.builder
        model, window = self._window_model(i)
        measures = self.measures.evaluate(model.segments, np.zeros(2)) if len(model) else {}
        best_type, best = normalized_measures(bcfg, measures)
        eps = self._track.rel.epsilon_m
        bound = eq3_bound(bcfg, eps)
        accepted = len(model) > 0 and best > bound
        self.attempts.append(PassiveAttempt(
            i, eps, bound, best_type, best, {k.value: float(v) for k, v in measures.items()},
            len(model), accepted))
        scan = self._scans[i]
        at = Pose2D(*(float(v) for v in scan.odom))
        if not accepted:
            self._next_attempt = i + 1 + cfg.retry_scans
            self._emit(EventKind.ATTEMPT_DISMISSED, scan.t_s, at, eps, measure=best, bound=bound,
                       reason=DismissReason.MEASURE)
            return
        island = Island(id=len(self.islands), model=model, model_type=best_type, r=float(best),
                        built_at_s=float(scan.t_s))
        self._add_island(PassiveIsland(island, i, scan.odom.copy()))
        self._emit(EventKind.ISLAND_ACCEPTED, scan.t_s, at, eps, anchor_odom=at, measure=best,
                   bound=bound, island=island)
        self._current = island.id
        self._track.rel.reset()
        # The anchor and the window scans before it are localized in the new island.
        for j, guess in window:
            if j > i or self._scan_island[j] >= 0:
                continue
            got = self._try_fix(island.id, j, guess)
            if got is not None:
                self._record(j, island.id, got)
        self._current = island.id
        if self._scan_island[i] == island.id:
            self._pose = self._scan_pose[i]
        else:
            self._record(i, island.id, np.zeros(3))

    def _add_island(self, isl: PassiveIsland) -> None:
        cfg = self.config
        self.islands.append(isl)
        origin = Pose2D(*(float(v) for v in isl.anchor_odom))
        self._link_from_last(isl.island.id, origin)
        # Its origin is the anchor scan: known there, with the odometry's covariance then.
        self.recognizer.remember(isl.island.id, origin, self._track.cov.copy())
        if cfg.place_recognition:
            self.recognizer.add_place_search(isl.island.id, PlaceSearch(
                isl.island.model, cfg.coverage_radius_m + cfg.search_range_m,
                cfg.coverage_radius_m))

    def _window_model(self, anchor: int) -> tuple[LineModel, list[tuple[int, FloatArray]]]:
        """Line model of the scans around `anchor` in the anchor's frame, and each scan's pose
        (odometry, refined against the anchor scan's own line model)."""
        cfg = self.config
        order = self._window_order(anchor)
        placed: list[tuple[int, FloatArray]] = []
        clouds: list[FloatArray] = []
        anchor_model: LineModel | None = None
        for j in order:
            guess = relative_poses(self._scans[anchor].odom, self._scans[j].odom)[0]
            pose = guess
            pts = self._scans[j].points
            if anchor_model is not None and len(anchor_model) and pts.shape[0]:
                fix = self.localize(anchor_model, pts, guess)
                if fix_ok(fix, guess, cfg, pts, anchor_model):
                    pose = fix.pose
            placed.append((j, pose))
            clouds.append(from_frame(pts, pose))
            if cfg.align_window and j == anchor:
                anchor_model = self.measures.fit(voxel_thin(pts, cfg.voxel_m))
        all_pts = np.concatenate(clouds) if clouds else np.zeros((0, 2))
        return self.measures.fit(voxel_thin(all_pts, cfg.voxel_m)), placed

    def _window_order(self, anchor: int) -> list[int]:
        """The scans of the window around `anchor`: the anchor, then outward (after, before)."""
        order = [anchor]
        for d in range(1, self.config.half_window_scans + 1):
            order += [j for j in (anchor + d, anchor - d) if j in self._scans]
        return order

    def _emit(self, kind: EventKind, t_s: float, odom: Pose2D, epsilon_m: float,
              **kw: object) -> None:
        self.diagnostics.counts[kind] += 1
        self.events.append(BuilderEvent(kind, t_s, odom, epsilon_m, **kw))  # type: ignore[arg-type]
