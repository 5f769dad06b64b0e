"""The island builder's state machine: where to build islands of reliability (paper sections
5 and 8.2, eq. 3), wiring the decisions of the other modules of this package.

States: WAITING (no odometry or scan yet) -> the first island's star, or FOLLOWING (the hall
follower drives; `follow` decides when to attempt, `recognition` whether the place is a known
island) -> STAR (the four legs; `star` registers them and decides accept or dismiss) ->
PROBING (an origin past the legs, checked on the spot) -> RETURNING (onto the origin, facing
theta 0) -> FOLLOWING; or, on a recognised island, DOCKING (onto its origin, look around,
re-localize) -> FOLLOWING. `command(t)` is called once per scan and returns FOLLOW or DRIVE(v, w)
and the events since the last call. docs/builder.md describes the decisions.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from island_msgs_py.geometry import ranges_to_points, unwind_sign
from island_msgs_py.types import (
    ControlStrategy,
    FloatArray,
    Island,
    LineModel,
    Pose2D,
)

from island_mapping.core.builder import motion, star
from island_mapping.core.builder.checks import localizes_back
from island_mapping.core.builder.config import BuilderConfig
from island_mapping.core.builder.diagnostics import Diagnostics, ProbeOutcome
from island_mapping.core.builder.docking import Dock, dock_step
from island_mapping.core.builder.epsilon import (
    EvaluateFn,
    FitFn,
    Measures,
    OdometryTrack,
    eq3_bound,
)
from island_mapping.core.builder.events import (
    BuilderCommand,
    BuilderEvent,
    CommandMode,
    DismissReason,
    EventKind,
)
from island_mapping.core.builder.follow import (
    FollowGate,
    Following,
    FollowStep,
    ScanHistory,
    follow_step,
    straight_behind_m,
)
from island_mapping.core.builder.geometry import concat, to_frame
from island_mapping.core.builder.held import Held
from island_mapping.core.builder.hooks import (
    APPROACH_M,
    BuilderHooks,
    Departure,
    approach_path,
    arrival_heading,
    exit_evidence,
    exit_updates,
    facing_exit,
    gate_refusal,
    hooked_config,
    with_exits,
)
from island_mapping.core.builder.inputs import checked_cov, checked_scan
from island_mapping.core.builder.ledger import Ledger
from island_mapping.core.builder.managed import ManagedInputs
from island_mapping.core.builder.motion import STOP, LookPhase, StallWatch, Twist
from island_mapping.core.builder.opening import Openings
from island_mapping.core.builder.path_record import PathRecord
from island_mapping.core.builder.recognition import Recognition, Recognizer
from island_mapping.core.builder.star import Attempt
from island_mapping.core.builder.state import State


# size-ok: one method per state and transition; the decisions are already functions
class IslandBuilder(ManagedInputs):
    """The island builder state machine (see the module docstring).

    Call `on_odometry` for every odometry message, `on_scan` for every scan, `set_strategy`
    whenever the hall follower publishes its executed strategy, `on_ground_truth` (evaluation
    only: stamped on islands as origin_truth), and `command(t)` once per scan. `fit` and
    `evaluate` replace the line fit and the model evaluation (tests); `hooks` are an
    explorer's (managed mode, exits, a revisit gate: `core.builder.hooks`).
    """

    def __init__(self, config: BuilderConfig | None = None, fit: FitFn | None = None,
                 evaluate: EvaluateFn | None = None, hooks: BuilderHooks | None = None) -> None:
        self.hooks = hooks if hooks is not None else BuilderHooks()
        self.config = hooked_config(config, self.hooks)
        self._departure: Departure | None = None
        self.measures = Measures.of(self.config, fit, evaluate)
        self.diagnostics = Diagnostics()
        self.recognizer = Recognizer(self.config, self.diagnostics)
        self._state = State.WAITING
        self._track = OdometryTrack(self.recognizer.calibration)
        self._truth: Pose2D | None = None
        self._last_scan: tuple[FloatArray, FloatArray] | None = None
        self._path_m = 0.0  # odometric path length while following [m]
        self._history = ScanHistory()
        self._gate = FollowGate()
        self._openings = Openings(self.config.opening)
        self._stall = StallWatch(self.config.drive_stall_s)
        self._gave_up = False  # the drive under way stalled: it ends where the robot is
        self._strategy = ControlStrategy(())
        self._path = PathRecord(self.config.edge_path_tolerance_m, self.config.edge_shortcut_m,
                                self.config.edge_loop_m)  # the follower's way
        self._attempt: Attempt | None = None
        self._dock: Dock | None = None
        self._held: Held | None = None
        self._events: list[BuilderEvent] = []
        self._t = 0.0
        self.ledger = Ledger(self.recognizer)

    # ----- inputs -----

    def on_odometry(self, t_s: float, odom_pose: Pose2D, cov3x3: npt.ArrayLike) -> None:
        """Latest odometry pose and its 3x3 covariance (x, y, theta) [m, rad]."""
        cov = checked_cov(t_s, cov3x3)
        moved = self._track.update(odom_pose, cov)
        if self._state is State.FOLLOWING:
            self._path_m += moved
            self._path.add(odom_pose)
        self._t = max(self._t, t_s)

    def on_ground_truth(self, pose: Pose2D) -> None:
        """The simulator's true pose, stored on islands as origin_truth for evaluation only."""
        self._truth = pose

    def set_strategy(self, strategy: ControlStrategy) -> None:
        """The hall follower's strategy executed since its last reset (at the last island, or
        at the explorer's handover: then it follows the handover's prefix)."""
        self._strategy = self._with_prefix(strategy)

    def _with_prefix(self, record: ControlStrategy) -> ControlStrategy:
        """`record` after the handover's prefix (if any), then the opening's steps (if any)."""
        prefix = () if self._departure is None else self._departure.prefix.steps
        return ControlStrategy(prefix + record.steps + self._openings.steps())

    def _edge_strategy(self) -> ControlStrategy:
        """The strategy of the edge the robot is on: the way it drove (edge_path_tolerance_m
        > 0), or the follower's record."""
        return self._with_prefix(self._path.strategy()) if self._path.on else self._strategy

    def on_scan(self, t_s: float, ranges_m: npt.ArrayLike, angles_rad: npt.ArrayLike) -> None:
        """A sonar scan: ranges from the robot centre [m] (inf = no echo) at robot-frame angles."""
        r, a = checked_scan(t_s, ranges_m, angles_rad)
        self._t = max(self._t, t_s)
        self._last_scan = (r, a)
        if self._odom is None:
            return
        pts = ranges_to_points(r, a, self._odom)
        near = r <= self.config.revisit.max_range_m  # far sonar echoes are wide cones
        near_pts = ranges_to_points(r[near], a[near], self._odom)  # for recognising known islands
        if self._state is State.STAR and self._attempt is not None:
            self._attempt.add_scan(pts, near_pts, self._odom, self.config.centre_radius_m, (r, a))
        look = self._look()
        if look is not None:
            if look.phase is LookPhase.LOOK:
                look.points.append(pts)
            return
        if self._state in (State.IDLE, State.HELD):  # the explorer drives: not its history
            return
        if self._state is State.FOLLOWING and self.config.opening.enabled:
            self._openings.observe(r, a, self._path_m, self._odom.theta)
        self._history.add(self._path_m, pts, near_pts, self._state is State.FOLLOWING,
                          self.config)

    # ----- queries (more in core.builder.view and .managed) -----

    def recognize(self) -> Recognition | None:
        """Search the known islands near the odometric pose for the recent scan points (the
        last revisit.history_m of path, echoes within revisit.max_range_m); see
        `Recognizer.recognize`."""
        if self._odom is None:
            return None
        return self.recognizer.recognize_recent(
            self._history.revisit_points(), self._odom, self.snapshot(), self.islands)

    # ----- the decision step -----

    def command(self, t_s: float) -> BuilderCommand:
        """What to do now (call once per scan) and the events since the last call."""
        self._t = max(self._t, t_s)
        v, w = STOP
        if self._state is State.WAITING and self._odom is not None and (
            self._last_scan is not None
        ):
            if self.config.build_first_island:
                self._start_attempt(first=True)
            else:
                self._track.rel.reset()
                self._path.restart(self._odom)
                self._state = State.FOLLOWING
        if self._state is State.FOLLOWING:
            self._maybe_attempt()
        if self._odom is not None and self._stall.update(self._t, self._odom, self._state in (
            State.ENTERING, State.LEAVING, State.RETURNING, State.DOCKING, State.STAR
        )):  # pushing at a wall: the drive ends where the robot is
            self.diagnostics.drive_stalls += 1
            self._gave_up = True
        if self._state is State.ENTERING:
            v, w = self._entry_step()
        if self._state is State.LEAVING:
            v, w = self._leave_step()
        if self._state is State.STAR:
            v, w = self._star_step()
        if self._state is State.PROBING:
            v, w = self._probe_step()
        if self._state is State.RETURNING:
            v, w = self._return_step()
        if self._state is State.DOCKING:
            v, w = self._dock_step()
        if self._held is not None and self._t - self._held.t_s > self.hooks.hold_s:
            self.reject()  # nobody answered: decide as without the hypotheses
        mode = (CommandMode.FOLLOW if self._state is State.FOLLOWING else
                CommandMode.IDLE if self._state in (State.IDLE, State.HELD) else
                CommandMode.DRIVE)
        events, self._events = tuple(self._events), []
        return BuilderCommand(mode, v, w, events)

    def _emit(self, kind: EventKind, epsilon_m: float | None = None, **kw: object) -> None:
        assert self._odom is not None
        self.diagnostics.counts[kind] += 1
        eps = self.epsilon_m if epsilon_m is None else epsilon_m
        self._events.append(
            BuilderEvent(kind, self._t, self._odom, eps, **kw)  # type: ignore[arg-type]
        )

    def _maybe_attempt(self) -> None:
        assert self._odom is not None
        odom, cfg = self._odom, self.config
        now = Following(self.epsilon_m, self._t, self._path_m, self._strategy,
                        self.ledger.near_last_island(odom, cfg.vicinity_m,
                                                     sight=self._openings.behind_walls),
                        self._openings.pending(self._path_m),
                        self._openings.in_hallway(self._path_m),
                        self._openings.in_room(self._path_m))
        step, quick = follow_step(
            self._gate, cfg, now,
            lambda: self.measures.of_points(concat(self._history.quick_points()),
                                            np.array([odom.x, odom.y]))[1],
            self._try_revisit)
        if step is FollowStep.FAIL_AT_ONCE:
            self._emit(EventKind.ATTEMPT_FAILED_AT_ONCE, anchor_odom=odom, measure=quick,
                       bound=eq3_bound(cfg, now.epsilon_m))
        elif step is FollowStep.ATTEMPT:
            if self._openings.enter(odom, self._path_m):  # back to its middle, then in
                self._state = State.ENTERING
            else:
                self._start_attempt(first=False)

    def _start_attempt(self, first: bool) -> None:
        assert self._odom is not None and self._last_scan is not None
        eps = self.epsilon_m
        bound = eq3_bound(self.config, eps) if not first else self.config.first_island_min_measure
        self._attempt = Attempt.begin(
            self._odom, self._truth, self._track.cov, eps, bound, first, self._ahead_free_m(),
            straight_behind_m(self._strategy),
            to_frame(ranges_to_points(*self._last_scan, self._odom), self._odom), self._last_scan)
        self._attempt.turn_sign = unwind_sign(self._track.turned_rad,
                                              self.config.star.unwind_turns)
        self._track.anchor_star()
        self._state = State.STAR
        self._emit(EventKind.ATTEMPT_STARTED, anchor_odom=self._odom, bound=bound)

    def _take_give_up(self) -> bool:
        """Did the drive under way stall (then it ends here)? Cleared once asked."""
        gave_up, self._gave_up = self._gave_up, False
        return gave_up

    def _entry_step(self) -> Twist:
        """Into the opening passed (back to its middle, a quarter turn, in); the attempt starts
        there, the edge's strategy going on with the steps driven."""
        assert self._odom is not None and self._last_scan is not None
        cmd = self._openings.step(self._odom, self._last_scan, self.config.star,
                                  self._take_give_up())
        if cmd is not None:
            return cmd
        self._strategy = ControlStrategy(self._strategy.steps + self._openings.steps())
        self._start_attempt(first=False)
        assert self._attempt is not None
        self._attempt.keep_anchor = True
        return STOP

    def _leave_step(self) -> Twist:
        """Back out of the opening to where the follower stopped; it follows on from there."""
        entry = self._openings.entry
        assert entry is not None and self._odom is not None
        cmd = entry.leave_step(self._odom, self.config.star, self._take_give_up())
        if cmd is not None:
            return cmd
        self._hand_back(entry.record_end, None)
        return STOP

    def _pose_in_anchor(self) -> Pose2D:
        assert self._odom is not None and self._attempt is not None
        return self._odom.relative_to(self._attempt.anchor)

    def _ahead_free_m(self) -> float:
        """Nearest echo within the ahead cone of the latest scan (from the robot centre) [m]."""
        if self._last_scan is None:
            return 0.0
        return motion.ahead_free_m(*self._last_scan, self.config.star)

    # ----- the star -----

    def _star_step(self) -> Twist:
        att = self._attempt
        assert att is not None and self._odom is not None
        var = None if self._track.star is None else float(self._track.star.p[2, 2])
        twist, verdict = star.star_step(self.measures, att, self._odom, self._ahead_free_m(), var,
                                        self._take_give_up())
        if verdict is star.Verdict.ACCEPT:
            self._accept()
        elif verdict is not star.Verdict.NONE:
            self._dismiss(partial=verdict is star.Verdict.DISMISS_PARTIAL)
        return twist

    def _accept(self) -> None:
        att, cfg = self._attempt, self.config
        assert att is not None
        if att.first and att.best <= cfg.first_island_min_measure and att.bound > 0:
            self._dismiss(partial=False)
            return
        if not att.first:
            rec = None if self._odom is None else self.recognizer.recognize_star(
                att.near_points, att.anchor, self._odom, self.snapshot(), self.islands)
            end = None if rec is None or self._odom is None else rec.pose.compose(
                self._odom.relative_to(att.anchor).inverse())  # the anchor in the island frame
            # the star is at a known island: a revisit, not a new one
            if rec is not None and self._gate_allows(rec, star=True, end=end):
                att.outcome = EventKind.ISLAND_REVISITED
                self._attempt, self._track.star = None, None
                self._revisit(rec, legs_m=tuple(att.legs_done), strategy_end=end)
                return
            if self._hold(att):
                return
        self._build()

    def _build(self) -> None:
        """The attempt's island (no known island recognised): its origin, checked."""
        att, cfg = self._attempt, self.config
        assert att is not None
        pts = concat(att.points)
        model = self.measures.fit(pts) if pts.shape[0] >= 2 else LineModel()
        origin = star.choose_origin(self.measures, model, att, self._pose_in_anchor())
        if cfg.verify_localization and not att.first and not localizes_back(
            cfg, model, star.seen_at_origin(att, origin, cfg), Pose2D(0.0, 0.0, 0.0)
        ):
            self._dismiss(partial=False, reason=DismissReason.LOCALIZATION_CHECK)
            return
        if isinstance(origin, star.Probe):  # past the driven legs: check it on the spot
            att.probe = origin
            self._state = State.PROBING
            return
        self._accept_at(model, *origin)

    def _accept_at(self, model: LineModel, shift: Pose2D, r_peak: float) -> None:
        """Accept the attempt's island with its origin at `shift` in the anchor frame, where
        its model's normalized measure is r_peak."""
        att, book = self._attempt, self.ledger
        assert att is not None
        if shift.x != 0.0 or shift.y != 0.0:
            model = LineModel(model.segments - np.array([shift.x, shift.y] * 2))
            att.best = max(att.best, r_peak)
        origin = att.anchor.compose(shift)
        evidence = exit_evidence(att, model, shift, approach_path(self._strategy, APPROACH_M))
        find = self.hooks.find_exits
        island = Island(
            id=len(book.islands), model=model, model_type=att.best_type, r=float(att.best),
            built_at_s=self._t,
            origin_truth=None if att.anchor_truth is None else att.anchor_truth.compose(shift),
            exits=() if find is None else find(*evidence, self._openings.exit_info(shift)),
        )
        arrival = None if evidence[3] is None else facing_exit(
            island, evidence[3], self.hooks.arrival_match_deg)
        edge = with_exits(book.edge_to(island.id, self._edge_strategy(), self._path_m,
                                       Pose2D(-shift.x, -shift.y, 0.0), att.epsilon_m),
                          self._departure, None if arrival is None else arrival.index)
        updates = exit_updates(edge, None if edge is None else (edge.source, edge.target),
                               self._departure, None if arrival is None else arrival.index)
        book.add_island(island, origin, att.anchor_cov, edge, att.epsilon_m,
                        self._track.rel.heading_sigma_rad, cov_at=att.anchor)
        if self._track.star is not None:  # epsilon restarts from the island origin
            self._track.rel.p = self._track.star.p.copy()
        att.outcome = EventKind.ISLAND_ACCEPTED
        att.anchor = origin  # the robot returns to the island origin before it is handed back
        self._emit(EventKind.ISLAND_ACCEPTED, epsilon_m=att.epsilon_m, anchor_odom=origin,
                   measure=att.best, bound=att.bound, legs_m=tuple(att.legs_done),
                   island=island, edge=edge, exit_updates=updates)
        self._state = State.RETURNING

    def _probe_step(self) -> Twist:
        """To the origin past the legs and look around there (`star.probe_step`); then accept
        the island there if the look localizes in the model from offset guesses (the
        new-island check), else at the best origin along the driven legs."""
        att = self._attempt
        assert att is not None and att.probe is not None and self._odom is not None
        got = star.probe_step(self.measures, att, self._odom, self._ahead_free_m(),
                              self.config.revisit.path_clearance_m)
        if not isinstance(got, star.ProbeVerdict):
            return got
        self.diagnostics.probed(ProbeOutcome.KEPT if got.kept else ProbeOutcome.FELL_BACK)
        if got.next is None:
            self._accept_at(got.model, got.shift, got.measure)
        return STOP

    def _dismiss(self, partial: bool, reason: DismissReason | None = None) -> None:
        att = self._attempt
        assert att is not None
        att.outcome = EventKind.ATTEMPT_DISMISSED
        self._gate.retry_after(self._path_m, self.config.retry_distance_m)
        self._emit(EventKind.ATTEMPT_DISMISSED, epsilon_m=att.epsilon_m, anchor_odom=att.anchor,
                   measure=att.best, bound=att.bound, legs_m=tuple(att.legs_done), partial=partial,
                   reason=reason if reason is not None else DismissReason.MEASURE)
        self._state = State.RETURNING

    def _return_step(self) -> Twist:
        att = self._attempt
        assert att is not None
        cmd = star.return_step(att, self._pose_in_anchor(), self.config.star,
                               self._take_give_up())
        if cmd is not None:
            return cmd
        accepted = att.outcome is EventKind.ISLAND_ACCEPTED
        self._attempt = None
        self._track.star = None
        if not accepted and self._openings.entry is not None:  # back out where the follower was
            self._openings.entry.leave()
            self._state = State.LEAVING
            return STOP
        self._hand_back(att.anchor, self.ledger.last_island if accepted else None)
        return STOP

    def _hand_back(self, origin: Pose2D, island: Island | None) -> None:
        """Back to the follower at `origin` (odometry); at `island`'s origin its record
        restarts there."""
        self.ledger.handed_back(island, self._path_m)
        self._openings.entry = None
        if island is not None:
            self._strategy = ControlStrategy(())
            self._path.restart(origin)  # the edge starts at the origin, facing its heading 0
            self._departure = None
        self._emit(EventKind.HANDED_BACK, anchor_odom=origin,
                   accepted_island_id=None if island is None else island.id)
        self._history.quick.clear()
        self._openings.reset()
        managed_stop = self.hooks.managed and island is not None
        self._state = State.IDLE if managed_stop else State.FOLLOWING

    # ----- revisits -----

    def _try_revisit(self) -> bool:
        """Recognise a known island here; on success the robot docks onto its origin."""
        rec = self.recognize()
        if rec is None or not self._gate_allows(rec, star=False):
            return False
        self._revisit(rec)
        return True

    def _gate_allows(self, rec: Recognition, star: bool, end: Pose2D | None = None) -> bool:
        """The explorer's revisit gate (topological evidence) agrees, or there is none; it sees
        where the robot came from (the record ended at `end`, default rec.pose)."""
        refusal = gate_refusal(self.hooks, rec, self.snapshot(),
                               self.ledger.island(rec.island_id), star,
                               approach_path(self._strategy, APPROACH_M),
                               rec.pose if end is None else end)
        if refusal is None:
            return True
        self.diagnostics.refuse(refusal)
        return False

    def _revisit(self, rec: Recognition, legs_m: tuple[tuple[float, float], ...] = (),
                 strategy_end: Pose2D | None = None) -> None:
        """Link the previous island to the recognised one and dock onto its origin.

        strategy_end: where the follower's strategy ended, in the island frame (default: the
        robot now); the edge's last steps drive from there to the origin. After a star the
        robot is back at the anchor but faces its last leg, so that must be the anchor pose.
        """
        origin_odom = self._link_revisit(rec, legs_m, strategy_end, self.epsilon_m,
                                         self._track.rel.heading_sigma_rad)
        self._dock = Dock(island=self.ledger.island(rec.island_id), target=origin_odom,
                          looks_left=self.config.revisit.dock_looks)
        self._state = State.DOCKING

    def _link_revisit(self, rec: Recognition, legs_m: tuple[tuple[float, float], ...],
                      strategy_end: Pose2D | None, epsilon_m: float, heading_sigma_rad: float,
                      seen: tuple[Pose2D, float] | None = None) -> Pose2D:
        """The edge and link from the previous island to the recognised one (its weight and
        sigmas from epsilon_m [m] and heading_sigma_rad [rad]), and the event (with the
        robot's pose in the island as recognised at a time before, `seen`: a held star's);
        the island's origin in the odometry frame."""
        assert self._odom is not None
        island = self.ledger.island(rec.island_id)
        origin_odom = self._odom.compose(rec.pose.inverse())  # the island origin, odometry
        prev = self.ledger.last_island
        edge = self.ledger.revisit(
            island.id, self._edge_strategy(), self._path_m,
            rec.pose if strategy_end is None else strategy_end, epsilon_m,
            self.config.revisit.strategy_min_go_m, origin_odom, heading_sigma_rad)
        came = arrival_heading(approach_path(self._strategy, APPROACH_M),
                               rec.pose if strategy_end is None else strategy_end)
        arrival = None if came is None else facing_exit(island, came, self.hooks.arrival_match_deg)
        index = None if arrival is None else arrival.index
        annotated = with_exits(edge, self._departure, index)
        if annotated is not None:
            edge = self.ledger.replace_edge(annotated)
        known = None if prev is None else self.ledger.edge(prev.id, island.id)
        self._emit(EventKind.ISLAND_REVISITED, anchor_odom=origin_odom,
                   revisited_island_id=island.id,
                   island_pose=rec.pose if seen is None else seen[0],
                   island_pose_t_s=None if seen is None else seen[1],
                   residual_m=rec.residual_m, edge=edge, legs_m=legs_m,
                   exit_updates=exit_updates(
                       known, None if known is None else (known.source, known.target),
                       self._departure, index))
        return origin_odom

    def _dock_step(self) -> Twist:
        """Drive onto the recognised origin, face its heading, look around and re-localize;
        then hand back there: the robot knows where it is (epsilon 0)."""
        dock = self._dock
        assert dock is not None and self._odom is not None
        if dock.phase is not LookPhase.LOOK:  # the next look turns the unwinding way
            dock.turn_sign = unwind_sign(self._track.turned_rad, self.config.star.unwind_turns)
        cmd = dock_step(dock, self._odom, self._ahead_free_m(), self.config)
        if cmd is not None and not self._take_give_up():
            return cmd
        self._track.rel.reset()
        self.recognizer.remember(dock.island.id, dock.target, self._track.cov.copy())
        self._gate.retry_at_path_m = self._path_m
        self._hand_back(dock.target, dock.island)
        self._dock = None
        self._history.revisit.clear()
        return STOP

    def _look(self) -> motion.Look | None:
        """The dock or probe under way, if the state is one of theirs."""
        if self._state is State.DOCKING:
            return self._dock
        if self._state is State.PROBING and self._attempt is not None:
            return self._attempt.probe
        return None

