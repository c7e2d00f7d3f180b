"""Optional 3-D relative-pose factors from lidar odometry (``Odometry.relative_pose`` 6-D).

Each increment is (rotation vector [rad], translation [m]) of the current body frame in the
previous one, with covariance in the same order: GTSAM's Pose3 tangent [omega, v] (right
perturbation), so it is used as is. Increments are composed between keyframes (right
perturbation: ``Sigma_ac = Ad(T_bc^-1) Sigma_ab Ad(T_bc^-1)^T + Sigma_bc``) into one
``BetweenFactorPose3`` per keyframe interval. An increment belongs to the interval in which
it ends (keyframes are committed only after the stream has passed their time, so an
increment ending at a keyframe's time is in).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from datasets.errors import InputError
from datasets.measurements import Odometry


@dataclass
class RelativePoseAccumulator:
    """Composes 6-D relative-pose odometry between keyframes."""

    increment: gtsam.Pose3 = field(default_factory=gtsam.Pose3)
    covariance: np.ndarray = field(default_factory=lambda: np.zeros((6, 6)))
    count: int = 0

    def start(self) -> None:
        self.increment = gtsam.Pose3()
        self.covariance = np.zeros((6, 6))
        self.count = 0

    def add(self, odometry: Odometry) -> None:
        if odometry.relative_pose is None:
            return  # a 3-D velocity is not used by the smoother
        values = np.asarray(odometry.relative_pose, dtype=float)
        covariance = np.asarray(odometry.covariance, dtype=float)
        if (
            values.shape != (6,)
            or covariance.shape != (6, 6)
            or not (np.all(np.isfinite(values)) and np.all(np.isfinite(covariance)))
        ):
            raise InputError(
                f"odometry at t={odometry.t:.6f} s: expected a finite 6-D relative pose with a (6, 6) covariance"
            )
        delta = gtsam.Pose3(gtsam.Rot3.Expmap(values[:3]), values[3:])
        adjoint = delta.inverse().AdjointMap()
        composed = adjoint @ self.covariance @ adjoint.T + covariance
        self.increment = self.increment.compose(delta)
        self.covariance = 0.5 * (composed + composed.T)
        self.count += 1

    def factor(self, previous_key: int, key: int) -> gtsam.NonlinearFactor | None:
        """The composed ``BetweenFactorPose3``, or None when no increment arrived."""
        if self.count == 0:
            return None
        noise = gtsam.noiseModel.Gaussian.Covariance(self.covariance + np.eye(6) * 1e-12)
        return gtsam.BetweenFactorPose3(previous_key, key, self.increment, noise)
