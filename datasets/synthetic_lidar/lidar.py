"""A spinning multi-beam lidar ray-caster (16 or 32 beams) with per-point times.

The sensor sweeps azimuth columns at a constant rate; all beams of a column fire together at
the column's time, from the sensor pose at that time (so a moving sensor produces the skew
that deskewing undoes). A point is reported in the sensor frame of its own firing time, as a
real lidar does: ``p = range * beam_direction``. Misses (nothing within range) are NaN in the
organized (beams x columns) cloud.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from datasets.synthetic_lidar.path import LoopPath
from datasets.synthetic_lidar.world import World


class LidarModel(BaseModel):
    """Spinning lidar parameters."""

    model_config = ConfigDict(extra="forbid")

    beams: int = Field(
        16,
        description="number of beams: 16 (-15..15 deg, 2 deg apart) or 32 (-22..9 deg, 1 deg apart)",
    )
    columns: int = Field(1800, ge=16, description="azimuth columns per revolution")
    rate_hz: float = Field(10.0, gt=0, description="revolutions per second")
    max_range_m: float = Field(40.0, gt=0, description="farthest return [m]")
    min_range_m: float = Field(0.3, ge=0, description="nearest return [m]")
    range_sigma_m: float = Field(0.01, ge=0, description="range noise std [m]")
    height_m: float = Field(1.0, gt=0, description="sensor height above the floor [m]")

    def elevations_rad(self) -> np.ndarray:
        if self.beams == 16:
            return np.deg2rad(np.linspace(-15.0, 15.0, 16))
        if self.beams == 32:
            return np.deg2rad(np.linspace(-22.0, 9.0, 32))
        raise ValueError(f"beams must be 16 or 32, got {self.beams}")


@dataclass(frozen=True)
class Sweep:
    """One revolution.

    Attributes:
        t0: time of the first column [s].
        points: sensor-frame points (beams, columns, 3) [m], NaN where nothing was hit.
        column_times: time offsets of the columns from ``t0`` (columns,) [s].
        ring: beam index (beams,).
    """

    t0: float
    points: np.ndarray
    column_times: np.ndarray
    ring: np.ndarray


def cast_rays(
    world: World, origins: np.ndarray, directions: np.ndarray, max_range_m: float
) -> np.ndarray:
    """Distance along each unit ray to the first wall or floor hit, inf if none within range.

    Args:
        origins: (R, 3) [m], above the floor.
        directions: (R, 3) unit vectors.

    Returns:
        (R,) distances [m].
    """
    o_xy, d_xy = origins[:, None, :2], directions[:, None, :2]
    start, edge = world.wall_start[None], (world.wall_end - world.wall_start)[None]
    denominator = d_xy[..., 0] * edge[..., 1] - d_xy[..., 1] * edge[..., 0]
    offset = start - o_xy
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = (offset[..., 0] * edge[..., 1] - offset[..., 1] * edge[..., 0]) / denominator
        mu = (offset[..., 0] * d_xy[..., 1] - offset[..., 1] * d_xy[..., 0]) / denominator
        z = origins[:, None, 2] + lam * directions[:, None, 2]
    valid = (
        (np.abs(denominator) > 1e-12)
        & (lam > 0)
        & (mu >= 0)
        & (mu <= 1)
        & (z >= 0)
        & (z <= world.wall_height[None])
    )
    wall = np.where(valid, lam, np.inf).min(axis=1)
    with np.errstate(divide="ignore"):
        floor = np.where(directions[:, 2] < 0, -origins[:, 2] / directions[:, 2], np.inf)
    distance = np.minimum(wall, floor)
    return np.where(distance <= max_range_m, distance, np.inf)


def sweep(
    world: World,
    path: LoopPath,
    model: LidarModel,
    t0: float,
    rng: np.random.Generator,
    chunk_columns: int = 256,
) -> Sweep:
    """Ray-cast one revolution starting at ``t0`` [s] (columns from azimuth -pi, CCW)."""
    elevations = model.elevations_rad()
    azimuths = -np.pi + 2.0 * np.pi * np.arange(model.columns) / model.columns
    column_times = np.arange(model.columns) / (model.columns * model.rate_hz)
    beam_dirs = np.stack(
        np.broadcast_arrays(
            np.cos(elevations)[:, None] * np.cos(azimuths)[None],
            np.cos(elevations)[:, None] * np.sin(azimuths)[None],
            np.sin(elevations)[:, None],
        ),
        axis=-1,
    )  # (beams, columns, 3) sensor frame
    motion = path.sample(t0 + column_times)
    distances = np.empty((len(elevations), model.columns))
    for first in range(0, model.columns, chunk_columns):
        cols = slice(first, first + chunk_columns)
        yaw = motion.yaw[cols]
        c, s = np.cos(yaw)[None, :], np.sin(yaw)[None, :]
        local = beam_dirs[:, cols]
        world_dirs = np.stack(
            [
                c * local[..., 0] - s * local[..., 1],
                s * local[..., 0] + c * local[..., 1],
                local[..., 2],
            ],
            axis=-1,
        )
        origin = np.column_stack([motion.position[cols], np.full(yaw.shape[0], model.height_m)])
        origins = np.broadcast_to(origin[None], world_dirs.shape)
        distances[:, cols] = cast_rays(
            world, origins.reshape(-1, 3), world_dirs.reshape(-1, 3), model.max_range_m
        ).reshape(len(elevations), -1)
    noisy = distances + rng.normal(0.0, model.range_sigma_m, distances.shape)
    hit = np.isfinite(distances) & (noisy >= model.min_range_m)
    points = np.where(hit, noisy, np.nan)[..., None] * beam_dirs
    return Sweep(t0=t0, points=points, column_times=column_times, ring=np.arange(len(elevations)))
