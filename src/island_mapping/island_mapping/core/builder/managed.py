"""The island builder's managed mode: the explorer's inputs (`core.builder.hooks`).

`ManagedInputs` is a base of `IslandBuilder` (core.builder.machine): the robot docked by the
explorer, the handover to the follower, an abort, and the answers to a held decision (confirm
one hypothesis or reject them all, `core.builder.held`). The state machine's own steps stay in
the machine; what these inputs call of it is declared here.
"""

from __future__ import annotations

from island_msgs_py.types import ControlStrategy, Island, Pose2D, PrimitiveKind

from island_mapping.core.builder.config import BuilderError
from island_mapping.core.builder.events import EventKind
from island_mapping.core.builder.follow import FollowGate, ScanHistory
from island_mapping.core.builder.held import Held, held_choices
from island_mapping.core.builder.hooks import (
    APPROACH_M,
    BuilderHooks,
    Departure,
    approach_path,
    gate_refusal,
)
from island_mapping.core.builder.opening import Openings
from island_mapping.core.builder.path_record import PathRecord
from island_mapping.core.builder.recognition import PoseSnapshot, Recognition, Recognizer
from island_mapping.core.builder.star import Attempt
from island_mapping.core.builder.state import State
from island_mapping.core.builder.view import BuilderView


class ManagedInputs(BuilderView):
    """The explorer's inputs (module docstring); the machine sets these attributes."""

    hooks: BuilderHooks
    recognizer: Recognizer
    _state: State
    _strategy: ControlStrategy
    _departure: Departure | None
    _openings: Openings
    _path: PathRecord
    _gate: FollowGate
    _history: ScanHistory
    _attempt: Attempt | None
    _held: Held | None
    _t: float

    @property
    def _odom(self) -> Pose2D | None:
        return self._track.pose

    @property
    def state(self) -> str:
        return self._state.value

    def snapshot(self) -> PoseSnapshot:
        """The robot's pose, covariance and error since the last island, for recognition."""
        track, last = self._track, self.ledger.last_island
        assert track.pose is not None
        return PoseSnapshot(track.pose, track.cov, self.epsilon_m, track.rel.heading_sigma_rad,
                            None if last is None else last.id,
                            self._path_m - self.ledger.start_path_m)

    def _emit(self, kind: EventKind, epsilon_m: float | None = None, **kw: object) -> None:
        raise NotImplementedError  # the machine's

    def _build(self) -> None:
        raise NotImplementedError  # the machine's

    def _link_revisit(self, rec: Recognition, legs_m: tuple[tuple[float, float], ...],
                      strategy_end: Pose2D | None, epsilon_m: float, heading_sigma_rad: float,
                      seen: tuple[Pose2D, float] | None = None) -> Pose2D:
        raise NotImplementedError  # the machine's

    def on_docked(self, island_id: int, origin_odom: Pose2D) -> None:
        """The robot is docked at island island_id's origin, which lies at origin_odom in the
        odometry frame: it is the last island, and epsilon restarts there. Only while IDLE."""
        island = self._managed_island("on_docked", island_id)
        self.recognizer.remember(island.id, origin_odom, self._track.cov.copy())
        self._track.rel.reset()
        self.ledger.handed_back(island, self._path_m)
        self._strategy = ControlStrategy(())

    def handover(self, island_id: int, exit_index: int | None, prefix: ControlStrategy) -> None:
        """Leave island island_id (the last docked) by exit exit_index (None: by no known exit)
        after driving `prefix` from its origin: the follower drives, the builder decides."""
        island = self._managed_island("handover", island_id)
        if self.ledger.last_island is None or self.ledger.last_island.id != island.id:
            raise BuilderError(f"handover: the robot is not docked at island {island_id}")
        if exit_index is not None and all(e.index != exit_index for e in island.exits):
            raise BuilderError(f"handover: island {island_id} has no exit {exit_index} (its "
                               f"exits: {[e.index for e in island.exits]})")
        self._departure = Departure(island.id, exit_index, prefix)
        self._openings.reset()  # openings count from a hallway driven after the handover
        self._strategy = prefix
        self._path.restart(self._odom)
        self._path_m += sum(s.metres for s in prefix.steps if s.kind is PrimitiveKind.GO)
        self._gate.retry_at_path_m = self._path_m
        self._history.quick.clear()
        self._history.revisit.clear()
        self._state = State.FOLLOWING
        self._emit(EventKind.HANDED_OVER, anchor_odom=self._odom)

    def abort(self) -> bool:
        """Take the robot back for the explorer (managed mode): from FOLLOWING to IDLE (event
        STOPPED). False while the builder is busy (a star, a dock): ask again later."""
        if not self.hooks.managed or self._state not in (State.FOLLOWING, State.IDLE):
            return False
        if self._state is State.FOLLOWING:
            self._emit(EventKind.STOPPED)
        self._state = State.IDLE
        self._departure = None
        return True

    def confirm(self, island_id: int) -> None:
        """The held star was at island island_id (the explorer's evidence, `core.builder.held`):
        the edge from the last island links it as a revisit and no island is built. IDLE
        after: the robot is where the explorer drove it, which reports its dock next."""
        held = self._held
        if held is None or self._odom is None:
            raise BuilderError(f"confirm: no decision is held (the builder is {self.state})")
        choice = held.choice(island_id)
        held.attempt.outcome = EventKind.ISLAND_REVISITED
        self._attempt, self._track.star, self._held = None, None, None
        origin = self._link_revisit(held.now(choice, self._odom), tuple(held.attempt.legs_done),
                                    choice.end, held.epsilon_m, held.heading_sigma_rad,
                                    seen=(choice.rec.pose, held.t_s))
        self.recognizer.remember(island_id, origin, held.cov, cov_at=held.odom)
        self.ledger.handed_back(self.ledger.island(island_id), self._path_m)
        self._strategy, self._departure = ControlStrategy(()), None
        self._path.restart(self._odom)
        self._history.quick.clear()
        self._history.revisit.clear()
        self._openings.reset()
        self._state = State.IDLE

    def reject(self) -> None:
        """None of the held star's hypotheses held: its island is built as it would have been
        without them (the robot back near the star's anchor)."""
        if self._held is None:
            raise BuilderError(f"reject: no decision is held (the builder is {self.state})")
        self._held = None
        self._build()

    def _hold(self, att: Attempt) -> bool:
        """Hold the star's decision for the explorer when it fits more than one known island
        and the gate admits some of them (`core.builder.held`); True when held."""
        limit = self.hooks.hold_hypotheses
        if limit <= 0 or not self.recognizer.hypotheses or self._odom is None:
            return False
        snap, approach = self.snapshot(), approach_path(self._strategy, APPROACH_M)
        choices = held_choices(
            self.recognizer.hypotheses, {i.id: i for i in self.islands},
            self._odom.relative_to(att.anchor).inverse(),
            lambda rec, island, end: gate_refusal(self.hooks, rec, snap, island, True,
                                                  approach, end) is None, limit)
        if not choices:
            return False
        self._held = Held(att, choices, self._odom, self._track.cov.copy(), self.epsilon_m,
                          self._track.rel.heading_sigma_rad, self._t)
        self._state = State.HELD
        self._emit(EventKind.REVISIT_HYPOTHESIS, anchor_odom=att.anchor,
                   hypotheses=self._held.event_hypotheses())
        return True

    def _managed_island(self, what: str, island_id: int) -> Island:
        if not self.hooks.managed:
            raise BuilderError(f"{what}: the builder is not in managed mode")
        found = [i for i in self.ledger.islands if i.id == island_id]
        if not found:  # wrong whatever the state: said first
            ids = sorted(i.id for i in self.ledger.islands)
            raise BuilderError(f"{what}: unknown island {island_id} (the builder has "
                               f"{len(ids)}: {ids[:20]})")
        if self._state is not State.IDLE or self._odom is None:
            raise BuilderError(f"{what}: only while idle (the builder is {self._state.value})")
        return found[0]

