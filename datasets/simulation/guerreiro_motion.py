"""The motion of the ``guerreiro-loop`` scenario (also driven by ``sim:laser2d``): the 60 m
path round the ring corridor and its speed profiles (sinusoidal or a seeded random walk),
with an optional lateral drift."""

from __future__ import annotations

import numpy as np

from datasets.simulation.floor_plan import ring_corridor_building
from datasets.simulation.trajectories import (
    LateralDrift,
    PlanarPathMotion,
    RandomSpeed,
    RoundedPolylinePath,
    SinusoidalSpeed,
)

LOOP_PATH_LENGTH_M = 60.0
LOOP_TURN_LENGTH_M = 3.0


def guerreiro_loop_motion(
    mean_speed_m_s: float,
    speed_walk_m_s_sqrt_s: float | None = None,
    rng: np.random.Generator | None = None,
    speed_reversion_s: float | None = 5.0,
    profile_s: float | None = None,
    lateral_walk_m_s_sqrt_s: float = 0.0,
    drift_rng: np.random.Generator | None = None,
) -> PlanarPathMotion:
    """The loop of Guerreiro et al. (2013) section V: start in the middle of the bottom
    corridor heading east, go counterclockwise round the ring corridor and on past the start
    until the path is 60 m long; corners rounded; speed 0.4 m/s on average, varying +-30 %
    in five smooth cycles, or, given ``speed_walk_m_s_sqrt_s`` and ``rng``, a random speed
    (``RandomSpeed``) with that density."""
    plan = ring_corridor_building()
    (x0, y0), (x1, _), (_, y1), _ = plan.corridor_centerline
    start = np.array([(x0 + x1) / 2, y0])
    vertices = [start, [x1, y0], [x1, y1], [x0, y1], [x0, y0]]
    lap = RoundedPolylinePath(np.array(vertices + [start]), LOOP_TURN_LENGTH_M)
    beyond = LOOP_PATH_LENGTH_M - lap.length_m
    path = RoundedPolylinePath(np.array(vertices + [start + [beyond, 0.0]]), LOOP_TURN_LENGTH_M)
    duration = path.length_m / mean_speed_m_s
    if profile_s is not None:
        duration = min(duration, profile_s)  # a pure random walk: drawn only as far as needed
    drift = None
    if lateral_walk_m_s_sqrt_s > 0.0:
        if drift_rng is None:
            raise ValueError("a lateral drift needs a generator")
        drift = LateralDrift(lateral_walk_m_s_sqrt_s, duration, drift_rng)
    if speed_walk_m_s_sqrt_s is None:
        return PlanarPathMotion(path, SinusoidalSpeed(mean_speed_m_s, 0.3, 5, duration), drift)
    if rng is None:
        raise ValueError("a random speed profile needs a generator")
    return PlanarPathMotion(
        path,
        RandomSpeed(mean_speed_m_s, speed_walk_m_s_sqrt_s, duration, rng, speed_reversion_s),
        drift,
    )
