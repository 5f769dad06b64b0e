"""The star's decisions, as functions of what the star surveyed (paper section 5, beyond it
where docs/builder.md says so).

- `Attempt`: one attempt's data: the anchor, the scans kept in its frame, the legs driven.
- `star_step`: the four legs, driven one step at a time, each registered (`register_leg`: the
  heading fix onto the earlier legs' model) and evaluated (`evaluate_legs`: accept, dismiss).
- `peak_origin`: where the accepted island's origin goes: the model's measure peak along the
  driven legs, past them (a probe is asked for), or off a plain hallway.
- `probe_verdict`: what a look around a probed origin decides: keep it (the look joins the
  model; perhaps climb on) or fall back to the legs' choice.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np
from island_msgs_py.types import FloatArray, LineModel, ModelType, Pose2D

from island_mapping.core.builder.checks import (
    REGISTER_GATE_SIGMAS,
    leg_heading,
    localizes_back,
    register_look,
)
from island_mapping.core.builder.config import BuilderConfig, StarConfig
from island_mapping.core.builder.epsilon import Measures
from island_mapping.core.builder.events import EventKind
from island_mapping.core.builder.geometry import concat, drive_clear, from_frame, to_frame
from island_mapping.core.builder.motion import (
    LEG_BEARINGS_RAD,
    LEG_BEARINGS_RIGHT_RAD,
    STOP,
    LegPhase,
    Look,
    Twist,
    along_line,
    drive_line,
    look_around,
    return_to_centre,
    turn_to,
)
from island_mapping.core.placement import PlaceKind, PlacementConfig, classify_place

Candidate = tuple[Pose2D, float]
"""An origin in the anchor frame [m] (heading 0) and the model's normalized measure there."""

_ANCHOR = Pose2D(0.0, 0.0, 0.0)


@dataclass
class Probe(Look):
    """An origin past the driven legs, checked on the spot before the island is accepted."""

    model: LineModel  # the star's model in the anchor frame [m]
    shift: Pose2D  # the candidate origin in the anchor frame
    measure: float  # its normalized measure
    fallback: Pose2D  # the best origin along the driven legs, if the check fails
    fallback_measure: float
    fallback_model: LineModel | None = None  # the model kept with the fallback (None: model)
    climbs: int = 0  # probes passed before this one


@dataclass
class Attempt:
    """One attempt at an island: the anchor (odometry pose of the island origin), the scans
    kept in its frame, the legs driven, and the best measure so far."""

    anchor: Pose2D
    anchor_truth: Pose2D | None
    anchor_cov: FloatArray
    epsilon_m: float
    bound: float
    first: bool
    points: list[FloatArray] = field(default_factory=list)  # in the origin frame [m]
    centre_points: list[FloatArray] = field(default_factory=list)  # seen from the origin [m]
    # Echoes within revisit.max_range_m, in the origin frame, for recognising a known island [m]
    near_points: list[FloatArray] = field(default_factory=list)
    # Where each scan of `points` was taken, in the anchor frame: (1, 2) each [m].
    scan_at: list[FloatArray] = field(default_factory=list)
    # Each scan's readings, echo or not: where the robot was plus the unit vector along the
    # reading's bearing, (K, 2) in the anchor frame [m]; and their ranges (K,) (inf: no echo).
    look_ends: list[FloatArray] = field(default_factory=list)
    look_ranges: list[FloatArray] = field(default_factory=list)
    leg: int = 0
    turn_sign: float = 1.0  # +1 the legs (and looks) turn left, -1 right
    phase: LegPhase = LegPhase.TURN
    leg_length_m: float = 0.0
    legs_done: list[tuple[float, float]] = field(default_factory=list)
    # Where the current leg's scans begin in points, centre_points, near_points, scan_at and
    # look_ends.
    leg_marks: tuple[int, ...] = (0, 0, 0, 0, 0)
    # Heading variance of the pose in the anchor frame after the last leg registration, and
    # odometry's relative heading variance then [rad^2].
    heading_var_rad2: float = 0.0
    odom_var_seen_rad2: float = 0.0
    ahead_free_m: float = 0.0  # nearest echo ahead of the anchor when the attempt started [m]
    behind_free_m: float = 0.0  # straight path the follower drove up to the anchor [m]
    probe: Probe | None = None
    keep_anchor: bool = False  # the origin stays at the anchor when its measure passes
    return_stalled: bool = False  # the drive back to the origin stalled: it only turns to it
    best: float = 0.0
    best_type: ModelType = ModelType.LINE
    model: LineModel | None = None
    outcome: EventKind | None = None  # set when accepted, dismissed or revisited

    @staticmethod
    def begin(anchor: Pose2D, truth: Pose2D | None, cov: FloatArray, epsilon_m: float,
              bound: float, first: bool, ahead_free_m: float, behind_free_m: float,
              first_points: FloatArray, first_scan: tuple[FloatArray, FloatArray]) -> Attempt:
        """An attempt anchored at the odometric pose `anchor` (truth: the true pose, for
        evaluation; cov: the odometry's covariance there) with the scan seen there
        (`first_points`, robot frame = anchor frame; `first_scan`: its ranges [m] and
        robot-frame angles [rad])."""
        att = Attempt(anchor, truth, cov.copy(), epsilon_m, bound, first)
        att.ahead_free_m, att.behind_free_m = ahead_free_m, behind_free_m
        att.points.append(first_points)
        att.centre_points.append(first_points)
        att.scan_at.append(np.zeros((1, 2)))
        att._keep_looks(first_scan, _ANCHOR)
        return att

    def _keep_looks(self, scan: tuple[FloatArray, FloatArray], rel: Pose2D) -> None:
        ranges, angles = scan
        bearing = np.asarray(angles, dtype=np.float64) + rel.theta
        ends = np.column_stack([rel.x + np.cos(bearing), rel.y + np.sin(bearing)])
        self.look_ends.append(ends)
        self.look_ranges.append(np.asarray(ranges, dtype=np.float64).copy())

    def add_scan(self, points_odom: FloatArray, near_odom: FloatArray, odom: Pose2D,
                 centre_radius_m: float, scan: tuple[FloatArray, FloatArray]) -> None:
        """Keep a scan's points (odometry frame, taken at `odom`) in the anchor frame: all of
        them, those seen from the origin (within centre_radius_m [m]), the near echoes; and
        its readings (`scan`: ranges [m], inf for no echo, at robot-frame angles [rad])."""
        local = to_frame(points_odom, self.anchor)
        self.points.append(local)
        rel = odom.relative_to(self.anchor)
        self.scan_at.append(np.array([[rel.x, rel.y]]))
        self._keep_looks(scan, rel)
        if math.hypot(rel.x, rel.y) <= centre_radius_m:
            self.centre_points.append(local)
        self.near_points.append(to_frame(near_odom, self.anchor))

    def point_lists(self) -> tuple[list[FloatArray], ...]:
        """points, centre_points, near_points, scan_at, look_ends: the scans kept in the
        anchor frame and where they were taken (the order of leg_marks)."""
        return self.points, self.centre_points, self.near_points, self.scan_at, self.look_ends

    def looks(self) -> FloatArray:
        """Every reading kept, (K, 4) in the anchor frame: where the robot was [m], the
        reading's bearing [rad] and range [m] (inf: no echo)."""
        if not self.look_ends:
            return np.zeros((0, 4))
        at = concat([np.repeat(w, len(e), axis=0)
                     for w, e in zip(self.scan_at, self.look_ends, strict=True)])
        d = concat(self.look_ends) - at
        return np.column_stack([at, np.arctan2(d[:, 1], d[:, 0]), concat(self.look_ranges)])

    def seen_from(self, at: Pose2D, radius_m: float) -> FloatArray:
        """The points of the scans taken within radius_m of `at` (anchor frame) [m]."""
        near = [p for p, w in zip(self.points, self.scan_at, strict=True)
                if math.hypot(float(w[0, 0]) - at.x, float(w[0, 1]) - at.y) <= radius_m]
        return concat(near) if near else np.zeros((0, 2))

    def survey(self, robot: Pose2D) -> Survey:
        """What the star surveyed so far, the robot at `robot` in the anchor frame."""
        return Survey(tuple(self.legs_done), self.bound, self.ahead_free_m, self.behind_free_m,
                      robot)


@dataclass(frozen=True)
class Survey:
    """What a star surveyed: the legs driven (bearing in the anchor frame [rad], length [m]),
    the attempt's acceptance bound, the free range ahead of the anchor and the straight path
    the follower drove up to it [m], and where the robot is now (anchor frame)."""

    legs_m: tuple[tuple[float, float], ...]
    bound: float
    ahead_free_m: float = 0.0
    behind_free_m: float = 0.0
    robot: Pose2D = _ANCHOR


# ----- the legs -----


class Verdict(StrEnum):
    """What a star step decided about the attempt."""

    NONE = "none"  # go on
    ACCEPT = "accept"  # the island passes (or is the first)
    DISMISS = "dismiss"  # a full star whose measure never passed the bound
    DISMISS_PARTIAL = "dismiss_partial"  # too poor after dismiss_min_legs legs


def star_step(
    m: Measures, att: Attempt, odom: Pose2D, ahead_free_m: float,
    odom_heading_var_rad2: float | None, stalled: bool = False,
) -> tuple[Twist, Verdict]:
    """One step of the four legs (ahead, left, behind, right; or ahead, right, behind, left
    when the attempt turns right): turn to the leg's bearing,
    drive out (shortened to the free range ahead minus the clearance; skipped if too short),
    register the leg and evaluate the attempt, reverse back to the centre. odom: the odometric
    pose; ahead_free_m: nearest echo ahead [m]; odom_heading_var_rad2: odometry's heading
    variance since the anchor (None: do not register); stalled: the drive under way made no
    progress (the robot touches a wall): a turn skips its leg, a leg or its way back ends
    where the robot is."""
    sc = m.cfg.star
    bearings = LEG_BEARINGS_RAD if att.turn_sign > 0 else LEG_BEARINGS_RIGHT_RAD
    while att.leg < len(bearings):
        bearing = bearings[att.leg]
        if att.phase is LegPhase.TURN:
            cmd = turn_to(odom.relative_to(att.anchor), bearing, sc)
            if cmd is not None and not stalled:
                return cmd, Verdict.NONE
            if cmd is not None:  # cannot turn here (touching a wall): skip this corner
                att.leg += 1
                return STOP, Verdict.NONE
            att.leg_length_m = min(sc.leg_length_m, ahead_free_m - sc.clearance_m)
            if att.leg_length_m < sc.min_leg_m:
                att.leg += 1  # this corner is not reachable: skip it
                continue
            att.phase = LegPhase.OUT
        along, lateral = along_line(odom.relative_to(att.anchor), bearing)
        if att.phase is LegPhase.OUT:
            remaining = att.leg_length_m - along
            if remaining > sc.position_tol_m and ahead_free_m >= sc.clearance_m and not stalled:
                return drive_line(odom.relative_to(att.anchor), bearing, lateral,
                                  min(sc.speed_mps, remaining * 2.0), sc), Verdict.NONE
            att.legs_done.append((bearing, max(along, 0.0)))
            att.phase = LegPhase.BACK
            if m.cfg.register_legs and odom_heading_var_rad2 is not None:
                register_leg(m, att, odom_heading_var_rad2)
            verdict = evaluate_legs(m, att)
            if verdict is not Verdict.NONE:
                return STOP, verdict
        if along > sc.position_tol_m and not stalled:  # BACK: reverse to the centre
            return drive_line(odom.relative_to(att.anchor), bearing, lateral,
                              -min(sc.speed_mps, along * 2.0), sc), Verdict.NONE
        att.leg += 1
        att.phase = LegPhase.TURN
        att.leg_marks = tuple(len(lst) for lst in att.point_lists())
    # All legs done without a decision.
    return STOP, Verdict.ACCEPT if att.first or att.best > att.bound else Verdict.DISMISS


def evaluate_legs(m: Measures, att: Attempt) -> Verdict:
    """Fit lines to the star's points and evaluate every model type at the anchor (keeping
    the best so far): ACCEPT at once when it passes the bound and complete_star is off,
    DISMISS_PARTIAL when after dismiss_min_legs legs it is below dismiss_fraction of the
    bound; island 0 always drives the full star."""
    cfg = m.cfg
    t, best, model = m.of_points(concat(att.points), np.zeros(2))
    if cfg.accept_on_legs and len(model) > 0:
        best = max(best, legs_best(m, model, att))
    if best >= att.best:
        att.best, att.best_type, att.model = best, t, model
    if att.first:
        return Verdict.NONE
    if att.best > att.bound:
        return Verdict.NONE if cfg.complete_star else Verdict.ACCEPT
    if len(att.legs_done) >= cfg.dismiss_min_legs and (
        att.best < cfg.dismiss_fraction * att.bound
    ):
        return Verdict.DISMISS_PARTIAL
    return Verdict.NONE


def legs_best(m: Measures, model: LineModel, att: Attempt) -> float:
    """The best normalized measure of `model` at the points along the driven legs (every
    peak_step_m) where it does not show a plain hallway: the region the star surveyed."""
    best = 0.0
    for bearing, length in att.legs_done:
        u = np.array([math.cos(bearing), math.sin(bearing)])
        for _, p, r in along(m, model, np.zeros(2), u, length, length, _ANCHOR):
            if r > best and not plain_hallway(m, model, p):
                best = r
    return best


def register_leg(m: Measures, att: Attempt, odom_heading_var_rad2: float) -> None:
    """Register the current leg's echoes (since the turn that began it) onto the model of
    the earlier legs, and turn them, and the anchor (so the robot's pose in it too), by the
    heading found times the gain var / (var + register_sigma^2), var the heading variance
    odometry added since the last registration plus what that one left. Only the heading:
    a partial view constrains a hallway's position along it poorly. Nothing when this is
    the first leg driven or the fit is refused. odom_heading_var_rad2: odometry's heading
    variance since the anchor [rad^2]."""
    i = att.leg_marks[0]
    if i == 0 or i == len(att.points):
        return
    model = m.fit(np.concatenate(att.points[:i], axis=0))
    if len(model) == 0:
        return
    var = att.heading_var_rad2 + max(odom_heading_var_rad2 - att.odom_var_seen_rad2, 0.0)
    sigma2 = math.radians(m.cfg.register_sigma_deg) ** 2
    found = leg_heading(m.cfg, model, np.concatenate(att.points[i:], axis=0),
                        REGISTER_GATE_SIGMAS * math.sqrt(var + sigma2))
    if found is None:
        return
    gain = var / (var + sigma2)
    att.heading_var_rad2, att.odom_var_seen_rad2 = (1.0 - gain) * var, odom_heading_var_rad2
    fix = Pose2D(0.0, 0.0, gain * found)
    for lst, mark in zip(att.point_lists(), att.leg_marks, strict=True):
        lst[mark:] = [from_frame(p, fix) for p in lst[mark:]]
    att.anchor = att.anchor.compose(fix.inverse())


# ----- where the origin goes -----


@functools.lru_cache(maxsize=8)
def _placement(radius_m: float) -> PlacementConfig | None:
    return PlacementConfig(radius_m=radius_m) if radius_m > 0.0 else None


def plain_hallway(m: Measures, model: LineModel, p: Pose2D) -> bool:
    """Does `model` show a plain hallway at p (anchor frame): only parallel walls within
    origin_feature_radius_m? Never with the radius 0 (the check off)."""
    placement = _placement(m.cfg.origin_feature_radius_m)
    return placement is not None and classify_place(
        model.segments, p.x, p.y, placement
    ) is PlaceKind.PLAIN_HALLWAY


def best_junction(
    m: Measures, model: LineModel, candidates: Sequence[Candidate], bound: float
) -> Candidate | None:
    """The best of `candidates` whose measure passes `bound` and where `model` does not show
    a plain hallway; None if there is none."""
    ok = [c for c in candidates if c[1] > bound and not plain_hallway(m, model, c[0])]
    return max(ok, key=lambda c: c[1]) if ok else None


def reachable(m: Measures, segs: FloatArray, p: FloatArray, robot: Pose2D) -> bool:
    """Are the straight drives anchor -> p and robot -> p clear of the model's walls?"""
    clear = m.cfg.revisit.path_clearance_m
    return all(
        drive_clear(segs, a, p, clear) for a in (np.zeros(2), np.array([robot.x, robot.y]))
    )


def along(
    m: Measures, model: LineModel, start: FloatArray, u: FloatArray, reach_m: float,
    free_m: float, robot: Pose2D,
) -> Iterator[tuple[float, Pose2D, float]]:
    """(d, the point start + d u, the model's measure there) every peak_step_m up to
    reach_m, in the anchor frame; beyond free_m (driven, known free) only while the point
    is `reachable` from the anchor and the robot, stopping at the first that is not."""
    step = m.cfg.peak_step_m
    for d in np.arange(step, reach_m + 1e-9, step):
        p = start + float(d) * u
        if d > free_m and not reachable(m, model.segments, p, robot):
            return
        yield float(d), Pose2D(float(p[0]), float(p[1]), 0.0), m.at(model, p)


def _leg_reach(m: Measures, survey: Survey, bearing: float, length: float) -> float:
    """How far the peak search goes along a leg: its driven length, or past it ahead (the free
    range) and behind (the straight path that led to the anchor), up to peak_ahead_m."""
    cfg = m.cfg
    if bearing == 0.0:
        return max(length, min(cfg.peak_ahead_m, survey.ahead_free_m - cfg.star.clearance_m))
    if bearing == math.pi and (cfg.peak_behind or cfg.origin_feature_radius_m > 0.0):
        return max(length, min(cfg.peak_ahead_m, survey.behind_free_m))  # came along it
    return length


def peak_origin(m: Measures, model: LineModel, survey: Survey) -> tuple[Candidate, Candidate]:
    """Where the model's normalized measure peaks (the origin in the anchor frame, its
    measure): along the driven star legs, and also past the ahead leg (and, with
    peak_behind, past the back leg along the straight path that led to the anchor) up to
    peak_ahead_m; each the anchor itself unless its peak beats it by peak_min_gain
    (peak_ahead_min_gain along the driven ahead leg). Where the model shows a plain
    hallway at the origin so chosen, the best driven point it shows at a junction (passing
    the attempt's bound) is the origin instead; failing that, the best such point past the
    legs (also past the back leg) is probed. Returns (the legs' choice, the choice to probe:
    the legs' choice itself when nothing past the legs is worth a probe)."""
    cfg = m.cfg
    anchor: Candidate = (_ANCHOR, m.at(model, np.zeros(2)))
    legs, far = anchor, anchor
    driven, past = [anchor], []  # candidates along the legs, and past them
    for bearing, length in survey.legs_m:
        gain = cfg.peak_ahead_min_gain if bearing == 0.0 else cfg.peak_min_gain
        leg_floor = anchor[1] * (1.0 + gain)
        behind = bearing == math.pi
        u = np.array([math.cos(bearing), math.sin(bearing)])
        reach = _leg_reach(m, survey, bearing, length)
        for d, p, r in along(m, model, np.zeros(2), u, reach, length, survey.robot):
            if d <= length:
                driven.append((p, r))
                if r > leg_floor and r > legs[1]:
                    legs = (p, r)
                continue
            past.append((p, r))
            if r > far[1] and (cfg.peak_behind or not behind):
                far = (p, r)
    if plain_hallway(m, model, legs[0]):
        on_legs = best_junction(m, model, driven, survey.bound)
        if on_legs is not None:
            legs = on_legs
        else:
            beyond = best_junction(m, model, past, survey.bound)
            if beyond is not None:
                return legs, beyond
    # The peak past the driven legs is probed only where it beats both the anchor by
    # peak_min_gain and the legs' choice; otherwise the legs' choice is the origin.
    floor = anchor[1] * (1.0 + cfg.peak_min_gain)
    return legs, (far if far[1] > floor and far[1] > legs[1] else legs)


def seen_at_origin(att: Attempt, origin: Candidate | Probe, cfg: BuilderConfig) -> FloatArray:
    """The points the new-island check localizes: those seen from the anchor, or with
    accept_on_legs from the chosen origin along the legs (a probe's own look checks a probed
    origin; before it, its fallback)."""
    if not cfg.accept_on_legs:
        return concat(att.centre_points)
    at = origin.fallback if isinstance(origin, Probe) else origin[0]
    return att.seen_from(at, cfg.origin_seen_radius_m)


def choose_origin(m: Measures, model: LineModel, att: Attempt,
                  robot: Pose2D) -> Candidate | Probe:
    """The accepted island's origin (anchor frame) and its measure, or a probe of an origin
    past the driven legs (nothing was seen from there yet); the anchor itself without
    origin_at_peak, for island 0, or without a model. robot: the robot in the anchor frame."""
    if not m.cfg.origin_at_peak or att.first or len(model) == 0:
        return _ANCHOR, att.best
    if att.keep_anchor:  # an opening's island: where the robot was taken to, if good enough
        r_anchor = m.at(model, np.zeros(2))
        if r_anchor > att.bound and not plain_hallway(m, model, _ANCHOR):
            return _ANCHOR, r_anchor
    (shift, r_peak), (far, r_far) = peak_origin(m, model, att.survey(robot))
    if far != shift:
        return Probe(model, far, r_far, shift, r_peak)
    return shift, r_peak


def climb(m: Measures, model: LineModel, at: Pose2D, r_at: float,
          robot: Pose2D) -> Candidate | None:
    """The model's peak further on from the anchor through `at` (ahead or back along the
    anchor's heading), up to peak_ahead_m past `at` (drives there from the anchor and from
    `robot` clear of its walls), if it beats r_at by peak_min_gain; else None."""
    cfg = m.cfg
    best: Candidate | None = None
    u = np.array([1.0 if at.x >= 0.0 else -1.0, 0.0])
    for _, p, r in along(m, model, np.array([at.x, at.y]), u, cfg.peak_ahead_m, 0.0, robot):
        if r > r_at * (1.0 + cfg.peak_min_gain) and (best is None or r > best[1]):
            best = (p, r)
    return best


# ----- the probe -----


@dataclass(frozen=True)
class ProbeVerdict:
    """What a probe's look decided: kept (the look localized at the probed origin) or not,
    the island's `model` (anchor frame), its origin `shift` (anchor frame) and the model's
    `measure` there, to accept unless `next` asks for a probe further on (a climb). Kept:
    the model refit with the look, whose points placed in the anchor frame are `look`, at
    the probed origin; else the fallback along the driven legs."""

    kept: bool
    model: LineModel
    shift: Pose2D
    measure: float
    look: FloatArray
    next: Probe | None = None


def probe_verdict(
    m: Measures, probe: Probe, look_odom: FloatArray, odom: Pose2D, anchor: Pose2D,
    star_points: Sequence[FloatArray], there: bool,
) -> ProbeVerdict:
    """The check of a probed origin: the look's points (odometry frame, taken at `odom`) are
    registered onto the star's model, and the island's model is refit from the star's points
    and the look (it gains what the look saw from the candidate origin itself, where every
    later arrival localizes). Kept when the robot got `there`, the look has points and
    localizes at the candidate from offset and turned guesses (`localizes_back` with
    probe_turn_deg). A kept probe climbs on to a further peak of the new model when its
    look's model still shows a plain hallway there, or while probe_climbs allows."""
    cfg = m.cfg
    robot_pts = to_frame(look_odom, odom)
    at = register_look(cfg, probe.model, robot_pts, odom.relative_to(anchor))
    look = from_frame(robot_pts, at)
    model = m.fit(concat([*star_points, look]))
    shift = probe.shift
    shifted = LineModel(model.segments - np.array([shift.x, shift.y] * 2))
    kept = there and look_odom.shape[0] >= 3 and localizes_back(
        cfg, shifted, robot_pts, Pose2D(at.x - shift.x, at.y - shift.y, at.theta),
        math.radians(cfg.probe_turn_deg))
    if not kept:
        fallback_model = probe.model if probe.fallback_model is None else probe.fallback_model
        return ProbeVerdict(False, fallback_model, probe.fallback, probe.fallback_measure, look)
    here = m.at(model, np.array([shift.x, shift.y]))
    climbing = probe.climbs < cfg.probe_climbs or (
        probe.climbs == 0 and plain_hallway(m, model, shift))
    on = climb(m, model, shift, here, odom.relative_to(anchor)) if climbing else None
    nxt = None if on is None else Probe(model, on[0], on[1], shift, here, model,
                                        probe.climbs + 1)
    return ProbeVerdict(True, model, shift, here, look, nxt)


def probe_step(m: Measures, att: Attempt, odom: Pose2D, ahead_free_m: float,
               there_m: float) -> Twist | ProbeVerdict:
    """Drive to the attempt's probed origin, face the anchor's heading and look around (a full
    circle): the twist meanwhile; then the look's verdict (`probe_verdict`; the robot got
    there when within there_m [m] of the origin). A kept look joins the attempt's points, and
    the attempt's probe becomes the verdict's next (None: accept now)."""
    pr, sc = att.probe, m.cfg.star
    assert pr is not None
    rel = odom.relative_to(att.anchor.compose(pr.shift))  # robot in the candidate's frame
    pr.turn_sign = att.turn_sign
    cmd = look_around(pr, rel, math.radians(sc.heading_tol_deg), odom.theta, ahead_free_m, sc)
    if cmd is not None:
        return cmd
    there = math.hypot(rel.x, rel.y) <= there_m
    verdict = probe_verdict(m, pr, concat(pr.points), odom, att.anchor, att.points, there)
    if verdict.kept:
        att.points.append(verdict.look)
    att.probe = verdict.next  # the completed model peaks further on: probe there too
    return verdict


def return_step(att: Attempt, rel: Pose2D, sc: StarConfig, gave_up: bool) -> Twist | None:
    """Back onto the origin facing heading 0 (`rel`: the robot in the origin's frame; None once
    there). A drive back that stalled (`gave_up`) only turns to heading 0, a disk always can;
    a turn that stalled too ends the return where the robot is."""
    cmd = None if gave_up and att.return_stalled else return_to_centre(
        rel, sc, turn_only=att.return_stalled or gave_up)
    att.return_stalled |= gave_up
    return cmd
