"""Shared data types of the islands-of-reliability map (numpy only, no ROS).

The global map of Simhon and Dudek (eq. 1) is M = {V, E}: a node (an *island*) holds a local
line-segment model L in its own frame and the model type T that accepted it; an edge holds the
control strategy S that drives the robot from the source island's origin to the target island's
origin, and a weight W.

An island also records its *exits*: the directions in its own frame in which free space leads
away from it, each `unexplored`, `explored` (by which edge) or `blocked`; an edge may say by which
exit it leaves its source and enters its target.

Conventions used everywhere in the project:
- poses are (x [m], y [m], theta [rad]) with theta wrapped to (-pi, pi];
- line segments are rows (x1, y1, x2, y2) [m] of an (N, 4) float array;
- control strategies use the paper's Table 1 units: Go in centimetres, Rot in degrees
  (counter-clockwise, in [0, 360)).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
import numpy.typing as npt

from island_msgs_py.errors import InputError
from island_msgs_py.limits import (
    MAX_EXIT_INDEX,
    MAX_EXITS_PER_ISLAND,
    MAX_GO_CM,
    MAX_ISLAND_ID,
    MAX_LENGTH_M,
    MAX_STRATEGY_STEPS,
)

FloatArray = npt.NDArray[np.float64]


class IslandTypeError(InputError):
    """A value of a shared type is malformed (the message names the field and the problem)."""


def wrap_angle(theta_rad: float) -> float:
    """Wrap an angle [rad] to (-pi, pi]."""
    wrapped = math.atan2(math.sin(theta_rad), math.cos(theta_rad))
    return math.pi if wrapped == -math.pi else wrapped


def _require_finite(name: str, *values: float) -> None:
    for v in values:
        if not math.isfinite(v):
            raise IslandTypeError(f"{name}: expected a finite number, got {v!r}")


@dataclass(frozen=True)
class Pose2D:
    """A planar pose: x, y [m] and heading theta [rad]."""

    x: float
    y: float
    theta: float

    def __post_init__(self) -> None:
        _require_finite("Pose2D", self.x, self.y, self.theta)

    def as_array(self) -> FloatArray:
        """(3,) array [x m, y m, theta rad]."""
        return np.array([self.x, self.y, self.theta], dtype=np.float64)

    @staticmethod
    def from_array(a: npt.ArrayLike) -> Pose2D:
        v = np.asarray(a, dtype=np.float64).reshape(-1)
        if v.shape != (3,):
            raise IslandTypeError(f"Pose2D: expected 3 values (x, y, theta), got {v.shape[0]}")
        return Pose2D(float(v[0]), float(v[1]), float(v[2]))

    def compose(self, other: Pose2D) -> Pose2D:
        """self (+) other: `other` expressed in this pose's frame, returned in the parent frame."""
        c, s = math.cos(self.theta), math.sin(self.theta)
        return Pose2D(
            self.x + c * other.x - s * other.y,
            self.y + s * other.x + c * other.y,
            wrap_angle(self.theta + other.theta),
        )

    def inverse(self) -> Pose2D:
        c, s = math.cos(self.theta), math.sin(self.theta)
        return Pose2D(-c * self.x - s * self.y, s * self.x - c * self.y, wrap_angle(-self.theta))

    def relative_to(self, base: Pose2D) -> Pose2D:
        """This pose expressed in the frame of `base` (base^-1 (+) self)."""
        return base.inverse().compose(self)


class PrimitiveKind(StrEnum):
    """A control-strategy step: drive straight (Go, cm) or rotate in place (Rot, deg CCW)."""

    GO = "Go"
    ROT = "Rot"


@dataclass(frozen=True)
class StrategyPrimitive:
    """One step of a control strategy in the paper's units: Go [cm] or Rot [deg, CCW, 0-360)."""

    kind: PrimitiveKind
    value: int

    def __post_init__(self) -> None:
        if self.kind is PrimitiveKind.GO and not 0 <= self.value <= MAX_GO_CM:
            raise IslandTypeError(
                f"Go distance must be in [0, {MAX_GO_CM}] cm, got {self.value}")
        if self.kind is PrimitiveKind.ROT and not 0 <= self.value < 360:
            raise IslandTypeError(f"Rot angle must be in [0, 360) deg, got {self.value}")

    def __str__(self) -> str:
        return f"{self.kind.value} {self.value}"

    @property
    def metres(self) -> float:
        """Go distance [m] (0 for a rotation)."""
        return self.value / 100.0 if self.kind is PrimitiveKind.GO else 0.0

    @property
    def radians(self) -> float:
        """Rotation [rad] in (-pi, pi] (0 for a Go); Rot 270 is a quarter turn clockwise."""
        return wrap_angle(math.radians(self.value)) if self.kind is PrimitiveKind.ROT else 0.0


_PRIMITIVE_RE = re.compile(r"^\s*(Go|Rot)\s+(-?\d+)\s*$", re.IGNORECASE)
_MAX_STEP_DIGITS = len(str(MAX_GO_CM))  # a longer number is out of range whatever it is


@dataclass(frozen=True)
class ControlStrategy:
    """Ordered primitives, printed like the paper's Table 1: `Go 125, Rot 270, Go 652`."""

    steps: tuple[StrategyPrimitive, ...] = ()

    def __str__(self) -> str:
        return ", ".join(str(s) for s in self.steps)

    @staticmethod
    def parse(text: str) -> ControlStrategy:
        """Parse `Go 125, Rot 270, Go 652`; an empty string is the empty strategy."""
        if not text.strip():
            return ControlStrategy(())
        parts = text.split(",", MAX_STRATEGY_STEPS)
        if len(parts) > MAX_STRATEGY_STEPS:
            raise IslandTypeError(
                f"control strategy: more than {MAX_STRATEGY_STEPS} steps (the limit)")
        steps = []
        for part in parts:
            m = _PRIMITIVE_RE.match(part)
            if m is None:
                raise IslandTypeError(f"control strategy: cannot parse step {_short(part)}")
            if len(m.group(2).lstrip("-")) > _MAX_STEP_DIGITS:
                raise IslandTypeError(
                    f"control strategy: step {_short(part)} has more than {_MAX_STEP_DIGITS} "
                    "digits (out of range)")
            kind = PrimitiveKind.GO if m.group(1).lower() == "go" else PrimitiveKind.ROT
            steps.append(StrategyPrimitive(kind, int(m.group(2))))
        return ControlStrategy(tuple(steps))

    @property
    def length_m(self) -> float:
        """Total Go distance [m]."""
        return sum(s.metres for s in self.steps)


def _short(text: str, limit: int = 40) -> str:
    """repr of `text`, cut to `limit` characters (error messages quote input, not megabytes)."""
    t = repr(text.strip())
    return t if len(t) <= limit else t[: limit - 3] + "..."


class ModelType(StrEnum):
    """The model types T_i that can accept an island (eq. 3)."""

    LINE = "line"  # the paper's sonar line-model measure R (eqs. 4-12)
    FISHER = "fisher"  # Fisher information / Cramer-Rao bound (Censi 2007)


def as_segments(a: npt.ArrayLike, name: str = "segments") -> FloatArray:
    """Validate and return an (N, 4) float64 array of finite segments (x1, y1, x2, y2) [m]."""
    arr = np.asarray(a, dtype=np.float64)
    if arr.size == 0:
        return np.zeros((0, 4), dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 4:
        raise IslandTypeError(f"{name}: expected an (N, 4) array, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        bad = int(np.argwhere(~np.isfinite(arr))[0][0])
        raise IslandTypeError(f"{name}: segment {bad} has a NaN or infinite coordinate")
    return arr


@dataclass(frozen=True, eq=False)
class LineModel:
    """A local metric map: line segments (N, 4) [m] in the island's own frame."""

    segments: FloatArray = field(default_factory=lambda: np.zeros((0, 4)))

    def __post_init__(self) -> None:
        object.__setattr__(self, "segments", as_segments(self.segments, "LineModel.segments"))

    def __eq__(self, other: object) -> bool:
        return isinstance(other, LineModel) and np.array_equal(self.segments, other.segments)

    def __len__(self) -> int:
        return int(self.segments.shape[0])


class ExitState(StrEnum):
    """What is known of an exit of an island."""

    UNEXPLORED = "unexplored"  # free space leads on; nobody has driven it yet
    EXPLORED = "explored"  # driven: the edge that drove it is recorded
    BLOCKED = "blocked"  # tried or seen closed: not worth exploring


class ExitSide(StrEnum):
    """The side of the robot a side opening lies on (the turn that enters it)."""

    LEFT = "left"  # a quarter turn counter-clockwise
    RIGHT = "right"  # a quarter turn clockwise


@dataclass(frozen=True)
class Exit:
    """A direction in which free space leads away from an island, in the island's own frame.

    `index` names the exit within its island (unique there, >= 0); `heading_rad` is the
    direction from the island origin [rad] in [-pi, pi]; `width_m` the opening's width [m];
    `edge` is the (source, target) of the edge that explored it: set exactly when the state is
    `explored`.

    A *side exit* is an opening seen beside the way while driving an edge: `prefix` is the
    strategy from the island's origin (facing its theta 0) to the opening and `side` the turn
    that enters it there; its `heading_rad` is then the heading after that turn. Both are set
    or neither (a plain exit at the origin).
    """

    index: int
    heading_rad: float
    width_m: float
    state: ExitState = ExitState.UNEXPLORED
    edge: tuple[int, int] | None = None
    prefix: ControlStrategy | None = None
    side: ExitSide | None = None

    def __post_init__(self) -> None:
        name = f"exit {self.index}"
        if isinstance(self.index, bool) or not isinstance(self.index, int | np.integer) or not (
            0 <= self.index <= MAX_EXIT_INDEX
        ):
            raise IslandTypeError(f"{name}: index must be an integer in [0, {MAX_EXIT_INDEX}]")
        _require_finite(f"{name} heading_rad", self.heading_rad)
        if not -math.pi <= self.heading_rad <= math.pi:
            raise IslandTypeError(
                f"{name}: heading_rad must be in [-pi, pi], got {self.heading_rad}")
        _require_finite(f"{name} width_m", self.width_m)
        if not 0.0 < self.width_m <= MAX_LENGTH_M:
            raise IslandTypeError(
                f"{name}: width_m must be in (0, {MAX_LENGTH_M:g}] m, got {self.width_m}")
        if not isinstance(self.state, ExitState):
            raise IslandTypeError(f"{name}: unknown state {self.state!r}")
        if self.edge is not None:
            if len(self.edge) != 2 or not all(
                isinstance(v, int | np.integer) and not isinstance(v, bool) for v in self.edge
            ):
                raise IslandTypeError(f"{name}: edge must be (source, target) island ids")
            object.__setattr__(self, "edge", (int(self.edge[0]), int(self.edge[1])))
        if (self.state is ExitState.EXPLORED) != (self.edge is not None):
            raise IslandTypeError(
                f"{name}: an explored exit names the edge that explored it, and only an "
                f"explored one (state {self.state.value}, edge {self.edge})")
        self._check_side(name)

    def _check_side(self, name: str) -> None:
        if (self.prefix is None) != (self.side is None):
            raise IslandTypeError(
                f"{name}: a side exit has both a prefix and a side (prefix {self.prefix}, "
                f"side {self.side})")
        if self.prefix is None:
            return
        if not isinstance(self.prefix, ControlStrategy):
            raise IslandTypeError(f"{name}: prefix must be a control strategy, got "
                                  f"{type(self.prefix).__name__}")
        if self.prefix.length_m <= 0.0:
            raise IslandTypeError(f"{name}: a side exit's prefix must drive (a Go), got "
                                  f"{str(self.prefix)!r}")
        if not isinstance(self.side, ExitSide):
            raise IslandTypeError(f"{name}: unknown side {self.side!r} (known: left, right)")

    @property
    def is_side(self) -> bool:
        """A side exit (reached by `prefix` then a turn to `side`), not one at the origin."""
        return self.prefix is not None


@dataclass(frozen=True)
class ExitUpdate:
    """A change of one exit's state: island `island`, exit `index`, the new state and, when
    explored, the (source, target) of the edge that explored it."""

    island: int
    index: int
    state: ExitState
    edge: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        _check_island_id(self.island, "exit update island")
        Exit(self.index, 0.0, 1.0, self.state, self.edge)  # the same checks as an exit's


@dataclass(frozen=True)
class NewExit:
    """An exit added to an existing island (a side opening seen on an edge that left it)."""

    island: int
    exit: Exit

    def __post_init__(self) -> None:
        _check_island_id(self.island, "new exit island")
        if not isinstance(self.exit, Exit):
            raise IslandTypeError(f"new exit: expected an Exit, got {type(self.exit).__name__}")


def _check_island_id(value: int, name: str) -> None:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or not (
        0 <= value <= MAX_ISLAND_ID
    ):
        raise IslandTypeError(f"{name} must be an integer in [0, {MAX_ISLAND_ID}], got {value!r}")


def _check_exits(island_id: int, exits: tuple[Exit, ...]) -> tuple[Exit, ...]:
    """Exits sorted by index; unique indices; an explored exit's edge touches the island."""
    if len(exits) > MAX_EXITS_PER_ISLAND:
        raise IslandTypeError(
            f"island {island_id}: {len(exits)} exits (the limit is {MAX_EXITS_PER_ISLAND})")
    seen: set[int] = set()
    for e in exits:
        if not isinstance(e, Exit):
            raise IslandTypeError(f"island {island_id}: expected an Exit, got {type(e).__name__}")
        if e.index in seen:
            raise IslandTypeError(f"island {island_id}: duplicate exit index {e.index}")
        seen.add(e.index)
        if e.edge is not None and island_id not in e.edge:
            raise IslandTypeError(
                f"island {island_id}: exit {e.index} explored by edge {e.edge[0]}->{e.edge[1]}, "
                "which does not touch the island")
    return tuple(sorted(exits, key=lambda e: e.index))


@dataclass(frozen=True)
class Island:
    """A node v_i = {L, T} of the global map, plus what the builder knew when it accepted it.

    `origin_truth` is the simulator's true pose of the island origin, kept for evaluation only
    (None on real data); no algorithm may use it.
    """

    id: int
    model: LineModel
    model_type: ModelType
    r: float  # best normalized measure max_i(R_i / T_i) at acceptance
    built_at_s: float  # time of acceptance [s] (sim or log time)
    frame_id: str = ""
    origin_truth: Pose2D | None = None
    exits: tuple[Exit, ...] = ()  # sorted by index

    def __post_init__(self) -> None:
        _check_island_id(self.id, "island id")
        object.__setattr__(self, "exits", _check_exits(self.id, tuple(self.exits)))
        _require_finite(f"island {self.id} r", self.r)
        _require_finite(f"island {self.id} built_at_s", self.built_at_s)
        if not self.frame_id:
            object.__setattr__(self, "frame_id", f"island_{self.id}")


@dataclass(frozen=True)
class Edge:
    """An edge e = {v_i v_j, S, W}: the strategy from source's origin to target's origin."""

    source: int
    target: int
    strategy: ControlStrategy
    weight: float  # cost used for planning: length travelled [m] plus expected error [m]
    length_m: float = 0.0
    expected_error_m: float = 0.0
    source_exit: int | None = None  # the exit of the source island the edge leaves by
    target_exit: int | None = None  # the exit of the target island the edge enters by

    def __post_init__(self) -> None:
        _check_island_id(self.source, f"edge {self.source}->{self.target}: source")
        _check_island_id(self.target, f"edge {self.source}->{self.target}: target")
        for end in ("source_exit", "target_exit"):
            v = getattr(self, end)
            if v is not None and (isinstance(v, bool) or not isinstance(v, int | np.integer)
                                  or not 0 <= v <= MAX_EXIT_INDEX):
                raise IslandTypeError(
                    f"edge {self.source}->{self.target}: {end} must be an exit index in "
                    f"[0, {MAX_EXIT_INDEX}] or None, got {v!r}")
        if self.source == self.target:
            raise IslandTypeError(f"edge {self.source}->{self.target}: an edge to itself")
        _require_finite(f"edge {self.source}->{self.target} weight", self.weight)
        if self.weight < 0:
            raise IslandTypeError(f"edge {self.source}->{self.target}: negative weight")
