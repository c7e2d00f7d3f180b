"""3-D motion from relative poses alone (lidar odometry, no IMU): Pose3 keyframes joined by
``BetweenFactorPose3`` of the increments composed between them
(``smoothers.odometry_factors.RelativePoseAccumulator``: right-perturbation covariance
composition, GTSAM's [rotation, translation] order).

The lidar-only counterpart of ``smoothers.imu_graph.ImuMotion`` and of the planar odometry
of ``smoothers.planar_graph.PlanarMotion``: the same interface for the keyframe smoother.
A keyframe needs at least one increment ending in its interval: lidar odometry and corner
scans share the frame times, so a keyframe at a scan always has the frame's increment.
"""

from __future__ import annotations

import gtsam
import numpy as np
from gtsam.symbol_shorthand import X

from datasets.errors import InputError
from datasets.estimate import EstimateRecorder
from datasets.measurements import Odometry
from datasets.rotations import matrix_from_quat_wxyz, quat_wxyz_from_matrix
from datasets.sequence import InitialState
from smoothers.covariances import MarginalSource, pose_covariance
from smoothers.imu_graph import navstate_prior_sigmas
from smoothers.odometry_factors import RelativePoseAccumulator
from smoothers.priors import InitialPriors


class SpatialOdometryMotion:
    """Pose3 keyframes from 6-D relative-pose odometry (module docstring)."""

    dimension = 3

    def __init__(self) -> None:
        self.odometry = RelativePoseAccumulator()
        self.increments: dict[int, gtsam.Pose3] = {}

    @staticmethod
    def keys(k: int) -> list[int]:
        return [X(k)]

    @staticmethod
    def pose_key(k: int) -> int:
        return X(k)

    @staticmethod
    def accepts(measurement: object) -> bool:
        return isinstance(measurement, Odometry)

    def look_ahead(self, measurement: Odometry) -> None:
        """Increments are composed as they come; the next one is not needed."""

    def add(self, measurement: Odometry) -> bool:
        if measurement.relative_pose is None:
            raise InputError(
                f"odometry at t={measurement.t:.6f} s is a velocity; the 3-D smoother composes "
                "relative poses"
            )
        self.odometry.add(measurement)
        return True

    def initial(
        self, start: InitialState, priors: InitialPriors
    ) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
        """The pose of keyframe 0 at ``start.t`` with its prior."""
        pose = gtsam.Pose3(
            gtsam.Rot3(matrix_from_quat_wxyz(start.rotation)),
            np.asarray(start.position, dtype=float),
        )
        graph = gtsam.NonlinearFactorGraph()
        sigmas = navstate_prior_sigmas(priors.rotation_sigma_rad, priors.position_sigma_m)
        graph.add(gtsam.PriorFactorPose3(X(0), pose, gtsam.noiseModel.Diagonal.Sigmas(sigmas)))
        values = gtsam.Values()
        values.insert(X(0), pose)
        self.odometry.start()
        return graph, values

    def close(
        self, k: int, t: float, estimate: gtsam.Values
    ) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
        """The composed between factor of keyframe interval ``k - 1 -> k`` and the
        composed pose as its initial value."""
        factor = self.odometry.factor(X(k - 1), X(k))
        if factor is None:
            raise InputError(
                f"keyframe at t={t:.6f} s: no relative pose ended since the previous keyframe "
                "(lidar odometry and the scans must share the frame times)"
            )
        self.increments[k] = self.odometry.increment
        graph = gtsam.NonlinearFactorGraph()
        graph.add(factor)
        values = gtsam.Values()
        values.insert(X(k), estimate.atPose3(X(k - 1)).compose(self.odometry.increment))
        return graph, values

    def dead_reckoning_step(self, k: int, values: gtsam.Values) -> gtsam.Values:
        """Open-loop pose of keyframe ``k`` from ``k-1`` in ``values``."""
        step = gtsam.Values()
        step.insert(X(k), values.atPose3(X(k - 1)).compose(self.increments[k]))
        return step

    def restart(self, t: float, estimate: gtsam.Values, k: int) -> None:
        self.odometry.start()

    def since_keyframe(self) -> int:
        return self.odometry.count

    @staticmethod
    def pose_of(values: gtsam.Values, k: int) -> gtsam.Pose3:
        return values.atPose3(X(k))

    @staticmethod
    def record(
        recorder: EstimateRecorder,
        t: float,
        values: gtsam.Values,
        k: int,
        marginals: MarginalSource | None,
    ) -> None:
        """The pose of keyframe ``k`` in interface conventions (it is the whole state)."""
        pose = values.atPose3(X(k))
        pose_cov = (
            None if marginals is None else pose_covariance(marginals.marginalCovariance(X(k)))
        )
        recorder.pose(
            t, pose.translation(), quat_wxyz_from_matrix(pose.rotation().matrix()), pose_cov
        )
