"""The passive mode's configuration (`core.builder.passive`): how a recording's scans build
islands and are localized in them, with the live builder's `BuilderConfig` inside (single
source of the passive mode's defaults)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any

from island_mapping.core.builder.config import BuilderConfig, BuilderError
from island_mapping.core.lines import LASER_LINE_FIT
from island_mapping.core.localize import LocalizeConfig
from island_mapping.core.measure import MeasureConfig


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


def replace_builder(config: PassiveConfig, **changes: Any) -> PassiveConfig:
    """`config` with fields of its BuilderConfig replaced (e.g. line_fit, measure)."""
    return dataclasses.replace(config, builder=dataclasses.replace(config.builder, **changes))
