"""The vehicle path of the synthetic lidar world: a rounded rectangle driven at constant speed.

The path is a closed chain of straight lines and circular arcs (continuous position and
heading, piecewise-constant curvature), evaluated analytically so that IMU samples
(angular rate, specific force) and ground truth are exact.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PathSample:
    """Planar motion at times t (all arrays have leading length N).

    Attributes:
        position: world (N, 2) [m].
        yaw: heading (N,) [rad].
        velocity: world (N, 2) [m/s].
        acceleration: world (N, 2) [m/s^2].
        yaw_rate: (N,) [rad/s].
    """

    position: np.ndarray
    yaw: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    yaw_rate: np.ndarray


class LoopPath:
    """Rounded rectangle between corner-arc centres ``(x0+r, y0+r)`` ... ``(x1-r, y1-r)``,
    driven counter-clockwise at ``speed_m_s`` from the middle of the bottom side."""

    def __init__(self, x0: float = 2.5, y0: float = 2.5, x1: float = 27.5, y1: float = 17.5, radius_m: float = 2.0, speed_m_s: float = 1.5) -> None:
        self.speed_m_s = speed_m_s
        r = radius_m
        mid = 0.5 * (x0 + x1)
        # (start x, start y, start heading, length, curvature)
        pieces = [
            (mid, y0, 0.0, x1 - r - mid, 0.0),
            (x1 - r, y0, 0.0, 0.5 * np.pi * r, 1.0 / r),
            (x1, y0 + r, 0.5 * np.pi, y1 - y0 - 2 * r, 0.0),
            (x1, y1 - r, 0.5 * np.pi, 0.5 * np.pi * r, 1.0 / r),
            (x1 - r, y1, np.pi, x1 - x0 - 2 * r, 0.0),
            (x0 + r, y1, np.pi, 0.5 * np.pi * r, 1.0 / r),
            (x0, y1 - r, 1.5 * np.pi, y1 - y0 - 2 * r, 0.0),
            (x0, y0 + r, 1.5 * np.pi, 0.5 * np.pi * r, 1.0 / r),
            (x0 + r, y0, 2.0 * np.pi, mid - x0 - r, 0.0),
        ]
        self._pieces = np.array(pieces)
        self._starts = np.concatenate([[0.0], np.cumsum(self._pieces[:, 3])[:-1]])
        self.length_m = float(np.sum(self._pieces[:, 3]))

    def sample(self, t: np.ndarray) -> PathSample:
        """Exact planar motion at times ``t`` [s] (time 0 at the start point), shape (N,)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        laps, s = np.divmod(self.speed_m_s * t, self.length_m)
        index = np.clip(np.searchsorted(self._starts, s, side="right") - 1, 0, len(self._pieces) - 1)
        x0, y0, h0, _, kappa = self._pieces[index].T
        u = s - self._starts[index]
        heading = h0 + kappa * u
        straight = kappa == 0.0
        safe_kappa = np.where(straight, 1.0, kappa)
        x = np.where(straight, x0 + u * np.cos(h0), x0 + (np.sin(heading) - np.sin(h0)) / safe_kappa)
        y = np.where(straight, y0 + u * np.sin(h0), y0 + (np.cos(h0) - np.cos(heading)) / safe_kappa)
        v = self.speed_m_s
        direction = np.column_stack([np.cos(heading), np.sin(heading)])
        normal = np.column_stack([-np.sin(heading), np.cos(heading)])
        yaw = np.mod(heading + 2.0 * np.pi * laps + np.pi, 2.0 * np.pi) - np.pi
        return PathSample(
            position=np.column_stack([x, y]),
            yaw=yaw,
            velocity=v * direction,
            acceleration=(v * v * kappa)[:, None] * normal,
            yaw_rate=v * kappa,
        )
