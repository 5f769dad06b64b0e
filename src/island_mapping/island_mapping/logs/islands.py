"""Islands from a log's scans and odometry: the log's beams become points, and the builder's
passive mode (island_mapping.core.builder.passive) walks the scans as the exploring robot would
(`build_islands_offline`). The laser mode keeps every beam; the sonar-like modes keep 24 or 16
beams (the same beams as the MCAP importer), a sonar's range and line fit, and a wider window.
Loops are closed as live exploration closes them (`loop_closure`: exploration's revisit search
and gate, `core.explore.loop_closure_hooks`, installed in the passive mode).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from island_msgs_py.errors import InputError
from island_msgs_py.geometry import from_frame
from island_msgs_py.types import Pose2D

from island_mapping.core.builder.epsilon import (
    EvaluateFn,
    FitFn,
    OdometryErrorModel,
    propagate_covariances,
)
from island_mapping.core.builder.passive import (
    IslandRun,
    Localizer,
    PassiveBuilder,
    PassiveConfig,
    replace_builder,
)
from island_mapping.core.explore import ExplorerConfig, loop_closure_hooks
from island_mapping.core.lines import LineFitConfig
from island_mapping.logs.carmen import flaser_angles, sonar_like_indices
from island_mapping.logs.geometry import ScanGeometry, SensorKind

FloatArray = npt.NDArray[np.float64]

LASER_BEAMS = 180
"""`beams` value of the laser mode: every beam of the scan, whatever its count."""
SUPPORTED_BEAMS = (LASER_BEAMS, 24, 16)
"""Beam counts the tools accept: the full laser scan, and the sonar-like rings (24, 16)."""
SONAR_LIKE_RANGE_M = 6.5
"""The sonar-like modes keep a Nomad-200 sonar's range [m]..."""
SONAR_LIKE_HALF_WINDOW = 4
"""...and accumulate more scans per island model (few beams per scan; the paper's four-corner
routine also gathers several ring readings)."""


class OfflineError(InputError):
    """Bad offline-builder input; the message names the argument and the problem."""


@dataclass(frozen=True)
class OfflineConfig:
    """Which beams of a log's scans build islands and which are localized in them, and the
    passive builder (single source of the offline defaults)."""

    beams: int = field(
        default=180,
        metadata={"help": "beams kept from each scan: 180 = laser (every beam, whatever the "
                  "scan's count), 24 or 16 = sonar-like mode [-]"},
    )
    max_range_m: float = field(
        default=10.0, metadata={"help": "readings beyond this are ignored (no return) [m]"}
    )
    localize_beams: int = field(
        default=0,
        metadata={"help": "beams kept for localizing scans in islands (0 = `beams`); e.g. 24 "
                  "localizes sonar-like scans (6.5 m range) in islands built from the laser [-]"},
    )
    odometry: OdometryErrorModel = field(
        default_factory=OdometryErrorModel,
        metadata={"help": "the raw odometry's error model, which propagates the covariance the "
                  "log does not record (epsilon, eq. 3)"},
    )
    islands: PassiveConfig = field(
        default_factory=PassiveConfig, metadata={"help": "the passive builder"}
    )
    loop_closure: bool = field(
        default=True,
        metadata={"help": "before each attempt, recognize known islands with live "
                  "exploration's revisit search and loop-closure gate (full covariance since an "
                  "island's origin was last known) [bool]"},
    )
    explorer: ExplorerConfig = field(
        default_factory=ExplorerConfig,
        metadata={"help": "live exploration's settings whose revisit search and gate "
                  "(revisit, revisit_near_m, revisit_max_mahalanobis2) close loops"},
    )

    def __post_init__(self) -> None:
        if self.beams not in SUPPORTED_BEAMS:
            raise OfflineError(f"OfflineConfig.beams: expected one of {SUPPORTED_BEAMS}, "
                               f"got {self.beams}")
        if self.localize_beams not in (0, *SUPPORTED_BEAMS):
            raise OfflineError(f"OfflineConfig.localize_beams: expected 0 or one of "
                               f"{SUPPORTED_BEAMS}, got {self.localize_beams}")
        if not (math.isfinite(self.max_range_m) and self.max_range_m > 0):
            raise OfflineError(f"OfflineConfig.max_range_m: expected a number > 0, got "
                               f"{self.max_range_m!r}")


def sonar_like_config(beams: int, base: OfflineConfig | None = None) -> OfflineConfig:
    """The sonar-like mode: keep `beams` beams, sonar range (6.5 m) and sonar line fitting."""
    cfg = base if base is not None else OfflineConfig()
    if beams == LASER_BEAMS:
        return dataclasses.replace(cfg, beams=LASER_BEAMS)
    return dataclasses.replace(_sonar_settings(cfg), beams=beams)


def for_sensor(cfg: OfflineConfig, geometry: ScanGeometry) -> OfflineConfig:
    """The configuration for the log's sensor: a sonar ring's readings (`SensorKind.SONAR_RING`,
    read from the data: `logs.geometry`) are built with the sonar settings of the sonar-like
    mode, every transducer kept; a laser's, or a sonar-like beam count chosen, as given."""
    if geometry.sensor is SensorKind.SONAR_RING and cfg.beams == LASER_BEAMS:
        return _sonar_settings(cfg)
    return cfg


def mode_text(cfg: OfflineConfig, geometry: ScanGeometry) -> str:
    """How the scans were used, for the console and the figure's title."""
    if geometry.sensor is SensorKind.SONAR_RING and cfg.beams == LASER_BEAMS:
        mode = f"sonar ring, every transducer, sonar line fit to {cfg.max_range_m:g} m"
    elif cfg.beams == LASER_BEAMS:
        mode = "laser"
    else:
        mode = f"sonar-like, {cfg.beams} beams"
    if cfg.localize_beams and cfg.localize_beams != cfg.beams:
        mode += f"; scans localized from {cfg.localize_beams} beams"
    return mode


def _sonar_settings(cfg: OfflineConfig) -> OfflineConfig:
    """A sonar's range (6.5 m), line fitting and window, the beams kept unchanged."""
    isl = cfg.islands
    islands = dataclasses.replace(
        replace_builder(isl, line_fit=LineFitConfig(),
                        measure=dataclasses.replace(isl.builder.measure,
                                                    max_range_m=SONAR_LIKE_RANGE_M)),
        half_window_scans=max(isl.half_window_scans, SONAR_LIKE_HALF_WINDOW),
        max_residual_m=max(isl.max_residual_m, 0.1),
        min_matched_fraction=min(isl.min_matched_fraction, 0.5),
        search_range_m=SONAR_LIKE_RANGE_M,
    )
    return dataclasses.replace(cfg, max_range_m=SONAR_LIKE_RANGE_M, islands=islands)


def scan_points(ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike, max_range_m: float,
                origins_m: npt.ArrayLike | None = None) -> FloatArray:
    """(N, 2) points [m] in the sensor frame, each beam from its origin (origins_m (B, 2) [m],
    default the sensor's origin); readings that are non-finite, <= 0 or beyond max_range_m (no
    return: the Intel log reports 81.83 m) are dropped."""
    r = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
    a = np.asarray(angles_rad, dtype=np.float64).reshape(-1)
    if r.shape != a.shape:
        raise OfflineError(f"scan: {r.size} ranges for {a.size} beam angles")
    ok = np.isfinite(r) & (r > 0.0) & (r <= max_range_m)
    pts = np.stack([r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok])], axis=1)
    if origins_m is None:
        return pts
    o = np.asarray(origins_m, dtype=np.float64).reshape(-1, 2)
    if o.shape[0] != r.size:
        raise OfflineError(f"scan: {r.size} ranges for {o.shape[0]} beam origins")
    return pts + o[ok]


def beam_points(ranges_m: FloatArray, cfg: OfflineConfig, angles_rad: npt.ArrayLike | None = None,
                mount: npt.ArrayLike | None = None, origins_m: npt.ArrayLike | None = None
                ) -> tuple[list[FloatArray], list[FloatArray]]:
    """Per scan of (S, B) ranges at `angles_rad` (B,) [rad] (default: the CARMEN FLASER
    format's, `flaser_angles`, which refuses beam counts it cannot know) from `origins_m`
    (B, 2) [m] (default the sensor's origin): the points that build island models (the kept
    beams) and the points localized in them (the `localize_beams` subset, if set), in the
    robot frame (`mount`: the sensor's pose on the robot)."""
    n_total = ranges_m.shape[1]
    angles = (flaser_angles(n_total) if angles_rad is None
              else np.asarray(angles_rad, dtype=np.float64).reshape(-1))
    if angles.shape != (n_total,):
        raise OfflineError(f"scan: {n_total} ranges per scan for {angles.size} beam angles")
    at = None if mount is None else np.asarray(mount, dtype=np.float64).reshape(3)
    origins = (np.zeros((n_total, 2)) if origins_m is None
               else np.asarray(origins_m, dtype=np.float64).reshape(-1, 2))

    def points(n_keep: int, max_range_m: float) -> list[FloatArray]:
        keep = (np.arange(n_total) if n_keep == LASER_BEAMS
                else sonar_like_indices(n_total, min(n_keep, n_total)))
        pts = [scan_points(r[keep], angles[keep], max_range_m, origins[keep]) for r in ranges_m]
        return pts if at is None or not np.any(at) else [from_frame(p, at) for p in pts]

    build = points(cfg.beams, cfg.max_range_m)
    if cfg.localize_beams and cfg.localize_beams != cfg.beams:
        return build, points(cfg.localize_beams, min(cfg.max_range_m, SONAR_LIKE_RANGE_M))
    return build, build


def build_islands_offline(
    ranges_m: npt.ArrayLike,
    raw_poses: npt.ArrayLike,
    times_s: npt.ArrayLike,
    config: OfflineConfig | None = None,
    *,
    localizer: Localizer | None = None,
    fitter: FitFn | None = None,
    evaluator: EvaluateFn | None = None,
    progress: Callable[[int, int, int], None] | None = None,
    angles_rad: npt.ArrayLike | None = None,
    mount: npt.ArrayLike | None = None,
    origins_m: npt.ArrayLike | None = None,
) -> IslandRun:
    """Islands over a log's scans: ranges_m (S, B) [m] at `angles_rad` from `origins_m`
    (`beam_points`),
    raw_poses (S, 3) the raw odometry at each scan, times_s (S,) [s], fed scan by scan to the
    passive builder with the covariance the odometry error model propagates along the raw odometry.
    `progress(scan, scans, islands)` is called after every scan when given."""
    cfg = config if config is not None else OfflineConfig()
    rng = np.asarray(ranges_m, dtype=np.float64)
    raw = np.asarray(raw_poses, dtype=np.float64)
    t = np.asarray(times_s, dtype=np.float64).reshape(-1)
    if rng.ndim != 2 or raw.ndim != 2 or raw.shape[1:] != (3,) or not (
        rng.shape[0] == raw.shape[0] == t.shape[0]
    ):
        raise OfflineError(
            f"build_islands_offline: {rng.shape} ranges, {raw.shape} poses, {t.shape[0]} times"
        )
    build, fix = beam_points(rng, cfg, angles_rad, mount, origins_m)
    hooks = loop_closure_hooks(cfg.explorer) if cfg.loop_closure else None
    builder = PassiveBuilder(cfg.islands, localizer=localizer, fit=fitter, evaluate=evaluator,
                             hooks=hooks)
    covs = propagate_covariances(raw, cfg.odometry)
    n = raw.shape[0]
    for i in range(n):
        builder.on_odometry(float(t[i]), Pose2D(*(float(v) for v in raw[i])), covs[i])
        builder.on_scan(float(t[i]), build[i], fix[i])
        if progress is not None and i > 0:
            progress(i, n, len(builder.islands))
    return builder.finish()
