"""Odometry as an input of the sensor-based filter: an extension beyond Guerreiro et al.
(2013), whose filter takes a rate gyro and landmarks only.

Two uses, each optional: without a gyro, the rate input over an odometry increment is the
increment's rotation over its duration (``odometry_rate``; the Earth-frame fallback then
carries the increment itself, ``odometry_increment``); with config ``use_odometry``, the
sample is a measurement of the body velocity ``v`` (``odometry_velocity``, a selection of the
state: ``velocity_update``). ``odometry_interval`` is the interval both
take a sample over.
"""

from __future__ import annotations

import numpy as np

from datasets.estimate import EstimateRecorder
from datasets.measurements import Odometry
from datasets.odometry_noise import OdometryNoiseModel
from datasets.rotations import rot2, so3_exp
from filters.sensor_based.state import FilterState
from filters.sensor_based.update import selection_update

ODOMETRY_RATE_BIAS_SIGMA_RAD_S = 1e-4
"""Prior std of the gyro-bias state when the rate comes from odometry (it has no bias; the
state stays so that the model is the paper's) [rad/s]."""


def odometry_interval(odometry: Odometry, previous_t: float | None) -> float:
    """An odometry sample's interval [s]: its own ``dt``, else the time since the previous
    sample (0 for the first: ``previous_t`` None). A previous time of 0.0 is a time like any
    other (a run starting at t = 0 once lost its first increment here)."""
    if odometry.dt is not None:
        return odometry.dt
    return 0.0 if previous_t is None else odometry.t - previous_t


def odometry_rate(odometry: Odometry, dt: float, dimension: int) -> tuple[np.ndarray, float] | None:
    """Without a gyro, the rate input over an odometry increment is its rotation over
    its duration (``log(dR) / dt``, held over the increment), and the white noise the
    model injects through ``G`` is the increment's rotation variance over ``dt``
    (a rate error of covariance ``Sigma_w / dt^2`` held for ``dt`` is a density
    ``Sigma_w / dt``). An extension beyond the paper, which assumes a rate gyro.

    Returns:
        (rate (r,), squared noise density), or None for a relative pose over no interval.
    """
    covariance = np.asarray(odometry.covariance, dtype=float)
    if odometry.relative_pose is not None:
        if not dt or dt <= 0.0:
            return None
        pose = np.asarray(odometry.relative_pose, dtype=float)
        rotation = pose[2:3] if dimension == 2 else pose[0:3]
        rotation_cov = covariance[2:3, 2:3] if dimension == 2 else covariance[0:3, 0:3]
        rate = rotation / dt
        density_sq = float(np.mean(np.diag(rotation_cov))) / dt
    else:
        velocity = np.asarray(odometry.velocity, dtype=float)
        rate = velocity[1:2] if dimension == 2 else velocity[3:6]
        rate_cov = covariance[1:2, 1:2] if dimension == 2 else covariance[3:6, 3:6]
        density_sq = float(np.mean(np.diag(rate_cov))) * max(dt or 0.0, 0.0)
    return rate, density_sq


def odometry_increment(odometry: Odometry, dimension: int) -> tuple[np.ndarray, np.ndarray]:
    """(translation (d,), rotation (d, d)) of a relative-pose sample: the Earth-frame
    fallback's motion over the increment (the velocity state, still converging at the start,
    would lose the distance)."""
    pose = np.asarray(odometry.relative_pose, dtype=float)
    if dimension == 2:
        return pose[:2], rot2(float(pose[2]))
    return pose[3:6], so3_exp(pose[0:3])


def odometry_velocity(
    odometry: Odometry,
    previous_t: float | None,
    dimension: int,
    model: OdometryNoiseModel | None,
    lateral_sigma_m_s: float,
) -> tuple[np.ndarray | None, np.ndarray]:
    """Odometry as a measurement of the body velocity ``v``: (body velocity (d,), its
    covariance (d, d)) of a sample, or None when its interval is unknown (the first velocity
    sample). The sample's mean velocity over its interval is taken as the velocity at its
    time; relative poses give ``translation / dt``. The noise is the sample's own; a planar
    velocity sample's lateral variance comes from the dataset's odometry noise ``model``
    (else ``lateral_sigma_m_s``, config ``odometry_lateral_sigma_m_s``)."""
    d = dimension
    cov = np.asarray(odometry.covariance, dtype=float)
    if odometry.relative_pose is not None:
        dt = (
            odometry.dt
            if odometry.dt is not None
            else (odometry.t - previous_t if previous_t is not None else 0.0)
        )
        if not dt or dt <= 0:
            return None, cov
        pose = np.asarray(odometry.relative_pose, dtype=float)
        if d == 2:
            return pose[:2] / dt, cov[:2, :2] / dt**2
        return pose[3:6] / dt, cov[3:6, 3:6] / dt**2
    velocity = np.asarray(odometry.velocity, dtype=float)
    if d == 3:
        return velocity[:3], cov[:3, :3]
    if previous_t is None or odometry.t <= previous_t:
        return None, cov
    dt = odometry.t - previous_t
    lateral = (
        model.variances(np.array([dt]), abs(velocity[0]) * dt, abs(velocity[1]) * dt)[0, 1] / dt**2
        if model is not None
        else lateral_sigma_m_s**2
    )
    return np.array([velocity[0], 0.0]), np.diag([cov[0, 0], max(lateral, 1e-12)])


def velocity_update(
    state: FilterState,
    recorder: EstimateRecorder,
    t: float,
    measured: np.ndarray,
    covariance: np.ndarray,
) -> None:
    """The update with a body-velocity measurement (d,) of covariance (d, d), a selection of
    the state (``update.selection_update``). Its innovations are recorded apart
    (``extras['odometry_velocity_nis']``): the table's NIS stays the landmarks' one."""
    d = state.dimension
    velocity = state.registry.vehicle_indices(["velocity"])
    state.x, outcome = selection_update(
        state.x, state.covariance, velocity, measured, covariance, [np.arange(d)]
    )
    if outcome.innovation is not None:
        recorder.extra(
            "odometry_velocity_nis",
            [t, outcome.innovation.nis, outcome.innovation.dof],
        )
    if outcome.correction is None:
        recorder.event(t, "update_refused", reason=outcome.refused)
