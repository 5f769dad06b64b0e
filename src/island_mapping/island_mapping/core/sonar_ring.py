"""The UCI wall-following robot's sonar ring (24 real ultrasound transducers, SCITOS G5): single
ring readings scored with a line model and the measures R and Fisher at the robot (pure).

The readings come from island_mapping.logs.uci_sonar.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import TypedDict

import numpy as np
import numpy.typing as npt
from island_msgs_py.errors import InputError
from island_msgs_py.types import ModelType

from island_mapping.core.lines import LineFitConfig, fit_lines
from island_mapping.core.measure import MeasureConfig, evaluate_models

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]


class SonarRingError(InputError):
    """Bad ring geometry or reading; the message names what was wrong."""


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
                raise SonarRingError(f"SonarRingConfig.{name}: expected a number >= 0, got {v!r}")


@dataclass(frozen=True, eq=False)
class SonarReadings:
    """UCI ring readings: ranges (K, 24) [m] in file order, labels (K,) the motion label."""

    ranges_m: FloatArray
    labels: tuple[str, ...]


def ring_angles() -> FloatArray:
    """Robot-frame angles [rad] of the 24 transducers (sensor 1 ahead, numbered clockwise)."""
    return -np.radians(np.arange(RING_SENSORS, dtype=np.float64) * RING_STEP_DEG)


def ring_points(ranges_m: npt.ArrayLike, cfg: SonarRingConfig) -> FloatArray:
    """(N, 2) echo points [m] in the robot frame of one reading (no-echo readings dropped)."""
    r = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
    if r.size != RING_SENSORS:
        raise SonarRingError(f"ring reading: expected {RING_SENSORS} ranges, got {r.size}")
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
    origin = np.zeros(2)

    def core_evaluate(segments: FloatArray) -> Mapping[ModelType, float]:
        return evaluate_models(segments, origin, c.measure)

    evaluate = evaluator if evaluator is not None else core_evaluate
    k = readings.ranges_m.shape[0]
    r = np.zeros(k)
    fisher = np.zeros(k)
    nseg = np.zeros(k, dtype=np.int64)
    for i in range(k):
        model = fit_lines(ring_points(readings.ranges_m[i], c), c.line_fit)
        nseg[i] = len(model)
        if len(model):
            m = evaluate(model.segments)
            r[i] = float(m.get(ModelType.LINE, 0.0))
            fisher[i] = float(m.get(ModelType.FISHER, 0.0))
    return RingScores(r, fisher, nseg)


# A single reading with R below this is "poorly constrained" (a corridor-like view).
RING_LOW_R = 0.3


class LabelMetrics(TypedDict):
    """R and Fisher score of the readings of one motion label (`ring_metrics`)."""

    count: int
    mean_r: float
    median_r: float
    mean_fisher: float
    median_fisher: float
    mean_segments: float
    frac_r_below_low: float  # fraction of the readings with R < RING_LOW_R [-]


class RingMetrics(TypedDict):
    """What `ring_metrics` returns (JSON-ready)."""

    readings: int
    mean_r: float | None  # None without readings
    low_r_threshold: float
    per_label: dict[str, LabelMetrics]


def ring_metrics(readings: SonarReadings, scores: RingScores) -> RingMetrics:
    """Per-label count, mean and median of R and of the Fisher score, the fraction of readings
    with R < RING_LOW_R (JSON-ready)."""
    labels = np.asarray(readings.labels)
    per: dict[str, LabelMetrics] = {}
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
