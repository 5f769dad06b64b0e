"""Real data: Kuemmerle relations, relative pose errors, the GMapping baseline, offline islands.

Pure core (numpy/scipy + other cores). Conventions:
- poses are rows (x [m], y [m], theta [rad]); a relative pose of b in the frame of a is a^-1 (+) b;
- "log time" is the CARMEN log's time since its start [s]; "relation time" is absolute UNIX
  time [s] as in `intel.relations`; relation time = log time + `INTEL_LOG_TO_UNIX_S`.

The GMapping trajectory of `intel.gfs.log` (see ../shared/data/README.md): every `FLASER` line
carries the corrected pose of its scan; every `ODOM` line carries "the corrected pose of the
previous scan plus the raw odometry accumulated since then". A relation time is matched to the
nearest log line; when a scan and an ODOM line are equally near (they often share a timestamp),
the scan's corrected pose wins. Scored on all 2984 relations this gives mean 0.0647 m / 2.13 deg,
median 0.0477 m / 1.50 deg (the README's 0.065 / 2.1 and 0.048 / 1.5).
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from island_msgs_py.errors import InputError
from island_msgs_py.geometry import (
    compose_poses,
    from_frame,
    point_segment_distance,
    relative_poses,
    wrap_angles,
)
from island_msgs_py.types import Island, LineModel, ModelType, Pose2D

from island_mapping.core.builder import BuilderConfig, eq3_bound, normalized_measures
from island_mapping.core.lines import LASER_LINE_FIT, LineFitConfig
from island_mapping.core.localize import LocalizeConfig, localize
from island_mapping.core.measure import MeasureConfig

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

# Relation time = log time + this [s] (the log's start in UNIX time; ../shared/data/README.md).
INTEL_LOG_TO_UNIX_S = 976052857.338
# A relation time matches a scan when they differ by at most this [s] (scans are ~3.35 s apart,
# relation timestamps sit within 6 ms of a log line).
SCAN_MATCH_TOLERANCE_S = 0.010


class RealDataError(InputError):
    """Malformed real-data input; the message names the file, the line and the problem."""


# --------------------------------------------------------------------------------------------
# Pose algebra on (N, 3) arrays
# --------------------------------------------------------------------------------------------


def _as_poses(a: npt.ArrayLike, name: str) -> FloatArray:
    arr = np.asarray(a, dtype=np.float64)
    if arr.ndim == 1:
        arr = arr.reshape(1, -1)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise RealDataError(f"{name}: expected (N, 3) poses (x, y, theta), got {arr.shape}")
    return arr


def relative_pose_errors(
    estimated: npt.ArrayLike, truth: npt.ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Per-row error of estimated relative poses against true ones (Kuemmerle et al. 2009).

    The error is truth^-1 (+) estimated; returns (translation error [m], |rotation error| [deg]).
    """
    err = relative_poses(truth, estimated)
    return np.hypot(err[:, 0], err[:, 1]), np.degrees(np.abs(err[:, 2]))


@dataclass(frozen=True)
class ErrorStats:
    """Summary of relative pose errors over a set of relations."""

    count: int
    mean_trans_err_m: float
    median_trans_err_m: float
    mean_rot_err_deg: float
    median_rot_err_deg: float

    @staticmethod
    def of(trans_m: npt.ArrayLike, rot_deg: npt.ArrayLike) -> ErrorStats:
        """Statistics of per-relation errors; NaN statistics when there are none."""
        t = np.asarray(trans_m, dtype=np.float64).reshape(-1)
        r = np.asarray(rot_deg, dtype=np.float64).reshape(-1)
        if t.size == 0:
            nan = float("nan")
            return ErrorStats(0, nan, nan, nan, nan)
        return ErrorStats(
            int(t.size),
            float(np.mean(t)),
            float(np.median(t)),
            float(np.mean(r)),
            float(np.median(r)),
        )

    def as_dict(self, prefix: str = "") -> dict[str, float | int | None]:
        """JSON-ready dict (NaN becomes None)."""

        def clean(v: float) -> float | None:
            return None if math.isnan(v) else round(v, 6)

        return {
            f"{prefix}count": self.count,
            f"{prefix}mean_trans_err_m": clean(self.mean_trans_err_m),
            f"{prefix}median_trans_err_m": clean(self.median_trans_err_m),
            f"{prefix}mean_rot_err_deg": clean(self.mean_rot_err_deg),
            f"{prefix}median_rot_err_deg": clean(self.median_rot_err_deg),
        }


# --------------------------------------------------------------------------------------------
# Relations
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Relations:
    """Ground-truth relative poses: pose at t2_s in the frame of the pose at t1_s.

    t1_s, t2_s: (N,) absolute UNIX times [s]; rel: (N, 3) (x [m], y [m], yaw [rad]).
    """

    t1_s: FloatArray
    t2_s: FloatArray
    rel: FloatArray

    def __len__(self) -> int:
        return int(self.t1_s.shape[0])


def parse_relations(lines: Iterable[str], source: str = "<relations>") -> Relations:
    """Parse `t1 t2 x y z roll pitch yaw` lines (blank lines and `#` comments skipped).

    Raises RealDataError naming `source` and the 1-based line number on a malformed line.
    """
    t1: list[float] = []
    t2: list[float] = []
    rel: list[tuple[float, float, float]] = []
    for lineno, line in enumerate(lines, start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        parts = text.split()
        if len(parts) != 8:
            raise RealDataError(
                f"{source}:{lineno}: expected 8 fields (t1 t2 x y z roll pitch yaw), "
                f"got {len(parts)}"
            )
        try:
            vals = [float(p) for p in parts]
        except ValueError as exc:
            raise RealDataError(f"{source}:{lineno}: not a number ({exc})") from None
        if not all(math.isfinite(v) for v in vals):
            raise RealDataError(f"{source}:{lineno}: NaN or infinite value")
        t1.append(vals[0])
        t2.append(vals[1])
        rel.append((vals[2], vals[3], vals[7]))
    return Relations(
        np.asarray(t1, dtype=np.float64),
        np.asarray(t2, dtype=np.float64),
        np.asarray(rel, dtype=np.float64).reshape(-1, 3),
    )


def read_relations(path: str | os.PathLike[str]) -> Relations:
    """Read a Kuemmerle relations file (see `parse_relations`)."""
    try:
        with open(path, encoding="utf-8") as f:
            return parse_relations(f, str(path))
    except OSError as exc:
        raise RealDataError(f"{path}: cannot read relations file ({exc.strerror})") from None


def match_times(
    query_s: npt.ArrayLike, reference_s: npt.ArrayLike, tolerance_s: float = SCAN_MATCH_TOLERANCE_S
) -> IntArray:
    """Index of the nearest reference time for each query time, -1 when farther than tolerance.

    `reference_s` need not be sorted. Among references with equal times (the Intel log stores
    6 significant digits: 10 ms steps after 1000 s) the first in input order is taken.
    """
    q = np.asarray(query_s, dtype=np.float64).reshape(-1)
    ref = np.asarray(reference_s, dtype=np.float64).reshape(-1)
    if ref.size == 0:
        return np.full(q.shape, -1, dtype=np.int64)
    order = np.argsort(ref, kind="stable")
    srt = ref[order]
    hi = np.clip(np.searchsorted(srt, q), 0, srt.size - 1)
    lo = np.clip(hi - 1, 0, srt.size - 1)
    pick = np.where(np.abs(srt[lo] - q) <= np.abs(srt[hi] - q), lo, hi)
    pick = np.searchsorted(srt, srt[pick], side="left")  # first of a block of equal times
    idx = order[pick].astype(np.int64)
    idx[np.abs(ref[idx] - q) > tolerance_s] = -1
    return idx


# --------------------------------------------------------------------------------------------
# The log's pose track (GMapping poses and raw odometry at every FLASER / ODOM line)
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class PoseTrack:
    """Poses at every FLASER and ODOM line of a GMapping-corrected CARMEN log, in file order.

    times_s: (M,) log time [s] (ODOM lines with time 0 are not odometry: they repeat the scan);
    gmapping: (M, 3) the GMapping pose (corrected for scans, corrected + raw odometry between);
    raw: (M, 3) raw odometry (an arbitrary but fixed frame);
    is_scan: (M,) True on FLASER lines; scan_index: (M,) index of the latest scan at or before
    the line (-1 before the first scan).
    """

    times_s: FloatArray
    gmapping: FloatArray
    raw: FloatArray
    is_scan: BoolArray
    scan_index: IntArray

    @property
    def scan_rows(self) -> IntArray:
        """Row indices of the scans, in scan order."""
        return np.flatnonzero(self.is_scan).astype(np.int64)


def parse_pose_track(lines: Iterable[str], source: str = "<log>") -> PoseTrack:
    """Read the poses of FLASER and ODOM lines (see `PoseTrack`); other lines are skipped.

    Only poses and times: the scans themselves come from island_mapping.bag.carmen.read_carmen.
    Kept here because the GMapping baseline depends on every ODOM line in file order (the
    nearest line to a relation time, the first of equal times, the scan on ties); ODOM lines
    with time 0 (the echo of the scan just logged) and those before the first scan are skipped.
    """
    times: list[float] = []
    gm: list[list[float]] = []
    raw: list[FloatArray] = []
    is_scan: list[bool] = []
    scan_idx: list[int] = []
    n_scans = 0
    last_corrected: FloatArray | None = None  # corrected pose of the latest scan
    last_raw_at_scan = np.zeros(3)  # raw odometry pose of the latest scan
    last_odom: FloatArray | None = None  # pose of the latest ODOM line
    for lineno, line in enumerate(lines, start=1):
        parts = line.split()
        if not parts or parts[0] not in ("FLASER", "ODOM"):
            continue
        try:
            if parts[0] == "FLASER":
                n = int(parts[1])
                pose = np.array([float(v) for v in parts[2 + n : 5 + n]], dtype=np.float64)
                t = float(parts[-1])
            else:
                pose = np.array([float(v) for v in parts[1:4]], dtype=np.float64)
                t = float(parts[-1])
        except (ValueError, IndexError):
            raise RealDataError(f"{source}:{lineno}: malformed {parts[0]} line") from None
        if pose.shape != (3,) or not np.all(np.isfinite(pose)) or not math.isfinite(t):
            raise RealDataError(f"{source}:{lineno}: malformed {parts[0]} pose or time")
        if parts[0] == "FLASER":
            if last_corrected is not None and last_odom is not None:
                inc = relative_poses(last_corrected, last_odom)
                last_raw_at_scan = compose_poses(last_raw_at_scan, inc)[0]
            last_corrected = pose
            last_odom = None
            times.append(t)
            gm.append(list(pose))
            raw.append(last_raw_at_scan.copy())
            is_scan.append(True)
            scan_idx.append(n_scans)
            n_scans += 1
        else:
            last_odom = pose
            if t == 0.0 or last_corrected is None:
                continue  # the repeat right after a scan, or odometry before the first scan
            times.append(t)
            gm.append(list(pose))
            raw.append(compose_poses(last_raw_at_scan, relative_poses(last_corrected, pose))[0])
            is_scan.append(False)
            scan_idx.append(n_scans - 1)
    if n_scans == 0:
        raise RealDataError(f"{source}: no FLASER lines")
    return PoseTrack(
        np.asarray(times, dtype=np.float64),
        np.asarray(gm, dtype=np.float64).reshape(-1, 3),
        np.asarray(raw, dtype=np.float64).reshape(-1, 3),
        np.asarray(is_scan, dtype=bool),
        np.asarray(scan_idx, dtype=np.int64),
    )


def read_pose_track(path: str | os.PathLike[str]) -> PoseTrack:
    """Read the pose track of a CARMEN log file (see `parse_pose_track`)."""
    try:
        with open(path, encoding="utf-8") as f:
            return parse_pose_track(f, str(path))
    except OSError as exc:
        raise RealDataError(f"{path}: cannot read log ({exc.strerror})") from None


def gmapping_poses_at(track: PoseTrack, times_unix_s: npt.ArrayLike) -> FloatArray:
    """The GMapping pose at absolute times: the nearest log line, a scan winning ties; (N, 3)."""
    t = np.asarray(times_unix_s, dtype=np.float64).reshape(-1) - INTEL_LOG_TO_UNIX_S
    scan_rows = track.scan_rows
    odom_rows = np.flatnonzero(~track.is_scan)
    i_s = scan_rows[match_times(t, track.times_s[scan_rows], math.inf)]
    if odom_rows.size == 0:
        return track.gmapping[i_s]
    i_o = odom_rows[match_times(t, track.times_s[odom_rows], math.inf)]
    use_scan = np.abs(track.times_s[i_s] - t) <= np.abs(track.times_s[i_o] - t)
    return track.gmapping[np.where(use_scan, i_s, i_o)]


def gmapping_relation_errors(
    track: PoseTrack, relations: Relations
) -> tuple[FloatArray, FloatArray]:
    """Per-relation (translation [m], rotation [deg]) errors of the GMapping trajectory."""
    p1 = gmapping_poses_at(track, relations.t1_s)
    p2 = gmapping_poses_at(track, relations.t2_s)
    return relative_pose_errors(relative_poses(p1, p2), relations.rel)


# --------------------------------------------------------------------------------------------
# Scans: beams, points, the sonar-like mode
# --------------------------------------------------------------------------------------------

# CARMEN FLASER with 180 readings: beam k at -90 deg + k * 1 deg, counter-clockwise (checked on
# the Intel log: consecutive scans placed by their corrected poses overlap to a 3 cm median only
# with this convention).
LASER_FIRST_BEAM_RAD = -math.pi / 2.0
LASER_BEAM_STEP_RAD = math.pi / 180.0
# Beam counts the tools accept: the full laser scan, and the sonar-like rings of issue 5.
SUPPORTED_BEAMS = (180, 24, 16)


def beam_angles(n_beams: int) -> FloatArray:
    """Angles [rad] of a CARMEN laser scan's n_beams readings (1 deg apart from -90 deg)."""
    return LASER_FIRST_BEAM_RAD + np.arange(n_beams, dtype=np.float64) * LASER_BEAM_STEP_RAD


def beam_subset(n_total: int, n_keep: int) -> IntArray:
    """Indices of n_keep beams spread evenly over a scan of n_total beams (sonar-like mode),
    each centred in its sector: the same beams as island_mapping.bag.carmen.sonar_like_indices
    (the MCAP importer), so both sonar-like modes see the same data."""
    if n_keep <= 0 or n_keep > n_total:
        raise RealDataError(f"beams: expected 1..{n_total} beams to keep, got {n_keep}")
    step = n_total / n_keep
    return np.floor(step / 2 + step * np.arange(n_keep)).astype(np.int64)


def scan_points(
    ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike, max_range_m: float
) -> FloatArray:
    """(N, 2) points [m] in the robot frame; readings that are non-finite, <= 0 or beyond
    max_range_m (no return: the Intel log reports 81.83 m) are dropped."""
    r = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
    a = np.asarray(angles_rad, dtype=np.float64).reshape(-1)
    if r.shape != a.shape:
        raise RealDataError(f"scan: {r.size} ranges for {a.size} beam angles")
    ok = np.isfinite(r) & (r > 0.0) & (r <= max_range_m)
    return np.stack([r[ok] * np.cos(a[ok]), r[ok] * np.sin(a[ok])], axis=1)


# --------------------------------------------------------------------------------------------
# Raw-odometry error model and epsilon
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class OdometryErrorModel:
    """Variance growth of the Intel robot's raw odometry, per metre driven and per radian turned.

    Defaults: least-squares fit (`fit_odometry_error_model`) of the squared per-scan differences
    between raw-odometry increments and GMapping-corrected increments over the whole Intel log
    (909 steps, 500 m, 283 rad turned); a median step of 0.67 m / 22 deg differs by 5.3 cm / 2.6
    deg. The corrected poses serve only to calibrate these four numbers.
    """

    var_xy_per_m_m2: float = field(
        default=0.0047, metadata={"help": "position variance added per metre driven [m^2/m]"}
    )
    var_xy_per_rad_m2: float = field(
        default=0.0062, metadata={"help": "position variance added per radian turned [m^2/rad]"}
    )
    var_theta_per_m_rad2: float = field(
        default=0.0056, metadata={"help": "heading variance added per metre driven [rad^2/m]"}
    )
    var_theta_per_rad_rad2: float = field(
        default=0.0020, metadata={"help": "heading variance added per radian turned [rad^2/rad]"}
    )

    def __post_init__(self) -> None:
        for name in ("var_xy_per_m_m2", "var_xy_per_rad_m2", "var_theta_per_m_rad2",
                     "var_theta_per_rad_rad2"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise RealDataError(f"OdometryErrorModel.{name}: expected a number >= 0, got {v!r}")


def fit_odometry_error_model(
    raw_increments: npt.ArrayLike, true_increments: npt.ArrayLike
) -> OdometryErrorModel:
    """Non-negative least squares of squared increment errors on (distance [m], |turn| [rad])."""
    from scipy.optimize import nnls

    raw = _as_poses(raw_increments, "raw_increments")
    tru = _as_poses(true_increments, "true_increments")
    if raw.shape != tru.shape or raw.shape[0] < 2:
        raise RealDataError("fit_odometry_error_model: need >= 2 matching increments")
    err = relative_poses(tru, raw)
    a = np.stack([np.hypot(tru[:, 0], tru[:, 1]), np.abs(tru[:, 2])], axis=1)
    xy, _ = nnls(a, err[:, 0] ** 2 + err[:, 1] ** 2)
    th, _ = nnls(a, err[:, 2] ** 2)
    return OdometryErrorModel(float(xy[0]), float(xy[1]), float(th[0]), float(th[1]))


class EpsilonTracker:
    """The paper's epsilon: estimated accumulated position error [m] since the last fix.

    First-order propagation per odometry increment (d [m], dtheta [rad]):
    var_theta += a_m d + a_r |dtheta|; var_xy += b_m d + b_r |dtheta| + var_theta d^2
    (the heading uncertainty swings every metre driven sideways); epsilon = sqrt(var_xy).
    """

    def __init__(self, model: OdometryErrorModel) -> None:
        self._m = model
        self.var_xy_m2 = 0.0
        self.var_theta_rad2 = 0.0

    def reset(self) -> None:
        """The robot knows where it is (it localized in an island)."""
        self.var_xy_m2 = 0.0
        self.var_theta_rad2 = 0.0

    def step(self, increment: npt.ArrayLike) -> float:
        """Add one raw-odometry increment (dx, dy, dtheta) [m, m, rad]; return epsilon [m]."""
        inc = np.asarray(increment, dtype=np.float64).reshape(3)
        d = float(math.hypot(inc[0], inc[1]))
        turn = abs(float(inc[2]))
        m = self._m
        self.var_theta_rad2 += m.var_theta_per_m_rad2 * d + m.var_theta_per_rad_rad2 * turn
        self.var_xy_m2 += (
            m.var_xy_per_m_m2 * d + m.var_xy_per_rad_m2 * turn + self.var_theta_rad2 * d * d
        )
        return self.epsilon_m

    @property
    def epsilon_m(self) -> float:
        return math.sqrt(self.var_xy_m2)


# --------------------------------------------------------------------------------------------
# Islands built offline over a log (the paper's mapping criterion, eq. 3)
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ScanFix:
    """Outcome of localizing one scan against an island's line model (island frame)."""

    pose: FloatArray  # (3,) x [m], y [m], theta [rad] in the island frame
    residual_m: float
    converged: bool
    matched_fraction: float


# (line model, (N, 2) scan points in the robot frame [m], initial pose (3,) in the island frame)
Localizer = Callable[[LineModel, FloatArray, FloatArray], ScanFix]
# (segments (K, 4) [m] in the island frame) -> {model type: measure at the origin}
Evaluator = Callable[[FloatArray], Mapping[ModelType, float]]
# ((N, 2) points [m]) -> line model
Fitter = Callable[[FloatArray], LineModel]


def _default_measure_config() -> MeasureConfig:
    # A laser sees walls at any incidence (no specular loss) and reliably farther than a sonar.
    return MeasureConfig(reflect_deg=80.0, max_range_m=10.0)


@dataclass(frozen=True)
class RealIslandConfig:
    """Offline island building and localization over a CARMEN log (single source of defaults)."""

    beams: int = field(
        default=180,
        metadata={"help": "beams kept from each 180-beam scan: 180 = laser, 24 or 16 = "
                  "sonar-like mode [-]"},
    )
    max_range_m: float = field(
        default=10.0, metadata={"help": "readings beyond this are ignored (no return) [m]"}
    )
    localize_beams: int = field(
        default=0,
        metadata={"help": "beams kept for localizing scans in islands (0 = `beams`); e.g. 24 "
                  "localizes sonar-like scans (6.5 m range) in islands built from the laser [-]"},
    )
    half_window_scans: int = field(
        default=2,
        metadata={"help": "an island model accumulates the scans this many steps before and "
                  "after the anchor scan [-]"},
    )
    align_window: bool = field(
        default=True,
        metadata={"help": "place each window scan by localizing it against the anchor scan's "
                  "own line model (False: by raw odometry only) [bool]"},
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
        metadata={"help": "islands whose origin is within this raw-odometry distance (plus "
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
    odometry: OdometryErrorModel = field(
        default_factory=OdometryErrorModel, metadata={"help": "raw-odometry error model (epsilon)"}
    )
    builder: BuilderConfig = field(
        default_factory=BuilderConfig,
        metadata={"help": "eq. 3: E_min, thresholds T_i, bound floor (core.builder)"},
    )
    line_fit: LineFitConfig = field(
        default_factory=lambda: LASER_LINE_FIT, metadata={"help": "line fitting of island data"}
    )
    measure: MeasureConfig = field(
        default_factory=_default_measure_config,
        metadata={"help": "the line-model measure R evaluated at the island origin"},
    )
    localize: LocalizeConfig = field(
        default_factory=LocalizeConfig, metadata={"help": "scan localization against islands"}
    )

    def __post_init__(self) -> None:
        if self.beams not in SUPPORTED_BEAMS:
            raise RealDataError(f"RealIslandConfig.beams: expected one of {SUPPORTED_BEAMS}, "
                                f"got {self.beams}")
        if self.localize_beams not in (0, *SUPPORTED_BEAMS):
            raise RealDataError(f"RealIslandConfig.localize_beams: expected 0 or one of "
                                f"{SUPPORTED_BEAMS}, got {self.localize_beams}")
        for name in ("max_range_m", "coverage_radius_m", "relocalize_radius_m", "max_residual_m",
                     "max_correction_m", "max_correction_deg"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise RealDataError(f"RealIslandConfig.{name}: expected a number > 0, got {v!r}")
        if not 0.0 <= self.min_matched_fraction <= 1.0:
            raise RealDataError("RealIslandConfig.min_matched_fraction: expected a value in [0, 1]")
        if self.half_window_scans < 0 or self.retry_scans < 0:
            raise RealDataError("RealIslandConfig: half_window_scans and retry_scans must be >= 0")


def sonar_like_config(beams: int, base: RealIslandConfig | None = None) -> RealIslandConfig:
    """The sonar-like mode: keep `beams` beams, sonar range (6.5 m) and sonar line fitting."""
    cfg = base if base is not None else RealIslandConfig()
    if beams == 180:
        return dataclasses.replace(cfg, beams=180)
    return dataclasses.replace(
        cfg,
        beams=beams,
        max_range_m=SONAR_LIKE_RANGE_M,
        line_fit=LineFitConfig(),
        half_window_scans=max(cfg.half_window_scans, SONAR_LIKE_HALF_WINDOW),
        max_residual_m=max(cfg.max_residual_m, 0.1),
        min_matched_fraction=min(cfg.min_matched_fraction, 0.5),
        measure=dataclasses.replace(cfg.measure, max_range_m=SONAR_LIKE_RANGE_M),
    )


# The sonar-like mode keeps a Nomad-200 sonar's range [m] and accumulates more scans per model
# (few beams per scan; the paper's four-corner routine also gathers several ring readings).
SONAR_LIKE_RANGE_M = 6.5
SONAR_LIKE_HALF_WINDOW = 4


@dataclass(frozen=True)
class Attempt:
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
class RealIsland:
    """An island built from the log: its line model in its own frame (origin = anchor scan)."""

    island: Island
    anchor_scan: int
    anchor_raw: FloatArray  # (3,) raw-odometry pose of the anchor scan (for re-localization)


@dataclass(frozen=True, eq=False)
class IslandRun:
    """Result of building islands over a log and localizing every scan in them.

    scan_island: (S,) id of the island a scan was localized in, -1 if none;
    scan_pose: (S, 3) the scan's pose in that island's frame (NaN when none);
    epsilon_m: (S,) epsilon at each scan, after its odometry increment and before a fix resets it.
    """

    islands: tuple[RealIsland, ...]
    attempts: tuple[Attempt, ...]
    scan_island: IntArray
    scan_pose: FloatArray
    epsilon_m: FloatArray
    config: RealIslandConfig


def core_localizer(config: LocalizeConfig | None = None) -> Localizer:
    """Localizer backed by core.localize (Dudek-MacKenzie correction, with heading)."""
    cfg = config if config is not None else LocalizeConfig()

    def run(model: LineModel, points: FloatArray, initial: FloatArray) -> ScanFix:
        res = localize(model, points, Pose2D.from_array(initial), cfg)
        return ScanFix(
            res.pose.as_array(), float(res.residual_m), bool(res.converged),
            float(res.matched_fraction),
        )

    return run


def core_evaluator(measure: MeasureConfig) -> Evaluator:
    """{LINE: R, FISHER: score} at the island origin (core.measure.evaluate_models)."""
    from island_mapping.core.measure import evaluate_models

    origin = np.zeros(2)

    def run(segments: FloatArray) -> Mapping[ModelType, float]:
        return evaluate_models(segments, origin, measure)

    return run


def core_fitter(config: LineFitConfig) -> Fitter:
    """Line fitting by core.lines.fit_lines."""
    from island_mapping.core.lines import fit_lines

    def run(points: FloatArray) -> LineModel:
        return fit_lines(points, config)

    return run


class _Scans:
    """Per-scan robot-frame points of the kept beams (computed once): `points` build island
    models, `fix_points` (the `localize_beams` subset, if set) are localized in them."""

    def __init__(self, ranges_m: FloatArray, cfg: RealIslandConfig) -> None:
        n_total = ranges_m.shape[1]
        angles = beam_angles(n_total)

        def points(n_keep: int, max_range_m: float) -> list[FloatArray]:
            keep = beam_subset(n_total, min(n_keep, n_total))
            return [scan_points(r[keep], angles[keep], max_range_m) for r in ranges_m]

        self.points = points(cfg.beams, cfg.max_range_m)
        if cfg.localize_beams and cfg.localize_beams != cfg.beams:
            self.fix_points = points(cfg.localize_beams, min(cfg.max_range_m, SONAR_LIKE_RANGE_M))
        else:
            self.fix_points = self.points


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


def _fix_ok(
    fix: ScanFix, guess: FloatArray, cfg: RealIslandConfig, points: FloatArray, model: LineModel
) -> bool:
    """A fix is trusted when it converged, moved the guess only a little, and enough of the
    scan's points lie on the model (points seeing beyond the island's model do not count
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
    dist = point_segment_distance(from_frame(points, fix.pose), model.segments).min(axis=1)
    return bool(np.mean(dist <= cfg.inlier_dist_m) >= cfg.min_inlier_fraction)


# Correlative place search: distance-field resolution [m], search grid over the coverage
# square [m] and headings [deg], points used (every k-th), and the score's distance scale [m].
_FIELD_RES_M = 0.1
_SEARCH_STEP_M = 0.2
_SEARCH_STEP_DEG = 10.0
_SEARCH_POINT_STRIDE = 4
_SEARCH_SIGMA_M = 0.1
# Two search optima closer than this are the same place hypothesis [m, deg].
_DISTINCT_M = 1.0
_DISTINCT_DEG = 30.0


class PlaceSearch:
    """Where could a scan be in an island? A brute-force correlative search of the island's
    line model (as a distance field) over positions within the coverage radius and all
    headings; the score of a pose is the mean of exp(-d^2 / 2 sigma^2) over the scan's points,
    d the distance to the model."""

    def __init__(self, model: LineModel, half_extent_m: float, coverage_m: float) -> None:
        from scipy.ndimage import distance_transform_edt

        self.res = _FIELD_RES_M
        self.half = half_extent_m
        n = math.ceil(2 * half_extent_m / self.res) + 1
        occ = np.ones((n, n), dtype=bool)
        for x1, y1, x2, y2 in model.segments:
            k = max(2, int(math.hypot(x2 - x1, y2 - y1) / (self.res / 2)) + 1)
            xs = np.linspace(x1, x2, k)
            ys = np.linspace(y1, y2, k)
            ix = np.round((xs + half_extent_m) / self.res).astype(np.int64)
            iy = np.round((ys + half_extent_m) / self.res).astype(np.int64)
            ok = (ix >= 0) & (ix < n) & (iy >= 0) & (iy < n)
            occ[iy[ok], ix[ok]] = False
        self.field = (distance_transform_edt(occ) * self.res).astype(np.float64)
        self.n = n
        ticks = np.arange(-coverage_m, coverage_m + 1e-9, _SEARCH_STEP_M)
        gx, gy = np.meshgrid(ticks, ticks)
        inside = np.hypot(gx, gy) <= coverage_m
        self.offsets = np.stack([gx[inside], gy[inside]], axis=1)
        self.headings = np.radians(np.arange(0.0, 360.0, _SEARCH_STEP_DEG))

    def search(self, points: FloatArray) -> tuple[FloatArray, float, float]:
        """(best pose (3,), its score, best score of a distinct hypothesis) for robot-frame
        points; scores are in [0, 1]."""
        pts = points[::_SEARCH_POINT_STRIDE]
        best = (np.zeros(3), -1.0)
        cands: list[tuple[float, float, float, float]] = []
        for th in self.headings:
            c, s_ = math.cos(th), math.sin(th)
            rot = np.stack([c * pts[:, 0] - s_ * pts[:, 1], s_ * pts[:, 0] + c * pts[:, 1]], 1)
            world = rot[None, :, :] + self.offsets[:, None, :]
            ij = np.round((world + self.half) / self.res).astype(np.int64)
            ok = (ij >= 0).all(axis=2) & (ij < self.n).all(axis=2)
            d = np.full(ok.shape, 10.0 * _SEARCH_SIGMA_M)
            d[ok] = self.field[ij[..., 1][ok], ij[..., 0][ok]]
            score = np.mean(np.exp(-0.5 * (d / _SEARCH_SIGMA_M) ** 2), axis=1)
            k = int(np.argmax(score))
            cands.append((float(score[k]), float(self.offsets[k, 0]), float(self.offsets[k, 1]),
                          float(th)))
            if score[k] > best[1]:
                best = (np.array([self.offsets[k, 0], self.offsets[k, 1], th]), float(score[k]))
        bp = best[0]
        second = 0.0
        for sc, x, y, th in cands:
            far = math.hypot(x - bp[0], y - bp[1]) > _DISTINCT_M
            turned = abs(math.degrees(wrap_angles(th - bp[2]))) > _DISTINCT_DEG
            if far or turned:
                second = max(second, sc)
        bp[2] = float(wrap_angles(bp[2]))
        return bp, best[1], second


# A fix from fewer scan points is not trusted (3 points barely constrain x, y and theta).
MIN_FIX_POINTS = 5


def build_islands_offline(
    ranges_m: npt.ArrayLike,
    raw_poses: npt.ArrayLike,
    times_s: npt.ArrayLike,
    config: RealIslandConfig | None = None,
    *,
    localizer: Localizer | None = None,
    evaluator: Evaluator | None = None,
    fitter: Fitter | None = None,
    progress: Callable[[int, int, int], None] | None = None,
) -> IslandRun:
    """Walk a log scan by scan as the exploring robot would, building islands by eq. 3.

    ranges_m (S, B) [m], raw_poses (S, 3) raw odometry, times_s (S,) [s]. Per scan: if the robot
    is tracking an island, the previous island-frame pose plus the raw-odometry increment is the
    guess for localizing the scan against that island's model; a trusted fix (`_fix_ok`: converged,
    small correction, enough inliers) inside the coverage radius keeps it there and resets
    epsilon. Otherwise islands whose origin lies near by raw odometry are tried. Every increment
    adds to epsilon; when a scan in no island finds epsilon > E_min an island is attempted there:
    the scans of a window around it are accumulated in its frame (raw odometry, refined by
    localizing each against the anchor scan's own line model), lines are fitted and every model
    type is evaluated at the origin; accepted when max_i R_i/T_i > E_min/epsilon
    (core.builder.eq3_bound, normalized_measures).
    `progress(scan, scans, islands)` is called after every scan when given.
    """
    cfg = config if config is not None else RealIslandConfig()
    rng = np.asarray(ranges_m, dtype=np.float64)
    raw = _as_poses(raw_poses, "raw_poses")
    t = np.asarray(times_s, dtype=np.float64).reshape(-1)
    if rng.ndim != 2 or rng.shape[0] != raw.shape[0] or t.shape[0] != raw.shape[0]:
        raise RealDataError(
            f"build_islands_offline: {rng.shape} ranges, {raw.shape[0]} poses, {t.shape[0]} times"
        )
    loc = localizer if localizer is not None else core_localizer(cfg.localize)
    evaluate = evaluator if evaluator is not None else core_evaluator(cfg.measure)
    fit = fitter if fitter is not None else core_fitter(cfg.line_fit)
    scans = _Scans(rng, cfg)
    n = raw.shape[0]
    scan_island = np.full(n, -1, dtype=np.int64)
    scan_pose = np.full((n, 3), np.nan)
    eps_log = np.zeros(n)
    islands: list[RealIsland] = []
    attempts: list[Attempt] = []
    eps = EpsilonTracker(cfg.odometry)
    current, pose = -1, np.zeros(3)
    next_attempt = 0
    searches: list[PlaceSearch] = []

    def try_fix(k: int, i: int, guess: FloatArray) -> FloatArray | None:
        pts = scans.fix_points[i]
        fix = loc(islands[k].island.model, pts, guess)
        if not _fix_ok(fix, guess, cfg, pts, islands[k].island.model):
            return None
        if math.hypot(fix.pose[0], fix.pose[1]) > cfg.coverage_radius_m:
            return None
        return fix.pose

    for i in range(n):
        if progress is not None and i > 0:
            progress(i, n, len(islands))
        inc = relative_poses(raw[i - 1], raw[i])[0] if i > 0 else np.zeros(3)
        fixed: FloatArray | None = None
        if current >= 0:
            guess = compose_poses(pose, inc)[0]
            fixed = try_fix(current, i, guess)
            if fixed is None:
                current = -1
        if fixed is None and islands:
            eps_now = math.sqrt(eps.var_xy_m2)
            near = []
            for k, isl in enumerate(islands):
                g = relative_poses(isl.anchor_raw, raw[i])[0]
                dist = math.hypot(g[0], g[1])
                if dist <= cfg.relocalize_radius_m + eps_now:
                    near.append((dist, k, g))
            for _, k, g in sorted(near, key=lambda x: x[0]):
                fixed = try_fix(k, i, g)
                if fixed is not None:
                    current = k
                    break
        eps_log[i] = eps.step(inc)
        if fixed is not None:
            pose = fixed
            scan_island[i], scan_pose[i] = current, fixed
            eps.reset()
            continue
        if eps.epsilon_m <= cfg.builder.e_min_m or i < next_attempt:
            continue
        if cfg.place_recognition and islands:
            found = _recognize(i, islands, searches, scans, cfg, loc)
            if found is not None:
                current, pose = found
                scan_island[i], scan_pose[i] = current, pose
                eps.reset()
                continue
        model, window = _window_model(i, raw, scans, cfg, fit, loc)
        measures = evaluate(model.segments) if len(model) else {}
        best_type, best = normalized_measures(cfg.builder, measures)
        bound = eq3_bound(cfg.builder, eps.epsilon_m)
        accepted = len(model) > 0 and best > bound
        attempts.append(
            Attempt(i, eps.epsilon_m, bound, best_type, best,
                    {k.value: float(v) for k, v in measures.items()}, len(model), accepted)
        )
        if not accepted:
            next_attempt = i + 1 + cfg.retry_scans
            continue
        new = Island(
            id=len(islands), model=model, model_type=best_type, r=float(best),
            built_at_s=float(t[i]),
        )
        islands.append(RealIsland(new, i, raw[i].copy()))
        if cfg.place_recognition:
            searches.append(PlaceSearch(model, cfg.coverage_radius_m + cfg.max_range_m,
                                        cfg.coverage_radius_m))
        current = new.id
        eps.reset()
        # The anchor and the buffered window scans are localized in the new island.
        for j, guess in window:
            if j > i or scan_island[j] >= 0:
                continue
            got = try_fix(current, j, guess)
            if got is not None:
                scan_island[j], scan_pose[j] = current, got
        pose = scan_pose[i] if scan_island[i] == current else np.zeros(3)
        if scan_island[i] != current:
            scan_island[i], scan_pose[i] = current, np.zeros(3)
    return IslandRun(tuple(islands), tuple(attempts), scan_island, scan_pose, eps_log, cfg)


def _recognize(
    i: int,
    islands: list[RealIsland],
    searches: list[PlaceSearch],
    scans: _Scans,
    cfg: RealIslandConfig,
    loc: Localizer,
) -> tuple[int, FloatArray] | None:
    """Place recognition for a lost robot: the island and island-frame pose of scan i, or None
    when no island explains the scan unambiguously (see RealIslandConfig.place_recognition)."""
    pts = scans.fix_points[i]
    if pts.shape[0] < MIN_FIX_POINTS:
        return None
    best: tuple[float, int, FloatArray] | None = None
    for k, search in enumerate(searches):
        guess, score, second = search.search(pts)
        if score - second < cfg.recognition_margin:
            continue
        if best is None or score > best[0]:
            best = (score, k, guess)
    if best is None:
        return None
    _, k, guess = best
    model = islands[k].island.model
    fix = loc(model, pts, guess)
    if not _fix_ok(fix, guess, cfg, pts, model):
        return None
    if math.hypot(fix.pose[0], fix.pose[1]) > cfg.coverage_radius_m:
        return None
    d = point_segment_distance(from_frame(pts, fix.pose), model.segments).min(axis=1)
    if np.mean(d <= cfg.inlier_dist_m) < cfg.recognition_min_inliers:
        return None
    return k, fix.pose


def _window_model(
    anchor: int,
    raw: FloatArray,
    scans: _Scans,
    cfg: RealIslandConfig,
    fit: Fitter,
    loc: Localizer,
) -> tuple[LineModel, list[tuple[int, FloatArray]]]:
    """Line model of the scans around `anchor` in the anchor's frame, and each scan's pose."""
    h = cfg.half_window_scans
    order = [anchor]
    for d in range(1, h + 1):
        order += [j for j in (anchor + d, anchor - d) if 0 <= j < raw.shape[0]]
    placed: list[tuple[int, FloatArray]] = []
    clouds: list[FloatArray] = []
    anchor_model: LineModel | None = None
    for j in order:
        guess = relative_poses(raw[anchor], raw[j])[0]
        pose = guess
        pts = scans.points[j]
        if anchor_model is not None and len(anchor_model) and pts.shape[0]:
            fix = loc(anchor_model, pts, guess)
            if _fix_ok(fix, guess, cfg, pts, anchor_model):
                pose = fix.pose
        placed.append((j, pose))
        clouds.append(from_frame(pts, pose))
        if cfg.align_window and j == anchor:
            anchor_model = fit(voxel_thin(pts, cfg.voxel_m))
    all_pts = np.concatenate(clouds) if clouds else np.zeros((0, 2))
    final = fit(voxel_thin(all_pts, cfg.voxel_m))
    return final, placed


# --------------------------------------------------------------------------------------------
# Scoring island localization on the relations
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class RelationScore:
    """Island localization scored on ground-truth relations.

    covered: (N,) both ends localized in the same island; island: (N,) that island (-1);
    trans_err_m, rot_err_deg: (N,) errors of covered relations (NaN elsewhere);
    islands: statistics over covered relations; gmapping_covered / gmapping_all: the GMapping
    trajectory on the same covered relations and on all relations; ends_at_scans: relations
    whose two times both have a pose source (a scan within tolerance, or a bridge);
    unresolvable: relations left out because both ends fall on the same scan or log line.
    """

    covered: BoolArray
    island: IntArray
    trans_err_m: FloatArray
    rot_err_deg: FloatArray
    islands: ErrorStats
    gmapping_covered: ErrorStats
    gmapping_all: ErrorStats
    ends_at_scans: int
    unresolvable: int = 0


def island_poses_at(
    run: IslandRun,
    scan_times_s: npt.ArrayLike,
    times_unix_s: npt.ArrayLike,
    *,
    track: PoseTrack | None = None,
    bridge_s: float = 0.0,
    tolerance_s: float = SCAN_MATCH_TOLERANCE_S,
) -> tuple[IntArray, FloatArray, BoolArray, IntArray]:
    """(island id (N,), island-frame pose (N, 3), has-a-pose-source (N,), source (N,)) at
    absolute times; source is the scan index, or S + the track row of a bridged log line, or -1.

    A time within `tolerance_s` of a scan takes that scan's fix. With a `track` and
    `bridge_s` > 0, a time that matches a log line (within tolerance) but no scan takes the fix
    of the nearer of the scans before and after it (at most `bridge_s` away) composed with the
    raw odometry between that scan and the time.
    """
    t_log = np.asarray(times_unix_s, dtype=np.float64).reshape(-1) - INTEL_LOG_TO_UNIX_S
    st = np.asarray(scan_times_s, dtype=np.float64).reshape(-1)
    j = match_times(t_log, st, tolerance_s)
    has = j >= 0
    isl = np.where(has, run.scan_island[np.maximum(j, 0)], -1).astype(np.int64)
    pose = np.where(has[:, None], run.scan_pose[np.maximum(j, 0)], np.nan)
    source = j.copy()
    if track is None or bridge_s <= 0:
        return isl, pose, has, source
    rows = track.scan_rows
    if rows.size < st.size:
        raise RealDataError(f"pose track has {rows.size} scans, the run {st.size}")
    line = match_times(t_log, track.times_s, tolerance_s)
    for q in np.flatnonzero(~has & (line >= 0)):
        r = int(line[q])
        best: tuple[float, int] | None = None
        for s in (int(track.scan_index[r]), int(track.scan_index[r]) + 1):
            if 0 <= s < st.size and run.scan_island[s] >= 0:
                dt = abs(st[s] - t_log[q])
                if dt <= bridge_s and (best is None or dt < best[0]):
                    best = (dt, s)
        has[q] = True
        source[q] = st.size + r
        if best is None:
            continue
        s = best[1]
        odo = relative_poses(track.raw[rows[s]], track.raw[r])
        isl[q] = run.scan_island[s]
        pose[q] = compose_poses(run.scan_pose[s], odo)[0]
    return isl, pose, has, source


def score_relations(
    run: IslandRun,
    scan_times_s: npt.ArrayLike,
    relations: Relations,
    track: PoseTrack | None = None,
    *,
    bridge_s: float = 0.0,
) -> RelationScore:
    """Relative pose errors of relations whose two ends were localized in the same island."""
    i1, p1, h1, s1 = island_poses_at(run, scan_times_s, relations.t1_s, track=track,
                                     bridge_s=bridge_s)
    i2, p2, h2, s2 = island_poses_at(run, scan_times_s, relations.t2_s, track=track,
                                     bridge_s=bridge_s)
    # Both ends on the same scan (or log line): the estimate is the identity whatever the
    # localization does, so the pair tests nothing. On the Intel log such pairs are 5-15 ms
    # apart in relation time yet 0.3 m apart in truth (the log keeps 6 significant digits).
    unresolvable = (s1 >= 0) & (s1 == s2)
    covered = (i1 >= 0) & (i1 == i2) & ~unresolvable
    n = len(relations)
    trans = np.full(n, np.nan)
    rot = np.full(n, np.nan)
    if np.any(covered):
        est = relative_poses(p1[covered], p2[covered])
        trans[covered], rot[covered] = relative_pose_errors(est, relations.rel[covered])
    if track is not None:
        gt, gr = gmapping_relation_errors(track, relations)
        g_cov, g_all = ErrorStats.of(gt[covered], gr[covered]), ErrorStats.of(gt, gr)
    else:
        g_cov = g_all = ErrorStats.of([], [])
    return RelationScore(
        covered, np.where(covered, i1, -1).astype(np.int64), trans, rot,
        ErrorStats.of(trans[covered], rot[covered]), g_cov, g_all, int(np.sum(h1 & h2)),
        int(np.sum(unresolvable)),
    )


# --------------------------------------------------------------------------------------------
# The UCI wall-following sonar ring (24 real ultrasound transducers, SCITOS G5)
# --------------------------------------------------------------------------------------------

# Transducers of the UCI ring: 24, 15 deg apart. The UCI description gives sensor 1 the
# "reference angle 180 deg" (the front) and sensor k the angle 180 - 15 (k - 1) deg, i.e. the
# ring is numbered clockwise from the front. Checked on the data: the robot follows the wall
# clockwise around the room (wall on its left), and sensors 16-21 (robot-frame +135..+60 deg
# under this convention) read the shortest ranges (median 0.7 m) in every motion class.
RING_SENSORS = 24
RING_STEP_DEG = 15.0


@dataclass(frozen=True)
class SonarRingConfig:
    """Geometry and scoring of the UCI sonar-ring readings (single source of defaults)."""

    max_range_m: float = field(
        default=5.0, metadata={"help": "the file's no-echo value; readings >= this are dropped [m]"}
    )
    ring_radius_m: float = field(
        default=0.25,
        metadata={"help": "assumed distance of the transducers from the robot centre (the UCI "
                  "description gives none; a SCITOS G5 is about 0.58 m wide) [m]"},
    )
    line_fit: LineFitConfig = field(
        default_factory=LineFitConfig, metadata={"help": "line fitting of one ring reading"}
    )
    measure: MeasureConfig = field(
        default_factory=lambda: MeasureConfig(max_range_m=5.0),
        metadata={"help": "the line-model measure R at the robot (sonar reflectance kept)"},
    )

    def __post_init__(self) -> None:
        for name in ("max_range_m", "ring_radius_m"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise RealDataError(f"SonarRingConfig.{name}: expected a number >= 0, got {v!r}")


@dataclass(frozen=True, eq=False)
class SonarReadings:
    """UCI ring readings: ranges (K, 24) [m] in file order, labels (K,) the motion label."""

    ranges_m: FloatArray
    labels: tuple[str, ...]


def parse_sonar_ring(
    lines: Iterable[str], source: str = "<sonar>", limit: int | None = None
) -> SonarReadings:
    """Parse the UCI `sensor_readings_24.data` text: an optional header line (`S1,...,OUTPUT`),
    then `r1,...,r24,Label` per line. At most `limit` readings are read. Raises RealDataError
    naming the line number on a malformed line."""
    ranges: list[list[float]] = []
    labels: list[str] = []
    for lineno, line in enumerate(lines, start=1):
        if limit is not None and len(ranges) >= limit:
            break
        text = line.strip()
        if not text:
            continue
        parts = [p.strip() for p in text.split(",")]
        if lineno == 1 and parts[0].upper() == "S1":
            continue  # the header
        if len(parts) != RING_SENSORS + 1:
            raise RealDataError(
                f"{source}:{lineno}: expected {RING_SENSORS} ranges and a label, "
                f"got {len(parts)} fields"
            )
        try:
            vals = [float(p) for p in parts[:RING_SENSORS]]
        except ValueError as exc:
            raise RealDataError(f"{source}:{lineno}: not a range ({exc})") from None
        if not all(math.isfinite(v) and v >= 0 for v in vals):
            raise RealDataError(f"{source}:{lineno}: a range is negative, NaN or infinite")
        if not parts[-1] or parts[-1][0].isdigit():
            raise RealDataError(f"{source}:{lineno}: missing motion label")
        ranges.append(vals)
        labels.append(parts[-1])
    return SonarReadings(np.asarray(ranges, dtype=np.float64).reshape(-1, RING_SENSORS),
                         tuple(labels))


def read_sonar_ring(path: str | os.PathLike[str], limit: int | None = None) -> SonarReadings:
    """Read a UCI sonar-ring file (see `parse_sonar_ring`)."""
    try:
        with open(path, encoding="utf-8") as f:
            return parse_sonar_ring(f, str(path), limit)
    except OSError as exc:
        raise RealDataError(f"{path}: cannot read sonar readings ({exc.strerror})") from None


def ring_angles() -> FloatArray:
    """Robot-frame angles [rad] of the 24 transducers (sensor 1 ahead, numbered clockwise)."""
    return -np.radians(np.arange(RING_SENSORS, dtype=np.float64) * RING_STEP_DEG)


def ring_points(ranges_m: npt.ArrayLike, cfg: SonarRingConfig) -> FloatArray:
    """(N, 2) echo points [m] in the robot frame of one reading (no-echo readings dropped)."""
    r = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
    if r.size != RING_SENSORS:
        raise RealDataError(f"ring reading: expected {RING_SENSORS} ranges, got {r.size}")
    a = ring_angles()
    ok = np.isfinite(r) & (r > 0) & (r < cfg.max_range_m)
    d = r[ok] + cfg.ring_radius_m
    return np.stack([d * np.cos(a[ok]), d * np.sin(a[ok])], axis=1)


@dataclass(frozen=True, eq=False)
class RingScores:
    """Per reading: line-model measure R at the robot, Fisher score, segment count."""

    r: FloatArray
    fisher: FloatArray
    segments: IntArray


def score_ring_readings(
    readings: SonarReadings,
    cfg: SonarRingConfig | None = None,
    evaluator: Callable[[FloatArray], Mapping[ModelType, float]] | None = None,
) -> RingScores:
    """Fit lines to each single reading's ring points and evaluate R and the Fisher score at
    the robot (the origin of the reading's frame)."""
    c = cfg if cfg is not None else SonarRingConfig()
    fit = core_fitter(c.line_fit)
    evaluate = evaluator if evaluator is not None else core_evaluator(c.measure)
    k = readings.ranges_m.shape[0]
    r = np.zeros(k)
    fisher = np.zeros(k)
    nseg = np.zeros(k, dtype=np.int64)
    for i in range(k):
        model = fit(ring_points(readings.ranges_m[i], c))
        nseg[i] = len(model)
        if len(model):
            m = evaluate(model.segments)
            r[i] = float(m.get(ModelType.LINE, 0.0))
            fisher[i] = float(m.get(ModelType.FISHER, 0.0))
    return RingScores(r, fisher, nseg)


# A single reading with R below this is "poorly constrained" (a corridor-like view).
RING_LOW_R = 0.3


def ring_metrics(readings: SonarReadings, scores: RingScores) -> dict[str, object]:
    """Per-label count, mean and median of R and of the Fisher score, the fraction of readings
    with R < RING_LOW_R (JSON-ready)."""
    labels = np.asarray(readings.labels)
    per: dict[str, object] = {}
    for lab in sorted(set(readings.labels)):
        sel = labels == lab
        per[lab] = {
            "count": int(np.sum(sel)),
            "mean_r": round(float(np.mean(scores.r[sel])), 6),
            "median_r": round(float(np.median(scores.r[sel])), 6),
            "mean_fisher": round(float(np.mean(scores.fisher[sel])), 6),
            "median_fisher": round(float(np.median(scores.fisher[sel])), 6),
            "mean_segments": round(float(np.mean(scores.segments[sel])), 3),
            "frac_r_below_low": round(float(np.mean(scores.r[sel] < RING_LOW_R)), 4),
        }
    return {
        "readings": int(labels.size),
        "mean_r": round(float(np.mean(scores.r)), 6) if labels.size else None,
        "low_r_threshold": RING_LOW_R,
        "per_label": per,
    }
