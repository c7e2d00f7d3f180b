"""The ``circle`` and ``static`` scenarios: simple 3-D motions (a level circle, a vehicle
at rest) among scattered landmarks, each with its options and builder."""

from __future__ import annotations

import numpy as np
from pydantic import Field

from datasets.sequence import Sequence
from datasets.simulation.spatial_scenario import SpatialOptions, simulate_spatial
from datasets.simulation.trajectories import CircleMotion, StaticMotion


class CircleOptions(SpatialOptions):
    duration_s: float | None = Field(60.0, gt=0, description="length of the sequence [s]")
    radius_m: float = Field(10.0, gt=0, description="circle radius [m]")
    speed_m_s: float = Field(2.0, gt=0, description="constant speed [m/s]")
    landmark_count: int = Field(30, ge=3, le=10000, description="landmarks around the circle")
    landmark_sigma_m: float = Field(0.1, ge=0, description="landmark noise sigma [m]")


class StaticOptions(SpatialOptions):
    duration_s: float | None = Field(60.0, gt=0, description="length of the sequence [s]")
    landmark_count: int = Field(20, ge=3, le=10000, description="landmarks around the vehicle")
    landmark_sigma_m: float = Field(0.1, ge=0, description="landmark noise sigma [m]")


def circle(seed: int, options: CircleOptions) -> Sequence:
    """A level constant-speed circle (radius 10 m, 2 m/s) with landmarks scattered 4..18 m
    from the centre, 1 m below to 3 m above the path plane; IMU with KITTI-equivalent sigmas."""
    motion = CircleMotion(np.zeros(3), options.radius_m, options.speed_m_s)
    layout = np.random.default_rng([options.layout_seed, 2])
    angles = layout.uniform(0, 2 * np.pi, options.landmark_count)
    radii = options.radius_m * layout.uniform(0.4, 1.8, options.landmark_count)
    landmarks = np.column_stack(
        [
            radii * np.cos(angles),
            radii * np.sin(angles),
            layout.uniform(-1, 3, options.landmark_count),
        ]
    )
    sigmas = np.full(options.landmark_count, options.landmark_sigma_m)
    duration = float(options.duration_s)
    return simulate_spatial(
        "circle", motion, duration, landmarks, sigmas, options, seed, f"duration_s={duration:g}"
    )


def static(seed: int, options: StaticOptions) -> Sequence:
    """No motion: the vehicle rests at the origin, slightly tilted (yaw 30, pitch -3,
    roll 2 deg), with landmarks 3..15 m around it; IMU with KITTI-equivalent sigmas."""
    motion = StaticMotion(np.zeros(3), np.deg2rad(30.0), np.deg2rad(-3.0), np.deg2rad(2.0))
    layout = np.random.default_rng([options.layout_seed, 3])
    angles = layout.uniform(0, 2 * np.pi, options.landmark_count)
    radii = layout.uniform(3.0, 15.0, options.landmark_count)
    landmarks = np.column_stack(
        [
            radii * np.cos(angles),
            radii * np.sin(angles),
            layout.uniform(-1, 3, options.landmark_count),
        ]
    )
    sigmas = np.full(options.landmark_count, options.landmark_sigma_m)
    duration = float(options.duration_s)
    return simulate_spatial(
        "static", motion, duration, landmarks, sigmas, options, seed, f"duration_s={duration:g}"
    )
