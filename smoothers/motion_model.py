"""``MotionModel``: what a keyframe smoother asks of its motion model, whichever it is
(``imu_graph.ImuMotion``: IMU preintegration; ``planar_graph.PlanarMotion``: planar
odometry or gyro; ``spatial_odometry.SpatialOdometryMotion``: 3-D relative poses).

The smoother, its fixed-lag exports, its smoothed output and the initial guesses all talk
to the model through this protocol, so none of them imports a concrete model and the models
import nothing of theirs (the priors they need live in ``smoothers.priors``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

import gtsam

from datasets.estimate import EstimateRecorder
from datasets.measurements import Measurement
from datasets.sequence import InitialState

if TYPE_CHECKING:
    from smoothers.covariances import MarginalSource
    from smoothers.priors import InitialPriors


class MotionModel(Protocol):
    """The motion between keyframes, as factors over each keyframe's state keys."""

    def keys(self, k: int) -> list[int]:
        """The state keys of keyframe ``k`` (pose first)."""

    def pose_key(self, k: int) -> int:
        """The pose key of keyframe ``k``."""

    def accepts(self, measurement: object) -> bool:
        """Whether ``measurement`` is this model's motion input."""

    def look_ahead(self, measurement: Measurement) -> None:
        """The next motion sample, seen before a keyframe closes at an earlier time."""

    def add(self, measurement: Measurement) -> bool:
        """Take one motion sample; False when it was not used (a repeated time stamp)."""

    def since_keyframe(self) -> int:
        """Motion samples taken since the last keyframe."""

    def initial(
        self, start: InitialState, priors: InitialPriors
    ) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
        """Keyframe 0's priors and values."""

    def close(
        self, k: int, t: float, estimate: gtsam.Values
    ) -> tuple[gtsam.NonlinearFactorGraph, gtsam.Values]:
        """The factors from keyframe ``k - 1`` to ``k`` at ``t`` [s] and ``k``'s initial values."""

    def dead_reckoning_step(self, k: int, values: gtsam.Values) -> gtsam.Values:
        """Keyframe ``k``'s state predicted from ``k - 1``'s in ``values`` by the motion alone."""

    def restart(self, t: float, estimate: gtsam.Values, k: int) -> None:
        """Start the motion after keyframe ``k`` at ``t`` [s] from its estimate."""

    def pose_of(self, values: gtsam.Values, k: int) -> gtsam.Pose2 | gtsam.Pose3:
        """Keyframe ``k``'s pose in ``values``."""

    def record(
        self,
        recorder: EstimateRecorder,
        t: float,
        values: gtsam.Values,
        k: int,
        marginals: MarginalSource | None,
    ) -> None:
        """Record keyframe ``k``'s state (and covariances from ``marginals``) at ``t`` [s]."""
