"""Deskewing a lidar sweep with the IMU's rotation (bags with an IMU topic, ``imu_deskew``).

KISS-ICP deskews under constant velocity: every point moves to the sweep end by the
previous frame's motion, scaled by its time in the sweep. When the yaw rate changes within
a frame that prediction lags. Here the rotation between a point's time and the sweep end is
the gyro's, integrated between its samples; the translation is constant *body-frame*
velocity (the previous frame's KISS-ICP twist over its duration, the same assumption KISS-ICP
makes), carried through that rotation. Under constant body velocity ``v`` and the body's
rotation ``R(s)`` relative to the sweep end ``t_e``, a point ``p`` measured at time ``s``
is, in the body frame at ``t_e``::

    p_e = R(s) p + x(s),   x(s) = -integral_s^t_e R(tau) v dtau

(``R(t_e) = I``). ``R`` is integrated backwards from ``t_e`` over the gyro samples
(midpoint of the linearly interpolated rates in each interval), ``x`` by the
trapezoid rule on the same knots, and each point's ``(log R, x)`` is interpolated linearly
in time between knots (the rotation over a 0.1 s sweep is a few degrees at most, where
that is exact to second order).

Gyro bias is not removed. A bias that stays constant distorts every sweep alike, and
KISS-ICP registers a sweep to a map of sweeps distorted the same way, so it cancels: on the
synthetic corridor bag with 0.05 rad/s added to the yaw gyro, the per-frame yaw error read
0.021 deg RMS without correction against 0.027 with a running estimate from KISS-ICP's
increments (whose frame-to-frame noise then distorted each sweep differently).

Measured on the synthetic corridor bag, seeds 0-2 (``benchmarks/bench_lidar_imu_deskew.py``):
KISS-ICP's per-frame yaw error is 0.0429 deg RMS (max 0.261) with its own constant-velocity
deskew, 0.0167 (max 0.063) with this one, and 0.0165 (max 0.055) with the *true* motion, an
upper bound for any deskew. The gain is in the sharp turn: on seed 0, per ten frames,
frames 60-79 read 0.093 / 0.076 deg RMS with KISS-ICP's deskew, 0.015 / 0.018 with the IMU's
and 0.016 / 0.017 with the truth; before it all three read 0.006-0.029, KISS-ICP's
registration noise, in no fixed order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.rotations import so3_exp, so3_log

COVERAGE_TOLERANCE_SAMPLES = 1.5
"""A sweep is deskewed with the IMU when its samples reach within this many sample intervals
of both ends of the sweep (the rate is held constant over that edge) ..."""

MAX_GAP_SAMPLES = 3.0
"""... and no two consecutive samples over it are further apart than this many intervals (a
dropped sample is interpolated through); otherwise the frame falls back to KISS-ICP's
constant-velocity deskew, and is counted. Intervals are the buffer's median."""


@dataclass(frozen=True)
class SweepMotion:
    """The body's motion over one sweep, relative to its end.

    Attributes:
        times: (m,) knot times [s], increasing, the last the sweep end.
        rotation_vectors: (m, 3) log of the body's rotation at each knot relative to the end.
        rotations: (m, 3, 3) the same rotations.
    """

    times: np.ndarray
    rotation_vectors: np.ndarray
    rotations: np.ndarray

    def to_end(self, points: np.ndarray, times: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """Points measured at ``times`` moved into the body frame at the sweep end.

        Args:
            points: (n, 3) body-frame points [m], each at its own time.
            times: (n,) absolute point times [s] (clamped to the knots).
            velocity: (3,) body-frame linear velocity over the sweep [m/s].
        Returns:
            (n, 3) [m].
        """
        steps = np.diff(self.times)
        # x at the knots: trapezoid of -R(tau) v backwards from x(t_e) = 0
        moved = self.rotations @ np.asarray(velocity, dtype=float)  # (m, 3)
        increments = 0.5 * (moved[1:] + moved[:-1]) * steps[:, None]
        offsets = np.zeros_like(moved)
        offsets[:-1] = -np.cumsum(increments[::-1], axis=0)[::-1]
        clamped = np.clip(np.asarray(times, dtype=float), self.times[0], self.times[-1])
        rotvec = np.column_stack(
            [np.interp(clamped, self.times, self.rotation_vectors[:, k]) for k in range(3)]
        )
        shift = np.column_stack([np.interp(clamped, self.times, offsets[:, k]) for k in range(3)])
        return rotate_each(rotvec, np.asarray(points, dtype=float)) + shift


def rotate_each(rotation_vectors: np.ndarray, points: np.ndarray) -> np.ndarray:
    """``Exp(r_i) p_i`` for each row (Rodrigues), (n, 3) and (n, 3) -> (n, 3)."""
    angle = np.linalg.norm(rotation_vectors, axis=1)
    small = angle < 1e-9
    safe = np.where(small, 1.0, angle)
    sine = np.where(small, 1.0 - angle**2 / 6.0, np.sin(safe) / safe)
    cosine = np.where(small, 0.5 - angle**2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    cross = np.cross(rotation_vectors, points)
    return points + sine[:, None] * cross + cosine[:, None] * np.cross(rotation_vectors, cross)


class GyroBuffer:
    """Gyro samples in time order, kept for the sweeps still to come."""

    def __init__(self) -> None:
        self.times: list[float] = []
        self.rates: list[np.ndarray] = []

    def add(self, t: float, rate: np.ndarray) -> None:
        """Append one sample (body rate [rad/s], (3,)); a repeated or older stamp (a second
        pass over the stream) is ignored."""
        if self.times and t <= self.times[-1]:
            return
        self.times.append(float(t))
        self.rates.append(np.asarray(rate, dtype=float))

    @property
    def last_time(self) -> float:
        return self.times[-1] if self.times else -np.inf

    def forget_before(self, t: float) -> None:
        """Drop samples older than the one at or just before ``t``."""
        keep = int(np.searchsorted(self.times, t, side="right")) - 1
        if keep > 0:
            del self.times[:keep]
            del self.rates[:keep]

    def interval(self) -> float:
        """Median sample interval [s] (inf with fewer than two samples)."""
        if len(self.times) < 2:
            return np.inf
        return float(np.median(np.diff(self.times)))

    def covers(self, start: float, end: float) -> bool:
        """Whether samples reach within ``COVERAGE_TOLERANCE_SAMPLES`` intervals of both
        ``start`` and ``end`` [s], with no gap over ``MAX_GAP_SAMPLES`` intervals between."""
        if len(self.times) < 2:
            return False
        times = np.asarray(self.times)
        first = max(int(np.searchsorted(times, start, side="right")) - 1, 0)
        last = int(np.searchsorted(times, end, side="left"))
        spanning = times[first : last + 1]
        interval = self.interval()
        return bool(
            spanning.size >= 2
            and spanning[0] <= start + COVERAGE_TOLERANCE_SAMPLES * interval
            and spanning[-1] >= end - COVERAGE_TOLERANCE_SAMPLES * interval
            and np.max(np.diff(spanning)) <= MAX_GAP_SAMPLES * interval
        )

    def motion(self, start: float, end: float) -> SweepMotion:
        """The body's rotation over ``[start, end]`` relative to ``end`` (module docstring),
        knots at ``start``, every sample strictly inside and ``end``; the rate is
        interpolated linearly between samples and held beyond the first and last."""
        times = np.asarray(self.times)
        rates = np.asarray(self.rates)
        inside = times[(times > start) & (times < end)]
        knots = np.concatenate([[start], inside, [end]])
        knot_rates = np.column_stack([np.interp(knots, times, rates[:, k]) for k in range(3)])
        rotations = np.empty((len(knots), 3, 3))
        rotations[-1] = np.eye(3)
        for j in range(len(knots) - 2, -1, -1):
            mean_rate = 0.5 * (knot_rates[j] + knot_rates[j + 1])
            step = knots[j + 1] - knots[j]
            rotations[j] = rotations[j + 1] @ so3_exp(-mean_rate * step)
        rotation_vectors = np.array([so3_log(rotation) for rotation in rotations])
        return SweepMotion(knots, rotation_vectors, rotations)
