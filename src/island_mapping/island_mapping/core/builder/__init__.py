"""The island builder: where to build islands of reliability (paper sections 5 and 8.2, eq. 3).

Pure decision logic (numpy only, no ROS). Modules, each one job:

- `config`: BuilderConfig, StarConfig, RevisitConfig (the single source of defaults);
- `events`: what the builder tells its driver (commands, events, their JSON);
- `epsilon`: eq. 3 (RelativeCovariance, eq3_bound, normalized_measures, Measures);
- `star`: the star's decisions as functions (leg registration, the origin's peak, probes);
- `checks`: the localization check and registrations onto a model;
- `recognition`: the Recognizer of known islands (revisits) and its link graph (`links`), with
  the correlative place search (`places`) as a strategy for a lost robot;
- `calibration`: the odometry's systematic heading error (rotation scale, curvature), learnt
  online from docks and revisits; `known`: the known origins, kept in its corrected frame;
- `uncertainty`: the full covariance of the robot's pose relative to a known island's origin
  (loop-closure candidates and the gate's Mahalanobis distance);
- `follow`: when an attempt may start while the follower drives;
- `motion`: turns, straight drives, docking and looks (no decisions);
- `path_record`: an edge's strategy from the way driven (odometry simplified to a polyline);
- `diagnostics`: counts, refusals, probes;
- `machine`: IslandBuilder, the state machine that wires them (the live builder);
- `passive`: PassiveBuilder, the same core on a recording (no star: a log cannot be driven);
- `inputs`: checked scans and odometry, and `feed`, which applies what the project's one
  stamp pairer (`island_msgs_py.stamps.ScanOdomPairer`, every_odometry) released.
"""

from island_mapping.core.builder.calibration import (
    CalibrationConfig,
    Mark,
    Measurement,
    OdometryCalibration,
)
from island_mapping.core.builder.checks import leg_heading, localizes_back, register_look
from island_mapping.core.builder.config import (
    BuilderConfig,
    BuilderError,
    RevisitConfig,
    StarConfig,
)
from island_mapping.core.builder.diagnostics import Diagnostics, ProbeOutcome, Refusal
from island_mapping.core.builder.epsilon import (
    CoreMeasures,
    EvaluateFn,
    FitFn,
    Measures,
    RelativeCovariance,
    eq3_bound,
    normalized_measures,
)
from island_mapping.core.builder.events import (
    BuilderCommand,
    BuilderEvent,
    CommandMode,
    DismissReason,
    EventKind,
    Hypothesis,
    event_to_dict,
)
from island_mapping.core.builder.follow import follower_settled, follower_turning
from island_mapping.core.builder.inputs import (
    GROUND_TRUTH,
    BuilderInputs,
    checked_cov,
    checked_scan,
    feed,
)
from island_mapping.core.builder.machine import IslandBuilder
from island_mapping.core.builder.passive import IslandRun, PassiveBuilder, PassiveConfig
from island_mapping.core.builder.path_record import PathRecord, strategy_from_path
from island_mapping.core.builder.recognition import PoseSnapshot, Recognition, Recognizer
from island_mapping.core.builder.star import Survey, peak_origin

__all__ = [
    "GROUND_TRUTH",
    "BuilderCommand",
    "BuilderConfig",
    "BuilderError",
    "BuilderEvent",
    "BuilderInputs",
    "CalibrationConfig",
    "CommandMode",
    "CoreMeasures",
    "Diagnostics",
    "DismissReason",
    "EvaluateFn",
    "EventKind",
    "FitFn",
    "Hypothesis",
    "IslandBuilder",
    "IslandRun",
    "Mark",
    "Measurement",
    "Measures",
    "OdometryCalibration",
    "PassiveBuilder",
    "PassiveConfig",
    "PathRecord",
    "PoseSnapshot",
    "ProbeOutcome",
    "Recognition",
    "Recognizer",
    "Refusal",
    "RelativeCovariance",
    "RevisitConfig",
    "StarConfig",
    "Survey",
    "checked_cov",
    "checked_scan",
    "eq3_bound",
    "event_to_dict",
    "feed",
    "follower_settled",
    "follower_turning",
    "leg_heading",
    "localizes_back",
    "normalized_measures",
    "peak_origin",
    "register_look",
    "strategy_from_path",
]
