"""Synthetic CARMEN logs of any building, for testing the real-log path where no real log of it
is at hand (the only real laser log offline is Intel's).

`simulate_log(world, ...)` drives a robot through a world (`island_sim.core.world_loader`
spec: HouseExpo rooms, the Willow floor plan, generated offices) along shortest paths between
seeded random goals in its free space, casts a laser of the chosen geometry, front or rear
(facing backwards, as CARMEN's rear laser), mounted anywhere on the robot, or a ring of sonar
transducers (one axis ray each, no beam width or specular loss), through the world
(`island_msgs_py.raycast` via the world), and integrates odometry with seeded noise.
`carmen_lines` writes it as a GMapping-corrected-style CARMEN log: PARAM lines with the laser's
resolution, field of view and mount offsets, FLASER (RLASER) lines with the laser's pose (the
corrected robot pose composed with the mount) in the pose fields and the raw odometry in the
odometry fields, or SONAR lines with each transducer's pose on the robot, and ODOM lines between
scans as "the corrected pose of the previous scan plus the raw odometry since" (what GMapping
writes); `relation_lines` writes Kuemmerle-style relations between scan times from the true
poses, in UNIX time; `write_all` those and the true poses as `t x y theta` lines.

  python -m island_mapping.evaluation.synthetic_log WORLD OUT_PREFIX [--beams 361 --fov 180]
      [--kind FLASER|RLASER|SONAR] [--mount X,Y,THETA_DEG] [--ring-radius M]
"""

from __future__ import annotations

import argparse
import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
from island_msgs_py.geometry import compose_poses, relative_poses, wrap_angles
from island_msgs_py.json_io import atomic_write_text
from island_sim.core.freespace import free_space
from island_sim.core.world import World
from island_sim.core.world_loader import load_world

FloatArray = npt.NDArray[np.float64]

NO_RETURN_M = 81.83
"""Range a SICK reports without an echo (as in the Intel log) [m]."""
UNIX_START_S = 1.134862e9
"""UNIX time of the synthetic logs' start (a 2005 date, like the public CARMEN logs) [s]."""
SONAR_MAX_RANGE_M = 5.0
"""A simulated sonar transducer's range, and the reading it reports without an echo (as a
Pioneer's does) [m]."""
SONAR_CONE_RAD = math.radians(25.0)
"""The cone angle a SONAR line records (not simulated: one axis ray per transducer) [rad]."""


@dataclass(frozen=True)
class SyntheticLog:
    """A simulated run: per scan the time [s], true pose, raw odometry pose, ranges [m], and
    a "corrected" pose (the truth with a SLAM-sized error) for the log's corrected fields."""

    name: str
    times_s: FloatArray
    truth: FloatArray
    corrected: FloatArray
    odometry: FloatArray
    ranges_m: FloatArray
    fov_deg: float
    resolution_deg: float
    kind: str = "FLASER"
    """The CARMEN line of the sensor: FLASER, RLASER (a laser facing backwards) or SONAR."""
    mount: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """The laser's pose on the robot (x [m], y [m], theta [rad]; RLASER's includes its pi)."""
    beam_poses: FloatArray | None = None
    """(B, 3) each SONAR transducer's pose on the robot [m, m, rad]."""


def _path_poses(world: World, goals: int, step_m: float, turn_step_rad: float,
                rng: np.random.Generator) -> FloatArray:
    """True poses every step_m along shortest paths between `goals` random reachable points,
    turning in place (turn_step_rad per pose) at each corner."""
    fs = free_space(world)
    cells = np.argwhere(fs.reachable)
    start = world.start_pose
    pts = [np.array([start.x, start.y])]
    heading = start.theta
    poses: list[FloatArray] = [np.array([start.x, start.y, heading])]
    for _ in range(goals):
        r, c = cells[rng.integers(cells.shape[0])]
        goal = fs.raster.centres_m(np.array([r]), np.array([c]))[0]
        length, poly = fs.shortest_path_m((float(pts[-1][0]), float(pts[-1][1])),
                                          (float(goal[0]), float(goal[1])))
        if not math.isfinite(length) or poly.shape[0] < 2:
            continue
        for a, b in itertools.pairwise(poly):
            seg = b - a
            d = float(np.hypot(*seg))
            if d < 1e-6:
                continue
            target = math.atan2(seg[1], seg[0])
            turn = float(wrap_angles(np.array([target - heading]))[0])
            for k in range(1, int(abs(turn) // turn_step_rad) + 1):
                poses.append(np.array([a[0], a[1], heading + math.copysign(k * turn_step_rad,
                                                                           turn)]))
            heading = target
            for s in np.arange(step_m, d + 1e-9, step_m):
                p = a + seg * (s / d)
                poses.append(np.array([p[0], p[1], heading]))
        pts.append(poly[-1])
    return np.asarray(poses, dtype=np.float64)


def _sensor_poses(kind: str, beams: int, fov_deg: float, mount: tuple[float, float, float],
                  ring_radius_m: float) -> tuple[FloatArray, tuple[float, float, float]]:
    """((B, 3) each beam's pose on the robot, the laser's mount incl. a rear laser's pi)."""
    if kind == "SONAR":
        a = 2.0 * math.pi * np.arange(beams) / beams
        return np.stack([ring_radius_m * np.cos(a), ring_radius_m * np.sin(a), a], axis=1), (
            0.0, 0.0, 0.0)
    if kind == "RLASER":  # faces backwards, `mount` given as if it were a front laser
        x, y, th = compose_poses(np.array([0.0, 0.0, math.pi]), np.asarray(mount))[0]
        mount = (float(x), float(y), float(th))
    inc = math.radians(fov_deg) / (beams - 1)
    angles = -0.5 * math.radians(fov_deg) + inc * np.arange(beams)
    on_laser = np.stack([np.zeros(beams), np.zeros(beams), angles], axis=1)
    return compose_poses(np.asarray(mount, dtype=np.float64), on_laser), mount


def simulate_log(world_spec: str, *, beams: int = 361, fov_deg: float = 180.0, goals: int = 6,
                 step_m: float = 0.25, seed: int = 1, range_noise_m: float = 0.01,
                 odom_noise: tuple[float, float] = (0.03, 0.02), max_range_m: float = 30.0,
                 scan_period_s: float = 0.8,
                 corrected_noise: tuple[float, float] = (0.02, 0.5), kind: str = "FLASER",
                 mount: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 ring_radius_m: float = 0.225) -> SyntheticLog:
    """A simulated run in a world (module docstring). odom_noise: the standard deviation
    of the relative odometry error per metre driven [m/m] and per radian turned [rad/rad];
    corrected_noise: the corrected poses' error (standard deviation [m], [deg]); kind: FLASER,
    RLASER (`mount` then as if it faced forwards) or SONAR (`beams` transducers evenly on a
    ring of ring_radius_m [m], SONAR_MAX_RANGE_M)."""
    if kind not in ("FLASER", "RLASER", "SONAR"):
        raise ValueError(f"kind: expected FLASER, RLASER or SONAR, got {kind!r}")
    rng = np.random.default_rng(seed)
    world = load_world(world_spec)
    truth = _path_poses(world, goals, step_m, math.radians(20.0), rng)
    poses, mount = _sensor_poses(kind, beams, fov_deg, mount, ring_radius_m)
    reach, no_echo = ((SONAR_MAX_RANGE_M, SONAR_MAX_RANGE_M) if kind == "SONAR"
                      else (max_range_m, NO_RETURN_M))
    ranges = np.empty((truth.shape[0], beams))
    for i, p in enumerate(truth):
        at = compose_poses(p, poses)
        hits = world.raycast(at[:, :2], at[:, 2], reach)
        r = hits.distance_m + rng.normal(0.0, range_noise_m, beams)
        ranges[i] = np.where(np.isfinite(hits.distance_m), np.clip(r, 0.0, reach), no_echo)
    steps = relative_poses(truth[:-1], truth[1:])
    d = np.hypot(steps[:, 0], steps[:, 1])
    noisy = steps.copy()
    noisy[:, 0] *= 1.0 + rng.normal(0.0, odom_noise[0], d.size)
    noisy[:, 1] += rng.normal(0.0, odom_noise[0], d.size) * d * 0.5
    noisy[:, 2] += rng.normal(0.0, odom_noise[1], d.size) * (np.abs(steps[:, 2]) + 0.2 * d)
    odo = [truth[0].copy()]
    for s in noisy:
        odo.append(compose_poses(odo[-1], s)[0])
    # Scan periods jitter as a real laser's do (a strictly periodic clock would let relation
    # times fit a log shifted by whole periods).
    periods: FloatArray = scan_period_s * (
        1.0 + 0.2 * np.asarray(rng.uniform(-1.0, 1.0, truth.shape[0]), dtype=np.float64))
    times: FloatArray = np.cumsum(periods) - periods[0] + 0.123
    name = world_spec if ":" in world_spec else Path(world_spec).stem
    corrected: FloatArray = truth + rng.normal(0.0, 1.0, truth.shape) * np.array(
        [corrected_noise[0], corrected_noise[0], math.radians(corrected_noise[1])])
    return SyntheticLog(name, times, truth, corrected, np.asarray(odo), ranges, fov_deg,
                        fov_deg / (beams - 1), kind, mount,
                        poses if kind == "SONAR" else None)


def _t(t: float, g_times: bool) -> str:
    return f"{t:g}" if g_times else f"{t:.6f}"


def carmen_lines(log: SyntheticLog, *, unix_times: bool = False, g_times: bool = False,
                 params: bool = True) -> list[str]:
    """The log as CARMEN text lines (module docstring); unix_times: timestamps in UNIX time
    (else from the log's start); g_times: printed with %g (6 significant digits)."""
    off = UNIX_START_S if unix_times else 0.0
    out = [f"# synthetic CARMEN log of {log.name} (island_mapping.evaluation.synthetic_log)"]
    out += _param_lines(log, params)
    # A SONAR log has no corrected poses: its ODOM lines are the raw odometry itself (a raw
    # CARMEN log's), which composing onto the previous raw pose instead of the corrected one
    # gives; the first is written before the first scan.
    raw_only = log.kind == "SONAR"
    prev_corr = log.odometry[0] if raw_only else np.zeros(3)
    prev_odo = log.odometry[0]
    if raw_only:
        tm = log.times_s[0] - 0.001 + off
        out.append(f"ODOM {prev_odo[0]:.6f} {prev_odo[1]:.6f} {prev_odo[2]:.6f} 0 0 0 "
                   f"{_t(tm, g_times)} sim {_t(tm, g_times)}")
    for i in range(log.times_s.shape[0]):
        t = log.times_s[i] + off
        if i > 0:  # ODOM lines half way and at the scan: corrected previous scan + raw since
            for frac, tm in ((0.5, 0.5 * (log.times_s[i - 1] + log.times_s[i])),
                             (1.0, log.times_s[i] - 0.001)):
                inc = relative_poses(log.odometry[i - 1], log.odometry[i])[0]
                mid = compose_poses(log.odometry[i - 1], frac * inc)[0]
                od = compose_poses(prev_corr, relative_poses(prev_odo, mid))[0]
                out.append(f"ODOM {od[0]:.6f} {od[1]:.6f} {od[2]:.6f} 0 0 0 "
                           f"{_t(tm + off, g_times)} sim {_t(tm + off, g_times)}")
        od = compose_poses(prev_corr, relative_poses(prev_odo, log.odometry[i]))[0] if i else (
            log.corrected[0])
        rng = " ".join(f"{r:.3f}" for r in log.ranges_m[i])
        stamp = f"{_t(t, g_times)} sim {_t(t, g_times)}"
        if log.kind == "SONAR":
            assert log.beam_poses is not None
            offs = " ".join(f"{x:.4f} {y:.4f} {a:.6f}" for x, y, a in log.beam_poses)
            out.append(f"SONAR {SONAR_CONE_RAD:.6f} {log.ranges_m.shape[1]} {rng} {offs} {stamp}")
        else:  # the pose fields: the laser's pose (CARMEN's), the corrected robot's + mount
            x, y, th = compose_poses(log.corrected[i], np.asarray(log.mount))[0]
            out.append(f"{log.kind} {log.ranges_m.shape[1]} {rng} {x:.6f} {y:.6f} {th:.6f} "
                       f"{od[0]:.6f} {od[1]:.6f} {od[2]:.6f} {stamp}")
        prev_corr, prev_odo = log.odometry[i] if raw_only else log.corrected[i], log.odometry[i]
    return out


def _param_lines(log: SyntheticLog, params: bool) -> list[str]:
    """The laser's PARAM lines: resolution and field of view (when `params`), and its mount
    offsets as CARMEN writes them (a rear laser's in its own, backward-facing frame: the mount
    turned back by pi; always, when not 0)."""
    if log.kind == "SONAR":
        return []
    front = log.kind == "FLASER"
    las = "laser_front_laser_" if front else "laser_rear_laser_"
    out = ([f"PARAM {las}resolution {log.resolution_deg:g} host 0.0",
            f"PARAM {las}fov {log.fov_deg:g} host 0.0"] if params else [])
    x, y, th = log.mount if front else compose_poses(np.array([0.0, 0.0, math.pi]),
                                                     np.asarray(log.mount))[0]
    rob = "robot_frontlaser_" if front else "robot_rearlaser_"
    if any(abs(v) > 1e-12 for v in (x, y, th)):
        th = float(wrap_angles(np.array([th]))[0])
        out += [f"PARAM {rob}offset {x:g} host 0.0",
                f"PARAM {rob}side_offset {y:g} host 0.0",
                f"PARAM {rob}angular_offset {th:g} host 0.0"]
    return out


def relation_lines(log: SyntheticLog, pairs: int = 400, max_gap: int = 12,
                   seed: int = 2) -> list[str]:
    """Kuemmerle-style relations `t1 t2 x y z roll pitch yaw` between scan times (UNIX time)
    from the true poses: scan pairs up to max_gap scans apart."""
    rng = np.random.default_rng(seed)
    n = log.times_s.shape[0]
    i = rng.integers(0, n - 1, pairs)
    j = np.minimum(i + rng.integers(1, max_gap + 1, pairs), n - 1)
    rel = relative_poses(log.truth[i], log.truth[j])
    t = log.times_s + UNIX_START_S
    return [f"{t[a]:.6f} {t[b]:.6f} {r[0]:.6f} {r[1]:.6f} 0 0 0 {r[2]:.6f}"
            for a, b, r in zip(i, j, rel, strict=True)]


def write_all(log: SyntheticLog, prefix: str | Path, **kw: bool) -> dict[str, Path]:
    """PREFIX.log, PREFIX.relations and PREFIX.reference (true poses, `t x y theta`)."""
    p = Path(prefix)
    paths = {"log": p.with_suffix(".log"), "relations": p.with_suffix(".relations"),
             "reference": p.with_suffix(".reference")}
    atomic_write_text(paths["log"], "\n".join(carmen_lines(log, **kw)) + "\n")
    atomic_write_text(paths["relations"], "\n".join(relation_lines(log)) + "\n")
    ref = [f"{t:.6f} {x:.6f} {y:.6f} {th:.6f}"
           for t, (x, y, th) in zip(log.times_s, log.truth, strict=True)]
    atomic_write_text(paths["reference"], "\n".join(ref) + "\n")
    return paths


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("world", help="world spec (file, built-in name, gen:office:seed=N)")
    ap.add_argument("prefix", help="output prefix (writes PREFIX.log/.relations/.reference)")
    ap.add_argument("--beams", type=int, default=361)
    ap.add_argument("--fov", type=float, default=180.0, help="field of view [deg]")
    ap.add_argument("--goals", type=int, default=6)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--g-times", action="store_true", help="print times with %%g")
    ap.add_argument("--no-params", action="store_true", help="no PARAM lines")
    ap.add_argument("--kind", default="FLASER", choices=("FLASER", "RLASER", "SONAR"),
                    help="the sensor's CARMEN lines (SONAR: --beams transducers on a ring)")
    ap.add_argument("--mount", default="0,0,0",
                    help="the laser's pose on the robot X,Y,THETA [m, m, deg] (RLASER: as if "
                         "facing forwards)")
    ap.add_argument("--ring-radius", type=float, default=0.225, help="sonar ring radius [m]")
    a = ap.parse_args(argv)
    mx, my, mth = (float(v) for v in a.mount.split(","))
    log = simulate_log(a.world, beams=a.beams, fov_deg=a.fov, goals=a.goals, seed=a.seed,
                       kind=a.kind, mount=(mx, my, math.radians(mth)),
                       ring_radius_m=a.ring_radius)
    paths = write_all(log, a.prefix, g_times=a.g_times, params=not a.no_params)
    print(f"{log.times_s.size} scans of {a.beams} beams: " + ", ".join(map(str, paths.values())))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
