"""How the simulator steps time: the loop's parameters (`SimLoopConfig`), fixed-step simulated
time (`SimClock`: which steps publish /odom, /ground_truth and /clock, which end a sensor
period), pacing by the wall clock (`RealTimePacer`) and the lockstep with the controllers
(`CommandGate`). Used by the odometry node and in-process runners (numpy-free).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from island_sim.core.robot import RobotError, check_finite


@dataclass(frozen=True)
class SimLoopConfig:
    """How the simulator steps time (used by the odometry node and in-process runners)."""

    physics_rate_hz: float = field(
        default=50.0,
        metadata={"help": "physics/odometry steps per simulated second [Hz]",
                  "range": (0.0, math.inf)},
    )
    sensor_rate_hz: float = field(
        default=10.0,
        metadata={"help": "sonar scans (and controller periods) per simulated second; must "
                  "divide physics_rate_hz [Hz]", "range": (0.0, math.inf)},
    )
    publish_rate_hz: float = field(
        default=50.0,
        metadata={"help": "rate of /odom (and the highest of /ground_truth and /clock); must "
                  "divide physics_rate_hz and be a multiple of sensor_rate_hz [Hz]",
                  "range": (0.0, math.inf)},
    )
    truth_rate_hz: float = field(
        default=0.0,
        metadata={"help": "rate of /ground_truth; 0 = publish_rate_hz; else it must divide "
                  "publish_rate_hz and be a multiple of sensor_rate_hz (the sonar fires on "
                  "the sensor period's stamps, so the sensor rate is all it needs) [Hz]",
                  "range": (0.0, math.inf)},
    )
    clock_rate_hz: float = field(
        default=0.0,
        metadata={"help": "rate of /clock; 0 = publish_rate_hz; else it must divide "
                  "publish_rate_hz and be a multiple of sensor_rate_hz (in lockstep the steps "
                  "between two sensor instants are taken at once, so the sensor rate tells "
                  "sim-time nodes as much) [Hz]", "range": (0.0, math.inf)},
    )
    real_time_factor: float = field(
        default=1.0,
        metadata={"help": "simulated seconds per wall second; 0 = as fast as possible [-]",
                  "live": True, "range": (0.0, math.inf)},
    )
    lockstep: bool = field(
        default=False,
        metadata={"help": "at every sensor period wait for that period's /cmd_vel before "
                  "stepping on (deterministic runs) [bool]"},
    )
    lockstep_timeout_s: float = field(
        default=2.0,
        metadata={"help": "wall-clock wait for a lockstep /cmd_vel before stepping anyway [s]",
                  "live": True, "range": (0.0, math.inf)},
    )
    own_clock: bool = field(
        default=True, metadata={"help": "publish rosgraph_msgs/Clock on /clock [bool]"}
    )
    cmd_timeout_s: float = field(
        default=0.5,
        metadata={"help": "stop the robot when no /cmd_vel arrived for this simulated time [s]",
                  "live": True, "range": (0.0, math.inf)},
    )
    stop_after_s: float = field(
        default=0.0,
        metadata={"help": "stop stepping at this simulated time; 0 = run forever [s]",
                  "range": (0.0, math.inf)},
    )

    def __post_init__(self) -> None:
        check_finite(
            "SimLoopConfig",
            {
                "physics_rate_hz": self.physics_rate_hz,
                "sensor_rate_hz": self.sensor_rate_hz,
                "publish_rate_hz": self.publish_rate_hz,
                "truth_rate_hz": self.truth_rate_hz,
                "clock_rate_hz": self.clock_rate_hz,
                "real_time_factor": self.real_time_factor,
                "lockstep_timeout_s": self.lockstep_timeout_s,
                "cmd_timeout_s": self.cmd_timeout_s,
                "stop_after_s": self.stop_after_s,
            },
        )
        if self.physics_rate_hz <= 0 or self.sensor_rate_hz <= 0:
            raise RobotError("SimLoopConfig: physics_rate_hz and sensor_rate_hz must be > 0")
        ratio = self.physics_rate_hz / self.sensor_rate_hz
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise RobotError(
                f"SimLoopConfig: sensor_rate_hz ({self.sensor_rate_hz}) must divide "
                f"physics_rate_hz ({self.physics_rate_hz}) into a whole number of steps"
            )
        _check_rate("publish_rate_hz", self.publish_rate_hz, "physics_rate_hz",
                    self.physics_rate_hz, self.sensor_rate_hz)
        for name in ("truth_rate_hz", "clock_rate_hz"):
            if getattr(self, name) != 0.0:
                _check_rate(name, getattr(self, name), "publish_rate_hz", self.publish_rate_hz,
                            self.sensor_rate_hz)
        if self.real_time_factor < 0:
            raise RobotError(
                f"SimLoopConfig.real_time_factor: must be >= 0, got {self.real_time_factor}"
            )
        if self.lockstep_timeout_s <= 0 or self.cmd_timeout_s <= 0:
            raise RobotError("SimLoopConfig: lockstep_timeout_s and cmd_timeout_s must be > 0")
        if self.stop_after_s < 0:
            raise RobotError(f"SimLoopConfig.stop_after_s: must be >= 0, got {self.stop_after_s}")

    @property
    def dt_s(self) -> float:
        """Fixed physics step [s]."""
        return 1.0 / self.physics_rate_hz

    @property
    def dt_ns(self) -> int:
        """Fixed physics step [ns] (sim time advances in whole steps)."""
        return round(1e9 / self.physics_rate_hz)

    @property
    def steps_per_publish(self) -> int:
        """Physics steps between publications of /odom, /ground_truth and /clock [-]."""
        return round(self.physics_rate_hz / self.publish_rate_hz)

    @property
    def steps_per_sensor_period(self) -> int:
        """Physics steps per sonar/controller period [-]."""
        return round(self.physics_rate_hz / self.sensor_rate_hz)

    @property
    def steps_per_truth(self) -> int:
        """Physics steps between publications of /ground_truth [-]."""
        return round(self.physics_rate_hz / (self.truth_rate_hz or self.publish_rate_hz))

    @property
    def steps_per_clock(self) -> int:
        """Physics steps between publications of /clock [-]."""
        return round(self.physics_rate_hz / (self.clock_rate_hz or self.publish_rate_hz))


def _check_rate(name: str, rate_hz: float, of_name: str, of_hz: float, sensor_hz: float) -> None:
    """`rate_hz` must divide `of_hz` and be a whole multiple of `sensor_hz` (RobotError)."""
    div = of_hz / rate_hz if rate_hz > 0 else 0.0
    per = rate_hz / sensor_hz
    if div < 1 or abs(div - round(div)) > 1e-9 or per < 1 or abs(per - round(per)) > 1e-9:
        raise RobotError(f"SimLoopConfig.{name} ({rate_hz}) must divide {of_name} ({of_hz}) "
                         f"and be a whole multiple of sensor_rate_hz ({sensor_hz})")


class SimClock:
    """Fixed-step simulated time: the step count, which steps publish, which end a sensor period
    (a lockstep boundary) and when the run is over (`SimLoopConfig.stop_after_s`, 0 = never)."""

    def __init__(self, cfg: SimLoopConfig) -> None:
        self.dt_ns = cfg.dt_ns
        self.steps_per_period = cfg.steps_per_sensor_period
        self.steps_per_publish = cfg.steps_per_publish
        self.steps_per_truth = cfg.steps_per_truth
        self.steps_per_clock = cfg.steps_per_clock
        self._stop_ns = round(cfg.stop_after_s * 1e9)
        self.step_count = 0

    @property
    def sim_time_ns(self) -> int:
        return self.step_count * self.dt_ns

    @property
    def finished(self) -> bool:
        return self._stop_ns > 0 and self.sim_time_ns >= self._stop_ns

    @property
    def at_boundary(self) -> bool:
        """Sim time is at the start of a sensor period (step 0 included)."""
        return self.step_count % self.steps_per_period == 0

    def advance(self) -> bool:
        """One step taken; True when the new instant is to be published (/odom, and /clock or
        /ground_truth where `due` says so)."""
        self.step_count += 1
        return self.step_count % self.steps_per_publish == 0

    def due(self, steps: int) -> bool:
        """Is the current instant one of every `steps` steps (e.g. `steps_per_clock`)?"""
        return self.step_count % steps == 0


class RealTimePacer:
    """How many fixed physics steps are due at a wall-clock time for a real-time factor.

    The simulation runs in fixed steps of `dt_ns` of sim time; the wall clock only decides when.
    Steps are due so that sim time keeps `real_time_factor` times the wall time elapsed since the
    pacing origin; at most `max_steps` at once, and a pacer that fell further behind than that
    restarts its origin instead of catching up later (a burst would starve the subscribers).
    """

    def __init__(self, real_time_factor: float, dt_ns: int, max_steps: int) -> None:
        if not (real_time_factor > 0 and dt_ns > 0 and max_steps > 0):
            raise RobotError(
                f"RealTimePacer: needs real_time_factor > 0, dt_ns > 0, max_steps > 0; got "
                f"{real_time_factor}, {dt_ns}, {max_steps}"
            )
        self.real_time_factor = real_time_factor
        self.dt_ns = dt_ns
        self.max_steps = max_steps
        self._origin: tuple[float, int] | None = None  # (wall time [s], step count) there

    def steps_due(self, now_s: float, step_count: int) -> int:
        """Steps to take now [-], given the wall time `now_s` [s] and the steps taken so far."""
        if self._origin is None:
            self._origin = (now_s, step_count)
        t0, k0 = self._origin
        due = k0 + int((now_s - t0) * self.real_time_factor * 1e9 / self.dt_ns) - step_count
        if due > self.max_steps:  # fell behind: do not try to catch up later
            self._origin = (now_s, step_count)
        return max(0, min(due, self.max_steps))


class CommandGate:
    """Which velocity command the simulated robot obeys, and in lockstep when it may step on.

    Commands carry the stamp [ns] of the sensor data they answer (0 = "now", for hand-typed
    ones). A command older than one already taken is stale and ignored. The latest taken command
    applies until `cmd_timeout_ns` of sim time without one, then the robot stops. In lockstep, at
    every sensor boundary the robot waits for a command answering that boundary's stamp (or a
    later one): waiting by stamp, not by counting messages, because when two controllers answer
    one scan (the hall follower and the island builder at a hand-over) a count runs ahead for
    good and every later command would act a period late.
    """

    def __init__(self, lockstep: bool, cmd_timeout_ns: int) -> None:
        if cmd_timeout_ns <= 0:
            raise RobotError(f"CommandGate: cmd_timeout_ns must be > 0, got {cmd_timeout_ns}")
        self.lockstep = lockstep
        self.cmd_timeout_ns = cmd_timeout_ns
        self.command = (0.0, 0.0)  # (v [m/s], w [rad/s]) of the latest command taken
        self.taken = 0  # commands taken
        self.stale = 0  # commands ignored: older than one already taken
        self.answered_ns = -1  # stamp of the latest command taken [ns]
        self.waiting_for_ns: int | None = None  # lockstep: the boundary stamp being waited for
        self._taken_at_ns: int | None = None  # sim time when the latest was taken [ns]

    def offer(self, v_mps: float, w_radps: float, stamp_ns: int, now_ns: int) -> bool:
        """A command arrives at sim time `now_ns`; True if it ends the current lockstep wait."""
        if stamp_ns == 0:
            stamp_ns = now_ns
        if stamp_ns < self.answered_ns:
            self.stale += 1
            return False
        self.command = (v_mps, w_radps)
        self.answered_ns = stamp_ns
        self.taken += 1
        self._taken_at_ns = now_ns
        if self.waiting_for_ns is not None and stamp_ns >= self.waiting_for_ns:
            self.waiting_for_ns = None
            return True
        return False

    def must_wait(self, boundary_ns: int) -> bool:
        """At a sensor boundary: must the robot wait for a command answering it?"""
        if not self.lockstep or self.answered_ns >= boundary_ns:
            return False
        self.waiting_for_ns = boundary_ns
        return True

    def give_up(self) -> None:
        """Step on without the awaited command (its period counts as answered)."""
        if self.waiting_for_ns is not None:
            self.answered_ns = self.waiting_for_ns
            self.waiting_for_ns = None

    def current(self, now_ns: int) -> tuple[float, float]:
        """The command to apply at sim time `now_ns` (zero before any, or after the timeout)."""
        if self._taken_at_ns is None or now_ns - self._taken_at_ns > self.cmd_timeout_ns:
            return 0.0, 0.0
        return self.command
