"""The algebra of control strategies (paper Table 1): normalize, reverse, ideal displacement."""

from __future__ import annotations

from island_msgs_py.types import ControlStrategy, Pose2D, PrimitiveKind, StrategyPrimitive

TURN_AROUND_DEG = 180  # the reverse of a strategy starts and ends with a half turn
FULL_TURN_DEG = 360


def normalize_strategy(strategy: ControlStrategy) -> ControlStrategy:
    """Drop Go 0 and Rot 0, merge consecutive rotations (mod 360) and consecutive Go steps."""
    steps: list[StrategyPrimitive] = []
    for s in strategy.steps:
        if s.value == 0:
            continue
        if steps and steps[-1].kind is s.kind:
            value = steps.pop().value + s.value
            if s.kind is PrimitiveKind.ROT:
                value %= FULL_TURN_DEG
            if value == 0:
                continue
            s = StrategyPrimitive(s.kind, value)
        steps.append(s)
    return ControlStrategy(tuple(steps))


def reverse_strategy(strategy: ControlStrategy) -> ControlStrategy:
    """The strategy that drives back from the target origin (heading 0) to the source origin.

    Turn around (Rot 180), replay the steps in reverse order with Go unchanged and every
    Rot a replaced by Rot (360 - a) % 360, then turn around again (Rot 180) so the robot faces
    the source frame's heading 0. Adjacent rotations are merged (`normalize_strategy`), so
    reversing twice gives back the normalized strategy.
    """
    turn = StrategyPrimitive(PrimitiveKind.ROT, TURN_AROUND_DEG)
    mirrored = [
        StrategyPrimitive(
            s.kind,
            (FULL_TURN_DEG - s.value) % FULL_TURN_DEG if s.kind is PrimitiveKind.ROT else s.value,
        )
        for s in reversed(strategy.steps)
    ]
    return normalize_strategy(ControlStrategy((turn, *mirrored, turn)))


def strategy_displacement(strategy: ControlStrategy) -> Pose2D:
    """Where the strategy ends, in the frame it starts from (ideal execution) [m, rad]."""
    pose = Pose2D(0.0, 0.0, 0.0)
    for s in strategy.steps:
        pose = pose.compose(Pose2D(s.metres, 0.0, s.radians))
    return pose
