"""``FrontEndReport``: what the lidar front end made of a recording, typed, on the ``Sequence``.

The front end (``datasets.lidar.frontend.LidarFrontEnd``) fills it frame by frame as it
registers the clouds, so after a pass over the sequence it holds the front end's own pose
trajectory (KISS-ICP's: world = the first body frame), the covariance it stated for each
frame-to-frame increment (the one the estimators were fed), and its counters. The front end
caches its frames, so a second pass (the next estimator) adds nothing: the report is the
same after every complete pass. Before the first pass it is empty.

Metrics read it (``workbench.metrics.frontend_agreement``: every estimate against the front
end's trajectory, the one reference a lidar-only run has). Estimators never see it: the
runner hands them a view of the sequence without it, as without its ground truth; the front
end's poses are not truth.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from datasets.trajectory import Trajectory, trajectory_from_homogeneous

if TYPE_CHECKING:
    from datasets.lidar.corner_tracking import ReobservationStats
    from datasets.lidar.increment_noise import IncrementNoise
    from datasets.lidar.motion_settling import MotionSettling


@dataclass
class FrontEndReport:
    """The front end's trajectory, increment covariances and counters after a pass.

    Attributes:
        name: the front end's odometry (``kiss-icp``).
        sole_motion_input: the front end's increments are the only motion input the
            sequence offers (no IMU, gyro or wheel odometry): every estimator that moves
            consumes them, which the departure check's covariance relies on
            (``workbench.metrics.frontend_agreement``). Set by the loader.
        frames: frames registered so far (with or without a pose).
        times: pose time of each frame [s] (the frame's odometry and corners share it).
        poses: (4, 4) body-to-world pose of each frame (world = the first body frame).
        increment_covariances: (6, 6) covariance [rotation, translation] (right
            perturbation, in the previous body frame) of the increment that ends at each
            frame, as fed to the estimators; None for the first frame.
        icp_seconds, corner_seconds: wall time of odometry and corners over all frames [s].
        corners_emitted: corners in the landmark scans the stream carries.
        untimed_frames: clouds without per-point times (read as motion-compensated).
        reobservation: the corner tracker's re-observation statistics (the corners' NIS
            against KISS-ICP's poses, ``datasets.lidar.corner_tracking``), or None.
        increment_noise: the covariance of KISS-ICP's increments in use at the last frame
            and the fit behind it (``datasets.lidar.increment_noise``), or None before a
            frame or without odometry.
        settling: KISS-ICP's warm-up (``datasets.lidar.motion_settling``: when the corners
            accepted its increments, how many were inflated before), or None without
            odometry.
    """

    name: str = "kiss-icp"
    sole_motion_input: bool = True
    times: list[float] = field(default_factory=list)
    poses: list[np.ndarray] = field(default_factory=list)
    increment_covariances: list[np.ndarray | None] = field(default_factory=list)
    frames: int = 0
    icp_seconds: float = 0.0
    corner_seconds: float = 0.0
    corners_emitted: int = 0
    untimed_frames: int = 0
    reobservation: ReobservationStats | None = None
    increment_noise: IncrementNoise | None = None
    settling: MotionSettling | None = None

    def add_frame(
        self,
        t: float,
        pose: np.ndarray | None,
        increment_covariance: np.ndarray | None,
        icp_seconds: float,
        corner_seconds: float,
        corners: int,
        untimed: bool,
    ) -> None:
        """Record one frame (``LidarFrontEnd.frame`` calls it once per new frame). A frame
        without a pose (odometry off) adds to the counters only."""
        self.icp_seconds += icp_seconds
        self.corner_seconds += corner_seconds
        self.corners_emitted += corners
        self.untimed_frames += bool(untimed)
        self.frames += 1
        if pose is None:
            return
        self.times.append(float(t))
        self.poses.append(np.array(pose, dtype=float))
        self.increment_covariances.append(
            None if increment_covariance is None else np.array(increment_covariance, dtype=float)
        )

    def trajectory(self) -> Trajectory | None:
        """The front end's poses (world = the first body frame), or None before any."""
        if not self.poses:
            return None
        return trajectory_from_homogeneous(np.array(self.times), np.array(self.poses))

    def ms_per_frame(self) -> float | None:
        """Odometry and corners' wall time per frame [ms], None before any frame."""
        if not self.frames:
            return None
        return 1e3 * (self.icp_seconds + self.corner_seconds) / self.frames

    def reobservation_nis_per_dof(self) -> float | None:
        """Mean NIS per dof of the corners' re-observations (2 dof each), None without."""
        if self.reobservation is None:
            return None
        return self.reobservation.summary()["reobservation_nis_per_dof"]
