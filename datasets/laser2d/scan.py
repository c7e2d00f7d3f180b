"""A 2-D laser scan (one sweep of a planar range finder) and its points in the body frame.

The sensor-agnostic input of the 2-D laser front end: a CARMEN log line, a simulated scan
(``datasets.laser2d.simulation``) or, later, a ROS ``sensor_msgs/LaserScan`` all become a
``PlanarScan``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PlanarScan:
    """One 2-D laser scan.

    Attributes:
        t: time [s] (the pose the scan is seen from is the body pose at ``t``).
        ranges: (n,) [m]; beam ``i`` points at ``angles[i]`` in the laser frame.
        angles: (n,) [rad], increasing, counter-clockwise from the laser's x axis.
        min_range_m, max_range_m: readings outside ``[min, max)`` are no return.
        mounting: (3,) the laser's pose in the body frame: x [m], y [m], theta [rad].
        beam_times: (n,) [s] each beam's time relative to ``t`` (a ROS ``LaserScan`` with
            ``time_increment > 0``: ``i * time_increment``, the header stamp being the first
            beam's), or None where the source gives none (CARMEN, simulated scans).
    """

    t: float
    ranges: np.ndarray
    angles: np.ndarray
    min_range_m: float
    max_range_m: float
    mounting: np.ndarray
    beam_times: np.ndarray | None = None

    def returns(self) -> np.ndarray:
        """Which beams returned, (n,) bool."""
        ranges = self.ranges
        return np.isfinite(ranges) & (ranges >= self.min_range_m) & (ranges < self.max_range_m)

    def laser_points(self) -> tuple[np.ndarray, np.ndarray]:
        """Returned beams as points in the laser frame, (m, 2) [m], in beam order, and their
        beam indices (m,)."""
        beams = np.flatnonzero(self.returns())
        ranges, angles = self.ranges[beams], self.angles[beams]
        return np.column_stack([ranges * np.cos(angles), ranges * np.sin(angles)]), beams


def laser_to_body(mounting: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (2, 2) and translation (2,) [m] taking laser-frame points to the body frame:
    ``p_body = R p_laser + t``."""
    x, y, theta = np.asarray(mounting, dtype=float)
    cos, sin = np.cos(theta), np.sin(theta)
    return np.array([[cos, -sin], [sin, cos]]), np.array([x, y])
