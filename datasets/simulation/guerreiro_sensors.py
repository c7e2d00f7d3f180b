"""The sensors of the ``guerreiro-loop`` scenario beyond its rate gyro: the laser's scans of
the wall corners (line of sight, optional wall directions) and the relative-pose wheel
odometry (``odometry=true``, not in the paper)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from datasets.rotations import wrap_angle
from datasets.simulation.assembly import OdometrySeries
from datasets.simulation.floor_plan import FloorPlan
from datasets.simulation.landmarks import (
    RangeBearingNoise,
    ScanSeries,
    field_of_view_mask,
    line_of_sight_mask,
    planar_direction_observations,
    range_bearing_observations,
    to_body_frame,
)
from datasets.simulation.trajectories import Kinematics

if TYPE_CHECKING:
    from datasets.simulation.guerreiro_loop import GuerreiroLoopOptions


def corner_scans(
    plan: FloorPlan,
    scan_times: np.ndarray,
    scan_kinematics: Kinematics,
    laser: RangeBearingNoise,
    options: GuerreiroLoopOptions,
    drawn: float,
    stated: float,
    rng: np.random.Generator,
    direction_rng: np.random.Generator,
) -> tuple[ScanSeries, np.ndarray | None]:
    """The laser's scans of the building's wall corners at ``scan_times``: every corner
    within range and field of view and in line of sight (walls occlude), its noise drawn
    from ``rng`` with ``laser``'s sigmas (``options.landmark_noise``,
    ``options.landmark_conversion``); with ``options.directions`` also each seen corner's
    two wall directions in the body frame, their noise drawn from ``direction_rng``. Returns
    the scans and the mask of the corners the first scan sees (None without scans)."""
    points, covariances, ids, directions = [], [], [], []
    visible_at_start = None
    for index in range(len(scan_times)):
        position, rotation = scan_kinematics.position[index], scan_kinematics.rotation[index]
        body = to_body_frame(rotation, position, plan.corners)
        mask = field_of_view_mask(body, options.range_m, options.fov_deg)
        mask &= line_of_sight_mask(position, plan.corners, plan.walls)
        if index == 0:
            visible_at_start = mask
        visible = np.flatnonzero(mask)
        measured, covariance = range_bearing_observations(
            body[visible],
            laser,
            drawn,
            stated,
            rng,
            options.landmark_noise,
            options.landmark_conversion,
        )
        points.append(measured)
        covariances.append(covariance)
        ids.append(visible.astype(int))
        if options.directions:
            body_directions = plan.corner_directions[visible] @ rotation  # R^T u for each direction
            directions.append(
                planar_direction_observations(
                    body_directions, np.deg2rad(options.direction_sigma_deg), drawn, direction_rng
                )
            )
    scans = ScanSeries(
        t=scan_times,
        points=tuple(points),
        covariances=tuple(covariances),
        ids=tuple(ids),
        directions=tuple(directions) if options.directions else None,
    )
    return scans, visible_at_start


def relative_pose_odometry(
    kinematics: Kinematics,
    sigmas: np.ndarray,
    drawn: float,
    stated: float,
    rng: np.random.Generator,
) -> OdometrySeries:
    """Planar relative-pose odometry between consecutive truth samples: the true
    ``(dx, dy) = R_k^T (p_{k+1} - p_k)``, ``dtheta = theta_{k+1} - theta_k`` plus white noise
    of std ``sigmas * drawn`` (dx, dy, dtheta), stated as ``diag(sigmas * stated)^2``. The
    estimators compose ``p' = p + R u_xy``, ``theta' = theta + u_theta``, which is linear in
    the increment: the noise model is exactly theirs."""
    rotation = kinematics.rotation
    steps = np.einsum("kji,kj->ki", rotation[:-1], np.diff(kinematics.position, axis=0))
    headings = np.arctan2(rotation[:, 1, 0], rotation[:, 0, 0])
    turns = wrap_angle(np.diff(headings))
    true = np.column_stack([steps, turns])
    measured = true + rng.standard_normal(true.shape) * (np.asarray(sigmas) * drawn)
    return OdometrySeries(
        t=kinematics.t[1:].copy(),
        dt=np.diff(kinematics.t),
        increments=measured,
        covariance=np.diag((np.asarray(sigmas, float) * stated) ** 2),
    )
