"""The vehicle path of the synthetic lidar world: a rounded rectangle driven at constant speed.

The path is a closed chain of straight lines and turns; each 90-degree turn ramps its
curvature linearly up to ``1 / radius_m``, holds it, and ramps it down (clothoid-arc-
clothoid), so heading, yaw rate and acceleration are continuous (a lidar sweep then sees a
smoothly changing motion, as constant-velocity deskewing assumes). Heading is the exact
integral of the piecewise-linear curvature; position is integrated on a fine arc-length grid
(``step_m``, error below a micrometre) and interpolated.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PathSample:
    """Planar motion at times t (all arrays have leading length N).

    Attributes:
        position: world (N, 2) [m].
        yaw: heading (N,) [rad], wrapped to [-pi, pi).
        velocity: world (N, 2) [m/s].
        acceleration: world (N, 2) [m/s^2].
        yaw_rate: (N,) [rad/s].
    """

    position: np.ndarray
    yaw: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    yaw_rate: np.ndarray


def _turn_curvature(radius_m: float, ramp_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Knots (arc length, curvature) of one left turn of 90 degrees."""
    kappa = 1.0 / radius_m
    hold = 0.5 * np.pi * radius_m - ramp_m  # heading change kappa * (ramp + hold) = pi / 2
    if hold < 0:
        raise ValueError("ramp_m too long for a 90-degree turn of this radius")
    return np.array([0.0, ramp_m, ramp_m + hold, 2 * ramp_m + hold]), np.array(
        [0.0, kappa, kappa, 0.0]
    )


class LoopPath:
    """Rounded rectangle with straights on ``y = y0``, ``x = x1``, ``y = y1``, ``x = x0``,
    driven counter-clockwise at ``speed_m_s`` from the middle of the bottom straight."""

    def __init__(
        self,
        x0: float = 2.5,
        y0: float = 2.5,
        x1: float = 27.5,
        y1: float = 17.5,
        radius_m: float = 2.0,
        ramp_m: float = 1.0,
        speed_m_s: float = 1.5,
        step_m: float = 0.005,
    ) -> None:
        self.speed_m_s = speed_m_s
        turn_s, turn_k = _turn_curvature(radius_m, ramp_m)
        # displacement of one turn (start heading 0): the straights end that far from the sides
        s_fine = np.linspace(0.0, turn_s[-1], 20001)
        heading = np.concatenate(
            [
                [0.0],
                np.cumsum(
                    np.diff(s_fine) * 0.5 * np.diff(np.interp(s_fine, turn_s, turn_k))
                    + np.diff(s_fine) * np.interp(s_fine, turn_s, turn_k)[:-1]
                ),
            ]
        )
        ds = np.diff(s_fine)
        advance = float(np.sum(ds * 0.5 * (np.cos(heading[1:]) + np.cos(heading[:-1]))))
        side = (x1 - x0) - 2 * advance, (y1 - y0) - 2 * advance
        if min(side) <= 0:
            raise ValueError("loop too small for its turns")
        # curvature knots over one lap, starting mid bottom straight
        knots_s, knots_k = [0.0], [0.0]

        def straight(length: float) -> None:
            knots_s.append(knots_s[-1] + length)
            knots_k.append(0.0)

        def turn() -> None:
            start = knots_s[-1]
            knots_s.extend(start + turn_s[1:])
            knots_k.extend(turn_k[1:])

        straight(0.5 * side[0])
        for length in (side[1], side[0], side[1]):
            turn()
            straight(length)
        turn()
        straight(0.5 * side[0])
        self._knots_s, self._knots_k = np.array(knots_s), np.array(knots_k)
        self.length_m = float(self._knots_s[-1])
        count = int(np.ceil(self.length_m / step_m)) + 1
        s = np.linspace(0.0, self.length_m, count)
        kappa = np.interp(s, self._knots_s, self._knots_k)
        ds = np.diff(s)
        # curvature is linear between grid points (knots are few), so the trapezoid is exact
        # up to the knots falling inside a cell
        heading = np.concatenate([[0.0], np.cumsum(ds * 0.5 * (kappa[1:] + kappa[:-1]))])
        x = 0.5 * (x0 + x1) + np.concatenate(
            [[0.0], np.cumsum(ds * 0.5 * (np.cos(heading[1:]) + np.cos(heading[:-1])))]
        )
        y = y0 + np.concatenate(
            [[0.0], np.cumsum(ds * 0.5 * (np.sin(heading[1:]) + np.sin(heading[:-1])))]
        )
        self._s, self._heading, self._x, self._y = s, heading, x, y

    def sample(self, t: np.ndarray) -> PathSample:
        """Motion at times ``t`` [s] (time 0 at the start point), shape (N,)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        laps, s = np.divmod(self.speed_m_s * t, self.length_m)
        heading = np.interp(s, self._s, self._heading)
        kappa = np.interp(s, self._knots_s, self._knots_k)
        v = self.speed_m_s
        direction = np.column_stack([np.cos(heading), np.sin(heading)])
        normal = np.column_stack([-np.sin(heading), np.cos(heading)])
        return PathSample(
            position=np.column_stack(
                [np.interp(s, self._s, self._x), np.interp(s, self._s, self._y)]
            ),
            yaw=np.mod(heading + 2.0 * np.pi * laps + np.pi, 2.0 * np.pi) - np.pi,
            velocity=v * direction,
            acceleration=(v * v * kappa)[:, None] * normal,
            yaw_rate=v * kappa,
        )
