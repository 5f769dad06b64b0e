"""Recognising an island the robot already built (revisits), from an explicit snapshot of the
robot's odometric pose and covariance.

`Recognizer` remembers where each island's origin was last known in the odometry frame (and the
odometry's covariance then) and the links measured between islands (`LinkGraph`). Given scan
points and a `PoseSnapshot`, it searches every candidate island around its odometric estimate
(a grid of guesses scored by inliers, the best refined by localization), refuses fits that are
weak, ambiguous, out of the search window or fail the new-island localization check, and
refuses the whole recognition when another island that may be here fits too (a look-alike).
Refusals are counted in `Diagnostics.revisit_refusals`.
"""

from __future__ import annotations

import dataclasses
import math
from collections import OrderedDict
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from island_msgs_py.geometry import relative_poses
from island_msgs_py.types import FloatArray, Island, Pose2D, wrap_angle

from island_mapping.core.builder.calibration import OdometryCalibration
from island_mapping.core.builder.checks import localizes_back
from island_mapping.core.builder.config import BuilderConfig
from island_mapping.core.builder.diagnostics import Diagnostics, Refusal
from island_mapping.core.builder.geometry import drive_clear, from_frame, to_frame
from island_mapping.core.builder.inlier_field import InlierField
from island_mapping.core.builder.known import KnownOrigins
from island_mapping.core.builder.links import Link, LinkGraph
from island_mapping.core.builder.places import PlaceSearch
from island_mapping.core.builder.recognized import PoseSnapshot, Recognition
from island_mapping.core.builder.revisit_config import RevisitConfig
from island_mapping.core.builder.uncertainty import (
    between_covariance,
    in_frame,
    mahalanobis2,
    relative_covariance,
)
from island_mapping.core.lines import point_segment_distance, thin_evenly
from island_mapping.core.localize import localize

# Guesses scored per batch of the grid search (bounds the (guesses x points x walls) array).
_GUESSES_PER_BATCH = 40
# Inlier grids kept for the islands searched last (each at most 4 MB, typically < 1 MB).
_FIELDS_KEPT = 64
# The turns under which a place may fit itself (a + junction, a square room, a hallway).
_ALIAS_TURNS_RAD = (math.pi / 2, -math.pi / 2, math.pi)
# The heading uncertainty past which they are checked: half of the smallest of them.
_ALIAS_MIN_REACH_RAD = math.pi / 4
# The heading half-width of the search around a turned fit, in heading steps.
_ALIAS_STEPS = 2


def _ignore(_reason: Refusal) -> None:
    """A refusal that is not counted."""


@dataclass(frozen=True)
class _Candidate:
    island: Island
    origin: Pose2D  # the island origin in the odometry frame (estimated)
    sigma_m: float
    sigma_rad: float


@dataclass(frozen=True)
class _Window:
    """A search around an estimate: radius [m], heading half-width [rad], grid step [m], and
    the largest residual accepted [m]."""

    radius_m: float
    max_dth_rad: float
    step_m: float
    max_residual_m: float


def search_window(rc: RevisitConfig, cand: _Candidate, star: bool) -> tuple[_Window, bool]:
    """The search window around a candidate's estimate, and whether it exceeds the caps
    (search_max_m / _deg, or the star's): with clip_search it is cut to them instead."""
    radius, dth, max_m, max_deg = _reach(rc, cand, star)
    too_wide = radius > max_m or dth > math.radians(max_deg)
    if too_wide and rc.clip_search:
        radius, dth, too_wide = min(radius, max_m), min(dth, math.radians(max_deg)), False
    step = max(rc.search_step_m, radius / rc.star_search_cells) if star else rc.search_step_m
    max_res = rc.star_max_residual_m if star else rc.max_residual_m
    return _Window(radius, dth, step, max_res), too_wide


def _reach(rc: RevisitConfig, cand: _Candidate, star: bool
           ) -> tuple[float, float, float, float]:
    """(search radius [m], heading half-width [rad]) a candidate's sigmas ask for, and the
    caps (max radius [m], max heading [deg]) of that search."""
    sigmas = rc.star_search_sigmas if star else rc.search_sigmas
    max_m, max_deg = ((rc.star_search_max_m, rc.star_search_max_deg) if star
                      else (rc.search_max_m, rc.search_max_deg))
    return (max(sigmas * cand.sigma_m, rc.search_min_m), sigmas * cand.sigma_rad, max_m,
            max_deg)


def exceeds_caps(rc: RevisitConfig, cand: _Candidate, star: bool) -> bool:
    """Would the candidate's window exceed the search caps (clipped or refused)?"""
    radius, dth, max_m, max_deg = _reach(rc, cand, star)
    return radius > max_m or dth > math.radians(max_deg)


Refine = Callable[[Island, FloatArray, Pose2D, _Window, Callable[[Refusal], None]],
                  list[Recognition]]


def fits_elsewhere(refine: Refine, rc: RevisitConfig, islands: Sequence[Island],
                   pts: FloatArray, best: Recognition, star: bool) -> Recognition | None:
    """The fit of an island other than best's that fits `pts` as well (inliers within
    ambiguity_inlier_margin of best's) at a pose within max_dock_m of its own origin, at any
    heading, or None. Where odometry no longer bounds where the robot is (a window cut to the
    caps), only the map's other places can tell a look-alike."""
    win = _Window(rc.max_dock_m, math.pi, rc.rival_step_m,
                  rc.star_max_residual_m if star else rc.max_residual_m)
    floor = best.inlier_fraction - rc.ambiguity_inlier_margin
    for island in islands:
        if island.id == best.island_id or len(island.model) == 0:
            continue
        fits = [f for f in refine(island, pts, Pose2D(0.0, 0.0, 0.0), win, _ignore)
                if f.inlier_fraction >= floor]
        if fits:
            return max(fits, key=lambda f: f.inlier_fraction)
    return None


def with_distance(rc: RevisitConfig, fit: Recognition, at: Pose2D,
                  spreads: Sequence[tuple[Pose2D, FloatArray]]) -> Recognition:
    """`fit` (the robot at odometric pose `at`) with its squared Mahalanobis distance: the
    largest over the island's estimates (`Recognizer.spreads`), each under its full covariance
    plus the fit's own error (fit_sigma_m / _deg): a true recognition lies within every honest
    estimate's uncertainty."""
    floor = np.diag([rc.fit_sigma_m ** 2, rc.fit_sigma_m ** 2,
                     math.radians(rc.fit_sigma_deg) ** 2])
    d2 = max((mahalanobis2(fit.pose, at.relative_to(origin), cov, floor)
              for origin, cov in spreads), default=None)
    return dataclasses.replace(fit, mahalanobis2=d2)


def look_alikes(rc: RevisitConfig, best: Recognition, rivals: Sequence[Recognition],
                spreads: Callable[[int], Sequence[tuple[Pose2D, FloatArray]]], at: Pose2D,
                estimate: Callable[[int], Pose2D]) -> list[Recognition]:
    """The hypotheses of a recognition refused for look-alikes: best and the rivals (each with
    its distance from its estimates, `with_distance`, the robot at odometric pose `at`), when
    best has the inliers a recognition needs (accept_inlier_fraction); else none. A rival is
    one only inside the star's search caps (star_search_max_m, star_search_max_deg) around
    `estimate` (the robot in its island's frame by odometry): a far look-alike is found at any
    heading, and in a lattice of corridors a place fits another turned by a quarter (office
    11 seed 1: a rehearsal of one 11.8 m and 93 deg off confirmed at a neighbour's look-alike
    turned the same way, a false merge)."""
    if best.inlier_fraction < rc.accept_inlier_fraction:
        return []
    out = [best]
    for f in rivals:
        est = estimate(f.island_id)
        if math.hypot(f.pose.x - est.x, f.pose.y - est.y) > rc.star_search_max_m or abs(
                wrap_angle(f.pose.theta - est.theta)) > math.radians(rc.star_search_max_deg):
            continue
        out.append(f if f.mahalanobis2 is not None else with_distance(
            rc, f, at, spreads(f.island_id)))
    return out


def rival_window(rc: RevisitConfig, cand: _Candidate, max_dth_rad: float, star: bool) -> _Window:
    """The wide window of a rival search around a candidate (rival_sigmas of its
    position sigma, within search_min_m and rival_max_m)."""
    radius = min(max(rc.rival_sigmas * cand.sigma_m, rc.search_min_m), rc.rival_max_m)
    return _Window(
        radius, max_dth_rad,
        min(max(rc.search_step_m, radius / rc.star_search_cells), rc.rival_step_m),
        rc.star_max_residual_m if star else rc.max_residual_m,
    )


Search = Callable[..., Recognition | None]
"""`Recognizer._search(island, points, estimate, window, count_refusals)`."""


def turned_alias(rc: RevisitConfig, search: Search, cand: _Candidate, best: Recognition,
                 pts: FloatArray, star: bool) -> bool:
    """Does the chosen island fit the points as well turned by a quarter or half turn, once
    its heading uncertainty (rival_sigmas sigmas) exceeds 45 deg? A + junction mapped all
    round fits itself turned, and a clipped heading window may hold the turned fit. Every
    turn is tried: odometry's systematic drift outgrows its sigmas."""
    k = rc.rival_sigmas
    if k <= 0 or not rc.turned_alias or k * cand.sigma_rad < _ALIAS_MIN_REACH_RAD:
        return False
    step = math.radians(rc.heading_step_deg)
    for turn in _ALIAS_TURNS_RAD:
        heading = best.pose.theta + turn
        win = rival_window(rc, cand, _ALIAS_STEPS * step, star)
        win = dataclasses.replace(win, radius_m=min(win.radius_m, rc.max_dock_m))
        alias = search(cand.island, pts, Pose2D(best.pose.x, best.pose.y, heading), win,
                       count_refusals=False)
        if alias is not None and (
            alias.inlier_fraction >= best.inlier_fraction - rc.ambiguity_inlier_margin
        ):
            return True
    return False


class Recognizer:
    """Known island origins, the links between them, and the search for revisits."""

    def __init__(self, config: BuilderConfig, diagnostics: Diagnostics | None = None) -> None:
        self.config = config
        self.diagnostics = diagnostics if diagnostics is not None else Diagnostics()
        self.calibration = OdometryCalibration(config.calibration)
        self._known = KnownOrigins(self.calibration)
        self._places: dict[int, PlaceSearch] = {}
        # the inlier tests of the islands searched last (most recent last; bounded memory)
        self._fields: OrderedDict[int, InlierField] = OrderedDict()
        self.links = LinkGraph()
        self.hypotheses: list[Recognition] = []  # the last look-alike refusal's fits, best first

    # ----- what is known -----

    def remember(self, island_id: int, origin_odom: Pose2D, odom_cov: FloatArray,
                 cov_at: Pose2D | None = None) -> None:
        """Island island_id's origin is at origin_odom in the odometry frame now, with the
        odometry's covariance odom_cov (3x3) taken at odometric pose cov_at (default: at
        the origin; a star's anchor, a few metres off, for a new island). Localized at a
        known island again, the calibration learns from where it was predicted."""
        self._known.remember(island_id, origin_odom, odom_cov, cov_at)

    def known(self, island_id: int) -> tuple[Pose2D, FloatArray] | None:
        """(origin in the odometry frame, odometry covariance then) as last known, or None."""
        return self._known.get(island_id)

    @property
    def known_ids(self) -> list[int]:
        return sorted(self._known)

    def near(self, odom: Pose2D, radius_m: float) -> list[tuple[float, int, FloatArray]]:
        """Known islands whose origin lies within radius_m [m] of the odometric pose `odom`,
        nearest first: (distance [m], island id, `odom` in the island's frame by odometry as
        an (x, y, theta) row)."""
        here = np.array([odom.x, odom.y, odom.theta])
        out = []
        for iid in self._known:
            origin = self._known.origin(iid)
            est = relative_poses(np.array([origin.x, origin.y, origin.theta]), here)[0]
            dist = math.hypot(est[0], est[1])
            if dist <= radius_m:
                out.append((dist, iid, est))
        return sorted(out, key=lambda c: c[0])

    def add_place_search(self, island_id: int, search: PlaceSearch) -> None:
        """Let `place` search island island_id's model by `search` (its correlative search)."""
        self._places[island_id] = search

    def place(self, points: FloatArray, margin: float) -> tuple[int, FloatArray] | None:
        """The correlative place search over every island given one (`add_place_search`):
        (island id, the best pose of robot-frame `points` in its frame as an (x, y, theta)
        row) of the best score that beats its island's best distinct hypothesis by `margin`;
        None when no island's does."""
        best: tuple[float, int, FloatArray] | None = None
        for iid, search in self._places.items():
            guess, score, second = search.search(points)
            if score - second < margin:
                continue
            if best is None or score > best[0]:
                best = (score, iid, guess)
        return None if best is None else (best[1], best[2])

    def link(self, a: int, b: int, origin_b_odom: Pose2D, sigma_m: float,
             sigma_rad: float) -> None:
        """Remember where b's origin lies in a's frame (the odometry since a's origin), with
        position and heading sigmas; a must be known."""
        t_ab = origin_b_odom.relative_to(self._known.origin(a))
        self.links.add(a, b, Link(t_ab, sigma_m, sigma_rad))

    # ----- the search -----

    def recognize_recent(
        self, recent_odom: Sequence[FloatArray], odom: Pose2D, snap: PoseSnapshot,
        islands: Sequence[Island],
    ) -> Recognition | None:
        """Recognition from the points seen while following (odometry frame, the last
        revisit.history_m of path), thinned to max_points, at the odometric pose `odom`."""
        rc = self.config.revisit
        if not rc.enabled or not self._known or not recent_odom:
            return None
        pts_odom = np.concatenate(recent_odom, axis=0)
        if pts_odom.shape[0] < rc.min_points:
            return None
        pts = to_frame(thin_evenly(pts_odom, rc.max_points), odom)
        return self.recognize(pts, odom, snap, islands)

    def recognize_star(
        self, near_points: Sequence[FloatArray], anchor: Pose2D, odom: Pose2D,
        snap: PoseSnapshot, islands: Sequence[Island],
    ) -> Recognition | None:
        """Recognition from a star's echoes (`near_points`, anchor frame, thinned to
        star_max_points) around its anchor (odometry); the pose is the robot's at `odom`."""
        rc = self.config.revisit
        if not (rc.enabled and rc.at_star) or not self._known or not near_points:
            return None
        pts = np.concatenate(near_points, axis=0)
        if pts.shape[0] < rc.min_points:
            return None
        pts = thin_evenly(pts, rc.star_max_points)
        rec = self.recognize(pts, anchor, snap, islands, star=True)
        # The distance from the estimate was measured at the anchor, where the points are.
        step = odom.relative_to(anchor)
        self.hypotheses = [dataclasses.replace(h, pose=h.pose.compose(step))
                           for h in self.hypotheses]
        return None if rec is None else dataclasses.replace(rec, pose=rec.pose.compose(step))

    def recognize(
        self, points: FloatArray, at: Pose2D, snap: PoseSnapshot, islands: Sequence[Island],
        star: bool = False,
    ) -> Recognition | None:
        """Search the known islands for robot-frame points `points` [m] seen from odometric
        pose `at`; the recognition's pose is `at` in the island frame.

        Candidates: islands whose origin could be within `max_dock_m` of the robot given the
        search radius (search_sigmas sigmas of the estimate's sigmas, heading at most
        search_max_deg). A grid of guesses around the estimate, scored by inliers (within
        inlier_m of the model); the best few are refined by localization. Accepted:
        converged, residual <= max_residual_m, constrained along every axis, inliers >=
        min_inlier_fraction (kept: >= accept_inlier_fraction), inside the window,
        unambiguous, the origin within max_dock_m by a path clear of walls, and the new-island
        localization check. The smallest residual wins, unless another island that may be
        here (rival_sigmas) fits too, the island fits turned (turned_alias), or, its window
        clipped, any island fits near its origin (clipped_rivals). star=True: a star's points,
        over star_search_sigmas within the star_ caps, a grid of at least radius /
        star_search_cells, residual up to star_max_residual_m."""
        rc = self.config.revisit
        self.hypotheses = []
        found: list[Recognition] = []
        candidates = list(self._candidates(snap, islands))
        for cand in candidates:
            est = at.relative_to(cand.origin)  # the robot in the island frame, by odometry
            win, too_wide = search_window(self.config.revisit, cand, star)
            if math.hypot(est.x, est.y) > win.radius_m + rc.max_dock_m:
                continue
            if too_wide:
                # The search could not cover where the island may be: a match inside it
                # could be a look-alike place.
                self.diagnostics.refuse(Refusal.DRIFT_TOO_LARGE)
                continue
            fit = self._search(cand.island, points, est, win)
            if fit is not None:
                found.append(with_distance(rc, fit, at, self.spreads(fit.island_id, snap)))
        if not found:
            return None
        best = min(found, key=lambda f: f.residual_m)
        rivals = [f for f in found if f.island_id != best.island_id
                  and f.inlier_fraction >= best.inlier_fraction - rc.ambiguity_inlier_margin]
        if not (rc.unique_island and rivals):
            rival = self._rival_fits(candidates, points, at, best.island_id, star)
            rivals = [] if rival is None else [rival]
        if rivals:
            self.hypotheses = look_alikes(rc, best, rivals, lambda i: self.spreads(i, snap), at,
                                          lambda i: self._estimate(i, snap, at))
            self.diagnostics.refuse(Refusal.LOOK_ALIKE)
            return None
        if best.inlier_fraction < rc.accept_inlier_fraction:  # rivals counted from min_...
            self.diagnostics.refuse(Refusal.INLIERS)
            return None
        chosen = next(c for c in candidates if c.island.id == best.island_id)
        if turned_alias(rc, self._search, chosen, best, points, star):
            self.diagnostics.refuse(Refusal.TURNED_ALIAS)
            return None
        far = None if not (rc.clipped_rivals and exceeds_caps(rc, chosen, star)) else (
            fits_elsewhere(self._refine, rc, [i for i in islands if i.id in self._known],
                           points, best, star))
        if far is not None:
            self.hypotheses = look_alikes(rc, best, [far], lambda i: self.spreads(i, snap), at,
                                          lambda i: self._estimate(i, snap, at))
            self.diagnostics.refuse(Refusal.FAR_LOOK_ALIKE)
        return best if far is None else None

    def estimates(self, island_id: int, snap: PoseSnapshot) -> list[tuple[Pose2D, float, float]]:
        """Where island island_id's origin may be in the odometry frame: (pose, position sigma
        [m], heading sigma [rad]), from its last known odometric pose (the odometry's drift
        since) and, when links join it to the last island, through the chain of links with the
        smallest summed sigma (epsilon plus the chain's error)."""
        origin, cov0 = self._known.origin(island_id), self._known.cov(island_id)
        grow = snap.odom_cov - cov0
        sys_var = self._known.residual_var(island_id)
        w_xy = np.linalg.eigvalsh(0.5 * (grow[:2, :2] + grow[:2, :2].T))
        out = [
            (
                origin,
                max(snap.epsilon_m, math.sqrt(max(float(w_xy[-1]), 0.0))),
                math.sqrt(max(float(grow[2, 2]), 0.0) + sys_var),
            )
        ]
        last = snap.last_island_id
        if last is not None and last in self._known and last != island_id:
            chain = self.links.chain(last, island_id)
            if chain is not None:
                base = self._known.origin(last)
                sig_rel_th = snap.heading_sigma_rad
                # The robot's own heading error since the last island turns the whole chain.
                reach = math.hypot(chain.pose.x, chain.pose.y)
                out.append((base.compose(chain.pose),
                            snap.epsilon_m + chain.sigma_m + sig_rel_th * reach,
                            sig_rel_th + chain.sigma_rad))
        return out

    def spreads(self, island_id: int, snap: PoseSnapshot) -> list[tuple[Pose2D, FloatArray]]:
        """The estimates of `estimates` with full covariances: (island island_id's origin in
        the odometry frame, 3x3 covariance of the robot's pose in the island frame by it).
        By odometry: the odometry's covariance since the origin was last known, relative to
        it (`uncertainty.relative_covariance`). Through the links: the robot's relative
        covariance since the last island's origin, and the chain's sigmas (isotropic in
        position: a link keeps the sigmas it was measured with)."""
        origin = self._known.origin(island_id)
        since = self._since(island_id, snap)
        since[2, 2] += self._known.residual_var(island_id)
        out = [(origin, in_frame(since, origin.theta))]
        last = snap.last_island_id
        if last is not None and last in self._known and last != island_id:
            chain = self.links.chain(last, island_id)
            if chain is not None:
                base = self._known.origin(last)
                robot = in_frame(self._since(last, snap), base.theta)
                link = np.diag([chain.sigma_m ** 2, chain.sigma_m ** 2, chain.sigma_rad ** 2])
                cov = between_covariance(chain.pose, link, snap.odom.relative_to(base), robot)
                out.append((base.compose(chain.pose), cov))
        return out

    def _estimate(self, island_id: int, snap: PoseSnapshot, at: Pose2D) -> Pose2D:
        """Odometric pose `at` in island island_id's frame, by its likeliest `estimates`."""
        return at.relative_to(min(self.estimates(island_id, snap), key=lambda e: e[1])[0])

    def _since(self, island_id: int, snap: PoseSnapshot) -> FloatArray:
        """The covariance of the robot's odometric pose now relative to where it was when
        island island_id's origin was last known (odometry axes)."""
        k = self._known
        return relative_covariance(k.cov_at(island_id), k.cov(island_id), snap.odom,
                                   snap.odom_cov)

    def _candidates(self, snap: PoseSnapshot, islands: Sequence[Island]) -> Iterator[_Candidate]:
        """Known islands a recognition may match, with their best odometric origin estimate
        and its sigmas: not the island just left."""
        by_id = {i.id: i for i in islands}
        just_left = snap.path_since_island_m < self.config.revisit.min_loop_m
        for iid in self._known:
            island = by_id.get(iid)
            if island is None or len(island.model) == 0:
                continue
            if iid == snap.last_island_id and just_left:
                continue
            origin, sig_m, sig_th = min(self.estimates(iid, snap), key=lambda e: e[1])
            yield _Candidate(island, origin, sig_m, sig_th)

    def _rival_fits(
        self, candidates: list[_Candidate], pts: FloatArray, at: Pose2D, chosen: int, star: bool,
    ) -> Recognition | None:
        """The fit of another known island that may be here (rival_sigmas) and fits the points
        too, or None. Its wide search finds an island whose odometric estimate drifted out of
        the narrow window the recognition searched."""
        rc = self.config.revisit
        k = rc.rival_sigmas
        if k <= 0:
            return None
        for cand in candidates:
            est = at.relative_to(cand.origin)
            if cand.island.id == chosen or math.hypot(est.x, est.y) > (
                k * cand.sigma_m + rc.max_dock_m
            ):
                continue
            dth = min(k * cand.sigma_rad, math.radians(rc.star_search_max_deg))
            win = rival_window(rc, cand, dth, star)
            # A rival's failed fits are not refusals of this recognition.
            fit = self._search(cand.island, pts, est, win, count_refusals=False)
            if fit is not None:
                return fit
        return None

    def _search(
        self, island: Island, pts: FloatArray, est: Pose2D, win: _Window,
        count_refusals: bool = True,
    ) -> Recognition | None:
        """The recognition of `island` in `pts` searched around `est` (see `recognize`), or
        None; each refusal is counted unless count_refusals is False."""
        rc = self.config.revisit
        refuse: Callable[[Refusal], None] = (
            self.diagnostics.refuse if count_refusals else _ignore)
        fits = self._refine(island, pts, est, win, refuse)
        if not fits:
            return None
        best = min(fits, key=lambda f: f.residual_m)
        p = best.pose
        if any(math.hypot(f.pose.x - p.x, f.pose.y - p.y) > rc.ambiguity_m
               and f.inlier_fraction >= best.inlier_fraction - rc.ambiguity_inlier_margin
               for f in fits):
            refuse(Refusal.AMBIGUOUS)
            return None
        if math.hypot(p.x, p.y) > rc.max_dock_m:
            refuse(Refusal.ORIGIN_TOO_FAR)
            return None
        segs = island.model.segments
        if not drive_clear(segs, np.array([p.x, p.y]), np.zeros(2), rc.path_clearance_m):
            refuse(Refusal.PATH_BLOCKED)
            return None
        if not localizes_back(self.config, island.model, pts, p):
            refuse(Refusal.LOCALIZATION_CHECK)
            return None
        return best

    def _guesses(self, island: Island, pts: FloatArray, est: Pose2D, win: _Window
                 ) -> list[Pose2D]:
        """The best-scoring distinct guesses of a grid around `est` (the fraction of points
        within inlier_m of the model), at most refine_guesses of them."""
        rc = self.config.revisit
        inliers = self._inlier_field(island)
        n = math.floor(win.radius_m / win.step_m + 1e-9)
        ticks = np.arange(-n, n + 1) * win.step_m
        gx, gy = np.meshgrid(ticks, ticks)
        inside = np.hypot(gx, gy) <= win.radius_m + 1e-9
        offs = np.stack([gx[inside], gy[inside]], axis=1)
        heading_step = math.radians(rc.heading_step_deg)
        m = math.floor(win.max_dth_rad / heading_step + 1e-9)
        guesses: list[tuple[float, Pose2D]] = []
        for dth in np.arange(-m, m + 1) * heading_step:
            th = est.theta + float(dth)
            c, s_ = math.cos(th), math.sin(th)
            rot = np.stack([c * pts[:, 0] - s_ * pts[:, 1], s_ * pts[:, 0] + c * pts[:, 1]], 1)
            base = rot + np.array([est.x, est.y])
            for chunk in np.array_split(offs, max(1, len(offs) // _GUESSES_PER_BATCH)):
                world = (base[None, :, :] + chunk[:, None, :]).reshape(-1, 2)
                score = np.mean(inliers.within(world).reshape(len(chunk), -1), axis=1)
                for k in range(len(chunk)):
                    guesses.append(
                        (float(score[k]), Pose2D(est.x + chunk[k, 0], est.y + chunk[k, 1], th))
                    )
        guesses.sort(key=lambda g: -g[0])
        chosen: list[Pose2D] = []
        for _, g in guesses:
            if all(math.hypot(g.x - c.x, g.y - c.y) > 2 * win.step_m for c in chosen):
                chosen.append(g)
            if len(chosen) >= rc.refine_guesses:
                break
        return chosen

    def _inlier_field(self, island: Island) -> InlierField:
        """The inlier test of island's model at revisit.inlier_m (made once per model)."""
        segs = island.model.segments
        got = self._fields.get(island.id)
        if got is None or got.inlier_m != self.config.revisit.inlier_m or not np.array_equal(
            got.segments, segs
        ):
            got = InlierField(segs, self.config.revisit.inlier_m)
        self._fields[island.id] = got
        self._fields.move_to_end(island.id)
        while len(self._fields) > _FIELDS_KEPT:
            self._fields.popitem(last=False)
        return got

    def _refine(self, island: Island, pts: FloatArray, est: Pose2D, win: _Window,
                refuse: Callable[[Refusal], None]) -> list[Recognition]:
        """Every refined guess that fits the model well (each refused one counted)."""
        rc = self.config.revisit
        heading_step = math.radians(rc.heading_step_deg)
        segs = island.model.segments
        fits: list[Recognition] = []
        for g in self._guesses(island, pts, est, win):
            res = localize(island.model, pts, g, self.config.localize)
            p = res.pose
            reason: Refusal | None = None
            if not res.converged:
                reason = Refusal.NOT_CONVERGED
            elif res.residual_m > win.max_residual_m:
                reason = Refusal.RESIDUAL
            elif res.constraint < rc.min_constraint:
                reason = Refusal.WEAK_CONSTRAINT
            elif math.hypot(p.x - est.x, p.y - est.y) > win.radius_m:
                reason = Refusal.OUTSIDE_SEARCH_RADIUS
            elif abs(wrap_angle(p.theta - est.theta)) > win.max_dth_rad + 2.0 * heading_step:
                # The refinement turned the points far out of the heading window (a +
                # junction fits itself turned by 90 deg).
                reason = Refusal.OUTSIDE_HEADING_WINDOW
            if reason is not None:
                refuse(reason)
                continue
            world = from_frame(pts, p)
            inl = float(np.mean(point_segment_distance(world, segs).min(axis=1) <= rc.inlier_m))
            if inl < rc.min_inlier_fraction:
                refuse(Refusal.INLIERS)
                continue
            fits.append(Recognition(island.id, p, float(res.residual_m), inl))
        return fits


__all__ = ["PoseSnapshot", "Recognition", "Recognizer", "exceeds_caps", "fits_elsewhere",
           "look_alikes", "rival_window", "search_window", "turned_alias", "with_distance"]
