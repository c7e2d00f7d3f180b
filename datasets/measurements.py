"""Measurement types: the vocabulary every source speaks and every estimator consumes.

All are frozen dataclasses with numpy arrays inside. Time ``t`` is float seconds (bags give
integer nanoseconds: loaders convert once). Vectors are in the body frame unless named
otherwise. A source yields them time-ordered through ``Sequence.measurements()``.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np


class Sensor(enum.StrEnum):
    """Kinds of measurement a sequence can provide and an estimator can need."""

    IMU = "imu"
    GYRO = "gyro"
    ODOMETRY = "odometry"
    GPS = "gps"
    LANDMARKS = "landmarks"
    POINT_CLOUD = "point_cloud"


@dataclass(frozen=True)
class ImuSample:
    """Strap-down IMU sample.

    Attributes:
        t: time [s].
        gyro: body angular rate [rad/s], shape (3,); measured = true + bias + noise.
        accel: specific force [m/s^2], shape (3,); at rest, z-up, reads (0, 0, +9.81).
    """

    t: float
    gyro: np.ndarray
    accel: np.ndarray
    sensor = Sensor.IMU


@dataclass(frozen=True)
class GyroSample:
    """Rate-gyro sample where only a rate is known.

    Attributes:
        t: time [s].
        rate: angular rate [rad/s]; shape (1,) in 2-D (about z), (3,) in 3-D.
    """

    t: float
    rate: np.ndarray
    sensor = Sensor.GYRO


@dataclass(frozen=True)
class Odometry:
    """Odometry: a relative pose since the previous sample, or a body velocity.

    Exactly one of ``relative_pose`` and ``velocity`` is set.

    Attributes:
        t: time [s] at the end of the increment (or of the velocity sample).
        relative_pose: 2-D (dx, dy, dtheta) in the previous body frame, shape (3,); or 3-D
            (rotation vector [rad], translation [m]) in the previous body frame, shape (6,).
        velocity: 2-D (v_forward [m/s], omega [rad/s]), shape (2,); 3-D (v[3], omega[3]).
        covariance: covariance of whichever is set, same order, shape (k, k).
        dt: duration of the increment [s] (for ``relative_pose``), else None.
        frame: the increment ends at a sensor frame (a lidar sweep the front end registered):
            the data expect a pose at ``t`` (``Estimate.frame_times``); False for wheel
            odometry, whose samples are motion input only.
    """

    t: float
    covariance: np.ndarray
    relative_pose: np.ndarray | None = None
    velocity: np.ndarray | None = None
    dt: float | None = None
    frame: bool = False
    sensor = Sensor.ODOMETRY


@dataclass(frozen=True)
class GpsFix:
    """Position fix in the world frame [m], shape (3,) (or (2,)), with covariance (d, d)."""

    t: float
    position: np.ndarray
    covariance: np.ndarray
    sensor = Sensor.GPS


@dataclass(frozen=True)
class LandmarkScan:
    """Landmarks observed at one time, as positions in the body frame.

    Attributes:
        t: time [s].
        points: body-frame positions [m], shape (k, d), ``p = R^T (rho - r)``.
        covariances: per-point measurement covariances [m^2], shape (k, d, d).
        ids: landmark ids, shape (k,) int, only when the source knows them (else None).
        directions: optional unit line directions in the body frame, shape (k, j, d)
            (corners with line segments; the sensor-based paper's direction landmarks).
    """

    t: float
    points: np.ndarray
    covariances: np.ndarray
    ids: np.ndarray | None = None
    directions: np.ndarray | None = None
    sensor = Sensor.LANDMARKS

    @property
    def count(self) -> int:
        """Number of landmarks in the scan."""
        return int(self.points.shape[0])


@dataclass(frozen=True)
class PointCloud:
    """Raw point cloud in the sensor (body) frame.

    Attributes:
        t: time of the scan [s] (the stamp of its message).
        points: positions [m], shape (n, 3).
        point_times: per-point time offsets [s] relative to ``t``, shape (n,), or None.
    """

    t: float
    points: np.ndarray
    point_times: np.ndarray | None = None
    sensor = Sensor.POINT_CLOUD


Measurement = ImuSample | GyroSample | Odometry | GpsFix | LandmarkScan | PointCloud
