"""A Nomad-200-like sonar ring simulated on a line-segment world (numpy only).

Model (see docs/sonar_model.md):
- N transducers on a ring of radius `ring_radius_m` around the robot centre; transducer i looks
  along the robot-frame bearing `first_angle_deg + i * 360 / N` (counter-clockwise).
- Each transducer is a cone of `beam_width_deg`, sampled by `rays_per_beam` rays spread evenly
  over the cone and starting at the transducer's position on the ring.
- A ray gives an echo when it hits a wall within [range_min_m, range_max_m] of the transducer
  and the angle of incidence (between the ray and the wall normal) is at most `reflect_deg`;
  otherwise the ray is lost (specular reflection away from the receiver, or out of range).
- The transducer reports the smallest echo distance among its rays (the first echo to return),
  plus Gaussian noise, as if it lay on its axis. A reading outside the limits after noise is lost.
- Ranges are reported from the ROBOT CENTRE (echo distance + ring radius), the LaserScan
  convention; `inf` means no echo.
- Ideal mode: one ray on the axis, no noise, no specular loss (range limits still apply).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from island_msgs_py.errors import InputError
from island_msgs_py.raycast import RayCaster
from island_msgs_py.types import FloatArray, Pose2D


class SonarError(InputError):
    """A sonar configuration or call argument is invalid; the message names the field."""


@dataclass(frozen=True)
class SonarConfig:
    """Parameters of the simulated sonar ring (defaults: a Nomad 200 with 16 Polaroid sensors)."""

    num_transducers: int = field(
        default=16, metadata={"help": "number of transducers on the ring, evenly spaced [-]",
                              "range": (1, math.inf)}
    )
    first_angle_deg: float = field(
        default=0.0,
        metadata={"help": "bearing of transducer 0 in the robot frame, 0 = heading [deg]; "
                  "the others follow counter-clockwise every 360/N deg"},
    )
    ring_radius_m: float = field(
        default=0.225, metadata={"help": "distance of the transducers from the robot centre [m]",
                                 "range": (0.0, math.inf)}
    )
    beam_width_deg: float = field(
        default=25.0, metadata={"help": "full opening angle of each transducer's cone [deg]",
                                "range": (0.0, 180.0)}
    )
    rays_per_beam: int = field(
        default=5, metadata={"help": "rays sampling each cone, spread evenly over its width [-]",
                             "range": (1, math.inf)}
    )
    range_min_m: float = field(
        default=0.15,
        metadata={"help": "closest echo a transducer reports, from the transducer [m]",
                  "range": (0.0, math.inf)},
    )
    range_max_m: float = field(
        default=6.5,
        metadata={"help": "farthest echo a transducer reports, from the transducer [m]",
                  "range": (0.0, math.inf)},
    )
    reflect_deg: float = field(
        default=30.0,
        metadata={"help": "largest incidence angle (ray vs wall normal) that still returns an "
                  "echo; beyond it the ray is reflected away and lost [deg]",
                  "range": (0.0, 90.0)},
    )
    noise_std_m: float = field(
        default=0.01, metadata={"help": "standard deviation of Gaussian range noise [m]",
                                "range": (0.0, math.inf)}
    )
    ideal: bool = field(
        default=False,
        metadata={"help": "one ray on the axis, no noise, no specular loss (for tests) [bool]"},
    )

    def __post_init__(self) -> None:
        floats = {
            "first_angle_deg": self.first_angle_deg,
            "ring_radius_m": self.ring_radius_m,
            "beam_width_deg": self.beam_width_deg,
            "range_min_m": self.range_min_m,
            "range_max_m": self.range_max_m,
            "reflect_deg": self.reflect_deg,
            "noise_std_m": self.noise_std_m,
        }
        for name, value in floats.items():
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise SonarError(f"SonarConfig.{name}: expected a number, got {value!r}")
            if not math.isfinite(value):
                raise SonarError(f"SonarConfig.{name}: expected a finite number, got {value!r}")
        for name, ivalue in (
            ("num_transducers", self.num_transducers),
            ("rays_per_beam", self.rays_per_beam),
        ):
            if isinstance(ivalue, bool) or not isinstance(ivalue, int | np.integer):
                raise SonarError(f"SonarConfig.{name}: expected an integer, got {ivalue!r}")
            if ivalue < 1:
                raise SonarError(f"SonarConfig.{name}: must be >= 1, got {ivalue}")
        if self.ring_radius_m < 0:
            raise SonarError(f"SonarConfig.ring_radius_m: must be >= 0, got {self.ring_radius_m}")
        if not 0.0 <= self.beam_width_deg < 180.0:
            raise SonarError(
                f"SonarConfig.beam_width_deg: must be in [0, 180), got {self.beam_width_deg}"
            )
        if self.range_min_m < 0:
            raise SonarError(f"SonarConfig.range_min_m: must be >= 0, got {self.range_min_m}")
        if self.range_max_m <= self.range_min_m:
            raise SonarError(
                f"SonarConfig.range_max_m ({self.range_max_m}) must exceed range_min_m "
                f"({self.range_min_m})"
            )
        if not 0.0 < self.reflect_deg <= 90.0:
            raise SonarError(f"SonarConfig.reflect_deg: must be in (0, 90], got {self.reflect_deg}")
        if self.noise_std_m < 0:
            raise SonarError(f"SonarConfig.noise_std_m: must be >= 0, got {self.noise_std_m}")
        if not isinstance(self.ideal, bool | np.bool_):
            raise SonarError(f"SonarConfig.ideal: expected a bool, got {self.ideal!r}")


class SonarModel:
    """Simulates the ring described by a `SonarConfig` on a `World` (any `RayCaster`).

    `seed` seeds the model's own generator, used when `scan` gets no `rng`: a model is
    deterministic unless the caller passes a generator of its own.
    """

    def __init__(self, config: SonarConfig | None = None, seed: int = 0) -> None:
        self.config = config if config is not None else SonarConfig()
        c = self.config
        n = int(c.num_transducers)
        self._angles: FloatArray = math.radians(c.first_angle_deg) + np.arange(
            n, dtype=np.float64
        ) * (2.0 * math.pi / n)
        self._angles.setflags(write=False)
        if c.ideal or c.rays_per_beam == 1:
            offsets = np.zeros(1)
        else:
            half = math.radians(c.beam_width_deg) / 2.0
            offsets = np.linspace(-half, half, int(c.rays_per_beam))
        self._offsets: FloatArray = offsets.astype(np.float64)
        self._cos_reflect = math.cos(math.radians(c.reflect_deg))
        self._rng = np.random.default_rng(seed)

    @property
    def angles_rad(self) -> FloatArray:
        """(N,) transducer bearings in the robot frame [rad], increasing by 2 pi / N (unwrapped)."""
        return self._angles

    @property
    def ray_offsets_rad(self) -> FloatArray:
        """(K,) ray directions within a cone relative to its axis [rad]."""
        return self._offsets.copy()

    @property
    def angle_increment_rad(self) -> float:
        """Bearing step between neighbouring transducers [rad]."""
        return 2.0 * math.pi / int(self.config.num_transducers)

    def scan_limits_m(self) -> tuple[float, float]:
        """(range_min, range_max) of reported ranges, measured from the robot centre [m]."""
        c = self.config
        return c.range_min_m + c.ring_radius_m, c.range_max_m + c.ring_radius_m

    def scan(
        self, world: RayCaster, pose: Pose2D, rng: np.random.Generator | None = None
    ) -> FloatArray:
        """(N,) ranges from the robot centre [m] at `pose` in `world`; `inf` = no echo."""
        return self.scan_many(world, pose.as_array()[None, :], rng)[0]

    def scan_many(
        self, world: RayCaster, poses: npt.ArrayLike, rng: np.random.Generator | None = None
    ) -> FloatArray:
        """(P, N) ranges from the robot centre [m] at poses (P, 3) rows (x [m], y [m], theta [rad]).

        All P * N * K rays go to the world's ray caster in one call.
        """
        p = np.asarray(poses, dtype=np.float64)
        if p.ndim == 1 and p.shape[0] == 3:
            p = p[None, :]
        if p.ndim != 2 or p.shape[1] != 3:
            raise SonarError(f"scan_many: poses must be a (P, 3) array, got shape {p.shape}")
        if not np.all(np.isfinite(p)):
            raise SonarError("scan_many: poses contain a NaN or infinite value")
        c = self.config
        n, k, npose = self._angles.shape[0], self._offsets.shape[0], p.shape[0]
        if npose == 0:
            return np.zeros((0, n))
        axis = p[:, 2:3] + self._angles[None, :]  # (P, N) world bearing of each transducer axis
        ox = p[:, 0:1] + c.ring_radius_m * np.cos(axis)
        oy = p[:, 1:2] + c.ring_radius_m * np.sin(axis)
        ray_ang = axis[:, :, None] + self._offsets[None, None, :]  # (P, N, K)
        origins = np.stack(
            [np.repeat(ox.reshape(-1), k), np.repeat(oy.reshape(-1), k)], axis=1
        )  # (P*N*K, 2)
        hits = world.raycast(origins, ray_ang.reshape(-1), c.range_max_m)
        d = hits.distance_m.reshape(npose, n, k)
        valid = np.isfinite(d) & (d >= c.range_min_m) & (d <= c.range_max_m)
        if not c.ideal:
            valid &= hits.cos_incidence.reshape(npose, n, k) >= self._cos_reflect - 1e-12
        echo = np.where(valid, d, np.inf).min(axis=2)  # (P, N) first echo per transducer
        if not c.ideal and c.noise_std_m > 0:
            gen = rng if rng is not None else self._rng
            noise = gen.normal(0.0, c.noise_std_m, size=echo.shape)
            echo = np.where(np.isfinite(echo), echo + noise, np.inf)
            echo = np.where((echo >= c.range_min_m) & (echo <= c.range_max_m), echo, np.inf)
        return np.where(np.isfinite(echo), echo + c.ring_radius_m, np.inf)

