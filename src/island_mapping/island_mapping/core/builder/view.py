"""The island builder's read-only view: what it has built and counted (`BuilderView`, the base
of `IslandBuilder`, core.builder.machine)."""

from __future__ import annotations

from island_msgs_py.types import Edge, Island, Pose2D

from island_mapping.core.builder.diagnostics import Diagnostics
from island_mapping.core.builder.epsilon import OdometryTrack
from island_mapping.core.builder.events import EventKind
from island_mapping.core.builder.ledger import Ledger


class BuilderView:
    """Queries of the builder's state (the machine sets these attributes)."""

    _track: OdometryTrack
    _path_m: float
    ledger: Ledger
    diagnostics: Diagnostics

    @property
    def epsilon_m(self) -> float:
        """The current epsilon [m] (see `RelativeCovariance`)."""
        return self._track.rel.epsilon_m

    @property
    def last_island(self) -> Island | None:
        return self.ledger.last_island

    @property
    def islands(self) -> list[Island]:
        """The islands built, in id order (the builder's own list)."""
        return self.ledger.islands

    @property
    def edges(self) -> list[Edge]:
        """The edges added (a cheaper revisit edge replaces its predecessor)."""
        return self.ledger.edges

    @property
    def island_origins_odom(self) -> dict[int, Pose2D]:
        """Each island's origin in the odometry frame when it was built."""
        return self.ledger.island_origins_odom

    @property
    def path_m(self) -> float:
        """Odometric path length followed (the hall follower driving) [m]."""
        return self._path_m

    @property
    def counts(self) -> dict[EventKind, int]:
        """Events emitted, by kind."""
        return self.diagnostics.counts

    @property
    def calibration(self) -> dict[str, float | int]:
        """The odometry calibration's estimate, sigmas and measurements used / refused."""
        return self.ledger.recognizer.calibration.summary()

    @property
    def revisit_refusals(self) -> dict[str, int]:
        """Why revisit hypotheses were refused: reason -> count."""
        return self.diagnostics.revisit_refusals

    @property
    def probes(self) -> dict[str, int]:
        """Origins past the star's legs: checked on the spot and kept, or fallen back from."""
        return self.diagnostics.probes
