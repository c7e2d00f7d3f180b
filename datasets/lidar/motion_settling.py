"""Warm-up: until the corners say KISS-ICP's motion has settled, its increments and the
frame's corners are inflated by the error the corners show (``LidarFrontEnd`` applies it).

KISS-ICP starts from an empty local map and a zero-motion prediction, and its first
increments can be off by more than any constant covariance says: on the synthetic corridor
bag (16 beams, walls that hold the forward direction weakly) its forward increments are about
4 cm short for ten frames against a stated 2 cm, 40 cm after ten frames
(``benchmarks/bench_lidar_bag_consistency.py``), and ``increment_noise``'s fit needs ten frames
of re-observations before it says anything. The frames' corners share the error: they are
deskewed with that motion. Landmarks initialised then carry it into the map at a covariance
that does not hold it. Nothing inside KISS-ICP shows it: its adaptive threshold never leaves
its initial value on that bag.

The criterion: a corner the tracker confirms in frame ``k`` was seen in frame ``k - 1``
(``corner_tracking``); put in the world frame with KISS-ICP's poses, the two sightings
differ by the detections' errors and by the error of KISS-ICP's increment ``k``. A
translation error ``delta`` of the increment moves every corner by ``-delta``, so the
weighted mean ``m`` of the differences estimates ``-delta`` with covariance
``(sum W)^-1``, and ``m^T (sum W) m`` is chi-square with 2 dof when the increment is right
(first order; a yaw error of the increment, which would swing the corners about the
vehicle, is left to the detections' covariance). KISS-ICP has *settled* once
``SETTLED_FRAMES`` consecutive frames with corners pass that test at ``probability``; from
then on nothing is changed (nor after ``LIMIT_FRAMES``, settled or not, which is a warning).
Until then each increment's horizontal translation covariance, and the horizontal
covariance of each of the frame's corners (a sweep deskewed with an increment off by
``delta`` moves its points by up to ``delta``), is raised by ``m m^T + (sum W)^-1``, the
size of the error the corners show. A frame without confirmed corners says nothing and
changes nothing.

Why inflate and not hold back: holding the corners back until KISS-ICP settles (built
and measured at stop 26) starts the map after KISS-ICP has drifted about 40 cm, and the map
keeps that offset (ekf-slam's raw ATE 0.11 -> 0.39 m on four bags).

Measured (``benchmarks/bench_lidar_bag_consistency.py --runs 10``, IMU deskew on; ANEES per
dof pose / map, then mean raw ATE / landmark RMSE [m], without -> with the warm-up):
ekf-slam 1.96 / 1.66 -> 0.44 / 1.10, 0.109 / 0.102 -> 0.116 / 0.109; iSAM2 and fixed-lag
1.42 / 2.16 -> 0.53 / 1.25, 0.025 / 0.030 -> 0.024 / 0.025; batch (smoothed) 1.83 / 2.68 ->
0.62 / 1.62, landmark RMSE 0.030 -> 0.025; sensor-based's map 1.12 -> 0.81; aghili 3.48 /
13.2 -> 1.55 / 6.43. KISS-ICP settles at frames 9-12 of the corridor bags.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

LIMIT_FRAMES = 50
"""The warm-up ends here, settled or not (5 s at 10 Hz): a recording whose corners never
accept KISS-ICP's increments (a corner covariance too small for its sensor, say) is not
inflated for ever, and the summary says the warm-up gave up (``gave_up_frame``), which the
front end turns into a warning (``LidarFrontEnd.settling_warning``)."""

SETTLED_FRAMES = 3
"""Consecutive frames whose increments the corners accept before KISS-ICP counts as
settled: a single frame of three or four corners accepts a 3 cm error about half the time
(about 1 cm standard error per frame on the corridor bag)."""


@dataclass
class MotionSettling:
    """The warm-up state (module docstring).

    Attributes:
        probability: chi-square probability of the per-frame test (2 dof).
        streak: consecutive frames with corners that passed so far.
        settled_frame: the frame at which KISS-ICP counted as settled, or None.
        gave_up_frame: ``LIMIT_FRAMES`` when the warm-up ended unsettled, else None.
        inflated_frames: how many increments were inflated.
    """

    probability: float = 0.99
    streak: int = 0
    settled_frame: int | None = None
    gave_up_frame: int | None = None
    inflated_frames: int = 0

    @property
    def warming_up(self) -> bool:
        """Whether increments and corners are still inflated."""
        return self.settled_frame is None and self.gave_up_frame is None

    @property
    def end_frame(self) -> int | None:
        """The first frame after the warm-up (settled or given up), or None while it lasts."""
        return self.settled_frame if self.settled_frame is not None else self.gave_up_frame

    def increment_inflation(
        self, frame: int, residuals: np.ndarray, covariances: np.ndarray
    ) -> np.ndarray | None:
        """The (2, 2) world-frame covariance [m^2] to add to increment ``frame``'s horizontal
        translation, from the frame's confirmed corners against their previous sightings
        (``residuals`` (k, 2) [m], ``covariances`` (k, 2, 2) [m^2]); None once settled or
        without corners."""
        if self.warming_up and frame >= LIMIT_FRAMES:
            self.gave_up_frame = frame
        if not self.warming_up or len(residuals) == 0:
            return None
        weights = np.linalg.inv(covariances)
        information = weights.sum(axis=0)
        covariance = np.linalg.inv(information)
        mean = covariance @ np.einsum("kij,kj->i", weights, residuals)
        if float(mean @ information @ mean) <= chi2.ppf(self.probability, 2):
            self.streak += 1
        else:
            self.streak = 0
        if self.streak >= SETTLED_FRAMES:
            self.settled_frame = frame
            return None
        self.inflated_frames += 1
        return np.outer(mean, mean) + covariance

    def summary(self) -> dict[str, int | None]:
        """For the front end's metrics: when KISS-ICP settled (or the warm-up gave up), and
        how many increments were inflated before."""
        return {
            "kiss_icp_settled_frame": self.settled_frame,
            "kiss_icp_warmup_gave_up_frame": self.gave_up_frame,
            "kiss_icp_warmup_inflated_increments": self.inflated_frames,
        }
