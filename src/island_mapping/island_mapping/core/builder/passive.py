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

A scan is decided once the `half_window_scans` scans after it have arrived (`on_scan`), or at
`finish`. Results: per scan the island it was localized in and its pose there (`run`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
from island_msgs_py.geometry import compose_poses, from_frame, relative_poses
from island_msgs_py.types import Island, LineModel, ModelType, Pose2D

from island_mapping.core.builder.config import BuilderConfig, BuilderError
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
from island_mapping.core.builder.places import PlaceSearch
from island_mapping.core.builder.recognition import Recognizer
from island_mapping.core.lines import LASER_LINE_FIT, point_segment_distance
from island_mapping.core.localize import LocalizeConfig, localize
from island_mapping.core.measure import MeasureConfig

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


def _laser_builder() -> BuilderConfig:
    """Eq. 3 as the live builder's, with a laser's line fit and measure (a laser sees walls at
    any incidence and reliably farther than a sonar) and Dudek-MacKenzie localization."""
    return BuilderConfig(line_fit=LASER_LINE_FIT,
                         measure=MeasureConfig(reflect_deg=80.0, max_range_m=10.0),
                         localize=LocalizeConfig())


@dataclass(frozen=True)
class PassiveConfig:
    """The passive mode (single source of its defaults)."""

    half_window_scans: int = field(
        default=2,
        metadata={"help": "an island model accumulates the scans this many steps before and "
                  "after the anchor scan [-]"},
    )
    align_window: bool = field(
        default=True,
        metadata={"help": "place each window scan by localizing it against the anchor scan's "
                  "own line model (False: by odometry only) [bool]"},
    )
    voxel_m: float = field(
        default=0.05,
        metadata={"help": "accumulated island points are thinned to one per grid cell of this "
                  "side before line fitting (0 = keep all) [m]"},
    )
    retry_scans: int = field(
        default=1, metadata={"help": "scans to skip after a failed attempt [-]"}
    )
    coverage_radius_m: float = field(
        default=3.0,
        metadata={"help": "a scan is inside an island when its localized position is within "
                  "this distance of the island origin [m]"},
    )
    relocalize_radius_m: float = field(
        default=2.5,
        metadata={"help": "islands whose origin is within this odometric distance (plus "
                  "epsilon) are tried when the robot is in no island [m]"},
    )
    max_residual_m: float = field(
        default=0.2,
        metadata={"help": "largest RMS residual of the matched points of a fix (a sanity bound; "
                  "the inlier test decides) [m]"},
    )
    min_matched_fraction: float = field(
        default=0.6, metadata={"help": "smallest fraction of scan points matched to the model [-]"}
    )
    inlier_dist_m: float = field(
        default=0.1, metadata={"help": "a scan point within this of the model is an inlier [m]"}
    )
    min_inlier_fraction: float = field(
        default=0.6,
        metadata={"help": "a fix needs at least this fraction of scan points as inliers "
                  "(0 = no inlier test) [-]"},
    )
    max_correction_m: float = field(
        default=0.6,
        metadata={"help": "a fix may move the odometry guess at most this far [m]"},
    )
    max_correction_deg: float = field(
        default=15.0, metadata={"help": "a fix may turn the odometry guess at most this much [deg]"}
    )
    place_recognition: bool = field(
        default=False,
        metadata={"help": "when lost, search every island's model for the scan (a correlative "
                  "search around the island origin) before attempting a new island [bool]"},
    )
    recognition_min_inliers: float = field(
        default=0.8,
        metadata={"help": "a recognized place needs at least this fraction of scan points "
                  "within inlier_dist_m of the island's model after the fix [-]"},
    )
    recognition_margin: float = field(
        default=0.1,
        metadata={"help": "the best search score must beat the best pose at least 1 m or 30 deg "
                  "away by this much (else the place is ambiguous, e.g. a corridor) [-]"},
    )
    search_range_m: float = field(
        default=10.0,
        metadata={"help": "the place search's distance field reaches this far beyond the "
                  "coverage radius (the sensor's range) [m]"},
    )
    builder: BuilderConfig = field(
        default_factory=_laser_builder,
        metadata={"help": "eq. 3 (E_min, T_i, bound floor), line fit, measure, localization: "
                  "the live builder's core with a laser's fit and measure"},
    )

    def __post_init__(self) -> None:
        for name in ("coverage_radius_m", "relocalize_radius_m", "max_residual_m",
                     "max_correction_m", "max_correction_deg", "search_range_m"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise BuilderError(f"PassiveConfig.{name}: expected a number > 0, got {v!r}")
        if not 0.0 <= self.min_matched_fraction <= 1.0:
            raise BuilderError("PassiveConfig.min_matched_fraction: expected a value in [0, 1]")
        if self.half_window_scans < 0 or self.retry_scans < 0:
            raise BuilderError("PassiveConfig: half_window_scans and retry_scans must be >= 0")


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
                 fit: FitFn | None = None, evaluate: EvaluateFn | None = None) -> None:
        self.config = config if config is not None else PassiveConfig()
        cfg = self.config
        self.measures = Measures.of(cfg.builder, fit, evaluate)
        self.localize = localizer if localizer is not None else core_localizer(cfg.builder.localize)
        self.diagnostics = Diagnostics()
        self.recognizer = Recognizer(cfg.builder, self.diagnostics)
        self.events: list[BuilderEvent] = []
        self.islands: list[PassiveIsland] = []
        self.attempts: list[PassiveAttempt] = []
        self._scans: dict[int, _Scan] = {}  # the window around the next scan to decide
        self._received = 0  # scans received
        self._decided = 0  # scans decided
        self._odom: FloatArray | None = None
        self._odometry: list[tuple[Pose2D, FloatArray]] = []  # messages since the last scan
        self._track = OdometryTrack()  # epsilon (eq. 3), advanced as scans are decided
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
        return IslandRun(tuple(self.islands), tuple(self.attempts),
                         np.asarray(self._scan_island, dtype=np.int64),
                         np.asarray(self._scan_pose, dtype=np.float64).reshape(n, 3),
                         np.asarray(self._eps_log, dtype=np.float64), self.config)

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
            self._track.update(pose, cov)
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
                    self._current = k
                    break
        return fixed

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

    def _lost(self, i: int) -> None:
        """Scan i in no island, epsilon past E_min: a known place (place search), else an
        attempt at a new island."""
        if self.config.place_recognition and self.islands:
            found = self._recognize(i)
            if found is not None:
                self._record(i, *found)
                self._track.rel.reset()
                return
        self._attempt(i)

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
        self.recognizer.remember(isl.island.id, Pose2D(*(float(v) for v in isl.anchor_odom)),
                                 np.zeros((3, 3)))
        if cfg.place_recognition:
            self.recognizer.add_place_search(isl.island.id, PlaceSearch(
                isl.island.model, cfg.coverage_radius_m + cfg.search_range_m,
                cfg.coverage_radius_m))

    def _window_model(self, anchor: int) -> tuple[LineModel, list[tuple[int, FloatArray]]]:
        """Line model of the scans around `anchor` in the anchor's frame, and each scan's pose
        (odometry, refined against the anchor scan's own line model)."""
        cfg = self.config
        order = [anchor]
        for d in range(1, cfg.half_window_scans + 1):
            order += [j for j in (anchor + d, anchor - d) if j in self._scans]
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

    def _emit(self, kind: EventKind, t_s: float, odom: Pose2D, epsilon_m: float,
              **kw: object) -> None:
        self.diagnostics.counts[kind] += 1
        self.events.append(BuilderEvent(kind, t_s, odom, epsilon_m, **kw))  # type: ignore[arg-type]


def replace_builder(config: PassiveConfig, **changes: Any) -> PassiveConfig:
    """`config` with fields of its BuilderConfig replaced (e.g. line_fit, measure)."""
    return dataclasses.replace(config, builder=dataclasses.replace(config.builder, **changes))
