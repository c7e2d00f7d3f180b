"""The ``aghili-rover`` scenario: its options, the case study world of Aghili's paper
(terrain and via points) and its builder."""

from __future__ import annotations

import numpy as np
from pydantic import Field

from datasets.errors import InputError
from datasets.sequence import Sequence
from datasets.simulation.scenario_common import duration_text
from datasets.simulation.spatial_scenario import SpatialOptions, simulate_spatial
from datasets.simulation.trajectories import Terrain, TerrainViaPointLoop


class AghiliRoverOptions(SpatialOptions):
    imu_rate_hz: float = Field(20.0, gt=0, le=10000, description="IMU rate [Hz] (paper: 20 Hz)")
    speed_m_s: float = Field(1.0, gt=0, le=5, description="cruise speed along the via points [m/s]")
    landmark_count: int = Field(
        60, ge=3, le=10000, description="landmarks scattered over the terrain"
    )
    landmark_sigma_min_m: float = Field(
        0.1, ge=0, description="smallest per-landmark noise sigma [m]"
    )
    landmark_sigma_max_m: float = Field(
        0.25, ge=0, description="largest per-landmark noise sigma [m]"
    )


# The Aghili case study world: a 30 x 60 m terrain (x across, y along) and seven via points.
ROVER_VIA_POINTS_XY = np.array(
    [[4.0, 4.0], [25.0, 6.0], [26.0, 24.0], [14.0, 32.0], [25.0, 51.0], [10.0, 56.0], [4.0, 31.0]]
)
ROVER_TERRAIN = Terrain(
    amplitudes_m=np.array([1.5, 0.7, 0.3]),
    wave_vectors=2 * np.pi * np.array([[1 / 60, 1 / 90], [-1 / 40, 1 / 45], [1 / 25, 1 / 20]]),
    phases_rad=np.array([0.4, 1.3, 2.2]),
)
TERRAIN_SIZE_M = (30.0, 60.0)


def aghili_rover(seed: int, options: AghiliRoverOptions) -> Sequence:
    """Aghili, "Lidar SLAM for Autonomous Driving Vehicles", section 5 case study: a rover
    at walking pace drives a closed loop through seven via points over a 30 x 60 m terrain
    with gentle slopes (heights within a few metres; pitch and roll follow the slope); IMU
    at 20 Hz with KITTI-equivalent sigmas (gtsam Data, the paper states none); landmarks
    scattered over the terrain (0.1..3 m above ground), observed as 3-D body-frame positions
    within range and field of view, each with its own sigma uniform in [0.1, 0.25] m (the
    paper's 0.1 < sigma_pi < 0.25), scan covariance sigma_i^2 I. Default duration: one lap.
    """
    if options.landmark_sigma_max_m < options.landmark_sigma_min_m:
        raise InputError("sim:aghili-rover: landmark_sigma_max_m must be >= landmark_sigma_min_m")
    motion = TerrainViaPointLoop(ROVER_VIA_POINTS_XY, options.speed_m_s, ROVER_TERRAIN)
    layout = np.random.default_rng([options.layout_seed, 1])
    width, length = TERRAIN_SIZE_M
    xy = layout.uniform([0.0, 0.0], [width, length], size=(options.landmark_count, 2))
    heights = ROVER_TERRAIN.height(xy) + layout.uniform(0.1, 3.0, size=options.landmark_count)
    sigmas = layout.uniform(
        options.landmark_sigma_min_m, options.landmark_sigma_max_m, size=options.landmark_count
    )
    duration = options.duration_s if options.duration_s is not None else motion.period_s
    return simulate_spatial(
        "aghili-rover",
        motion,
        duration,
        np.column_stack([xy, heights]),
        sigmas,
        options,
        seed,
        duration_text(options, duration, f"one lap at speed_m_s={options.speed_m_s:g}"),
        landmark_sigmas_m=[float(value) for value in sigmas],
        lap_duration_s=float(motion.period_s),
    )
