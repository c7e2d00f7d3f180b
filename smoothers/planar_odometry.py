"""Planar odometry composed between keyframes: ``Odometry.relative_pose`` (dx, dy, dtheta)
or ``Odometry.velocity`` (v_forward, omega) into one relative ``Pose2`` with its covariance,
for the ``BetweenFactorPose2`` of ``smoothers.planar_graph.PlanarMotion``.

Increments are composed with the right-perturbation covariance
(``Sigma_ac = Ad(b^-1) Sigma_ab Ad(b^-1)^T + Sigma_bc``). A velocity sample is held
(zero-order hold) until the next one; its covariance is the error of the held velocity, so
the increment over ``dt`` has covariance ``J Sigma J^T`` with ``J = [[dt, 0], [0, 0],
[0, dt]]`` plus a lateral-slip floor ``odometry_lateral_sigma_m_s^2 dt^2`` (a unicycle
cannot move sideways, a real one slips a little, and a zero row would make the factor
degenerate).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import gtsam
import numpy as np

from datasets.errors import InputError
from datasets.measurements import Odometry


def compose_increment(
    first: gtsam.Pose2, first_cov: np.ndarray, second: gtsam.Pose2, second_cov: np.ndarray
) -> tuple[gtsam.Pose2, np.ndarray]:
    """``first * second`` with its covariance in the right-perturbation tangent [x, y, theta]."""
    adjoint = second.inverse().AdjointMap()
    covariance = adjoint @ first_cov @ adjoint.T + second_cov
    return first.compose(second), 0.5 * (covariance + covariance.T)


@dataclass
class OdometryAccumulator:
    """Composes odometry between keyframes into one relative pose with covariance.

    Attributes:
        lateral_sigma_m_s: lateral-slip floor for velocity odometry [m/s].
        max_gap_s: a velocity hold longer than this is an ``InputError``.
    """

    lateral_sigma_m_s: float
    max_gap_s: float
    increment: gtsam.Pose2 = field(default_factory=gtsam.Pose2)
    covariance: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    cursor: float = 0.0
    held: Odometry | None = None
    count: int = 0

    def start(self, t: float) -> None:
        self.increment = gtsam.Pose2()
        self.covariance = np.zeros((3, 3))
        self.cursor = float(t)
        self.count = 0

    def _append(self, delta: gtsam.Pose2, covariance: np.ndarray) -> None:
        self.increment, self.covariance = compose_increment(
            self.increment, self.covariance, delta, covariance
        )
        self.count += 1

    def _integrate_velocity_until(self, t: float) -> None:
        if self.held is None or self.held.velocity is None:
            return
        dt = t - self.cursor
        if dt <= 0.0:
            return
        if t - self.held.t > self.max_gap_s:
            raise InputError(
                f"odometry gap: no sample between t={self.held.t:.6f} s and t={t:.6f} s (max gap {self.max_gap_s} s)"
            )
        v, omega = float(self.held.velocity[0]), float(self.held.velocity[1])
        jacobian = np.array([[dt, 0.0], [0.0, 0.0], [0.0, dt]])
        covariance = jacobian @ np.asarray(self.held.covariance, dtype=float)[:2, :2] @ jacobian.T
        covariance[1, 1] += (self.lateral_sigma_m_s * dt) ** 2
        self._append(gtsam.Pose2.Expmap(np.array([v * dt, 0.0, omega * dt])), covariance)
        self.cursor = t

    def add(self, odometry: Odometry) -> None:
        if odometry.relative_pose is not None:
            dx, dy, dtheta = np.asarray(odometry.relative_pose, dtype=float)[:3]
            covariance = np.asarray(odometry.covariance, dtype=float)[:3, :3]
            self._append(gtsam.Pose2(dx, dy, dtheta), covariance)
            self.cursor = odometry.t
            return
        if odometry.velocity is None:
            raise InputError(
                f"odometry at t={odometry.t:.6f} s has neither a relative pose nor a velocity"
            )
        self._integrate_velocity_until(odometry.t)
        self.held = odometry
        self.cursor = max(self.cursor, odometry.t)

    def close(self, t: float) -> tuple[gtsam.Pose2, np.ndarray]:
        """The composed increment since the last keyframe, up to ``t``."""
        self._integrate_velocity_until(t)
        if self.count == 0:
            raise InputError(f"keyframe at t={t:.6f} s: no odometry since the previous keyframe")
        return self.increment, self.covariance
