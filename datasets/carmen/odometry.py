"""The odometry pose at every scan of a CARMEN log, and the increments between scans.

Every laser line carries the odometry pose CARMEN gave the scan (``odom_x odom_y odom_theta``,
a ``ROBOTLASER1``'s robot pose): on the shared Intel log it equals the pose of the latest
``ODOM`` line before the scan (at 13619 of 13631 scans), on Freiburg 079 it is interpolated
between them, and MIT CSAIL has no ``ODOM`` lines at all. So by default (``odometry=scan``)
the motion input is the scans' own odometry, one rule on every log, with the ``ODOM`` lines
interpolated to the scan stamps as the alternative (``odometry=messages``); the loader prints
how far the two differ.

*Stale odometry.* On MIT CSAIL the odometry of a moving robot sometimes stops changing for
a few scans and then jumps by the motion of all of them (three runs of four scans at about
1 m/s: steps of 0.83-0.94 m in 0.21 s). A run of zero increments is taken as stale when the
jump that ends it, spread over the run, matches the speed and turn rate of the increment
before the run better than the jump itself does (and that speed exceeds
``STALE_MIN_SPEED_M_S`` or turn rate ``STALE_MIN_RATE_RAD_S``; a robot that stopped and
starts again moves slowly at first). By default (``stale_odometry=spread``) the poses of
the run are replaced by the constant-velocity interpolation between the last fresh pose and
the pose after the jump; every run is counted and printed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.rotations import wrap_angle

STALE_MIN_SPEED_M_S = 0.05
"""Slowest speed before a run of repeated poses for it to count as stale odometry [m/s]."""

STALE_MIN_RATE_RAD_S = 0.05
"""Slowest turn rate before a run of repeated poses for it to count as stale [rad/s]."""

TURN_WEIGHT_M = 0.3
"""Metres per radian when speed and turn-rate mismatches are added (a lever of 0.3 m)."""


def relative_increments(poses: np.ndarray) -> np.ndarray:
    """Increments between consecutive poses (n, 3) (x [m], y [m], theta [rad]): the pose of
    ``k + 1`` in the frame of pose ``k``, (n - 1, 3) ``(dx, dy, dtheta)``."""
    poses = np.asarray(poses, dtype=float)
    steps = np.diff(poses[:, :2], axis=0)
    cos, sin = np.cos(poses[:-1, 2]), np.sin(poses[:-1, 2])
    return np.column_stack(
        [
            cos * steps[:, 0] + sin * steps[:, 1],
            -sin * steps[:, 0] + cos * steps[:, 1],
            wrap_angle(np.diff(poses[:, 2])),
        ]
    )


def interpolate_poses(times: np.ndarray, t: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """Poses (n, 3) at ``times`` (n,) [s], linear in ``t`` (m,) increasing between ``poses``
    (m, 3) (heading unwrapped first), held at the first and last pose outside."""
    heading = np.unwrap(poses[:, 2])
    return np.column_stack(
        [
            np.interp(times, t, poses[:, 0]),
            np.interp(times, t, poses[:, 1]),
            wrap_angle(np.interp(times, t, heading)),
        ]
    )


@dataclass(frozen=True)
class StaleRuns:
    """Runs of stale odometry (module docstring).

    Attributes:
        runs: (first repeated scan, scan after the jump) for each run, indices into the scans.
        scans: scans whose pose was replaced.
    """

    runs: tuple[tuple[int, int], ...]
    scans: int


def find_stale_runs(times: np.ndarray, poses: np.ndarray) -> StaleRuns:
    """The runs of stale odometry among scan ``times`` (n,) [s] and ``poses`` (n, 3)."""
    increments = relative_increments(poses)
    durations = np.diff(times)
    steps = np.hypot(increments[:, 0], increments[:, 1])
    turns = np.abs(increments[:, 2])
    zero = np.all(np.diff(poses, axis=0) == 0.0, axis=1)
    runs: list[tuple[int, int]] = []
    k, count = 0, len(zero)
    while k < count:
        if not zero[k]:
            k += 1
            continue
        first = k
        while k < count and zero[k]:
            k += 1
        if first == 0 or k >= count:
            continue
        before = first - 1  # the increment before the run
        speed, rate = steps[before] / durations[before], turns[before] / durations[before]
        if speed < STALE_MIN_SPEED_M_S and rate < STALE_MIN_RATE_RAD_S:
            continue
        span = times[k + 1] - times[first]  # the run and the jump
        spread = abs(steps[k] / span - speed) + TURN_WEIGHT_M * abs(turns[k] / span - rate)
        single = abs(steps[k] / durations[k] - speed) + TURN_WEIGHT_M * abs(
            turns[k] / durations[k] - rate
        )
        if spread < single:
            runs.append((first, k + 1))
    return StaleRuns(tuple(runs), sum(last - first - 1 for first, last in runs))


def spread_stale(times: np.ndarray, poses: np.ndarray, stale: StaleRuns) -> np.ndarray:
    """``poses`` with every stale run's scans at the constant-velocity interpolation between
    the run's last fresh pose and the pose after its jump."""
    poses = np.array(poses, dtype=float)
    for first, last in stale.runs:
        inside = np.arange(first + 1, last)
        fraction = (times[inside] - times[first]) / (times[last] - times[first])
        change = np.concatenate(
            [poses[last, :2] - poses[first, :2], [wrap_angle(poses[last, 2] - poses[first, 2])]]
        )
        poses[inside] = poses[first] + fraction[:, None] * change
        poses[inside, 2] = wrap_angle(poses[inside, 2])
    return poses


def stale_line(stale: StaleRuns, times: np.ndarray, lines: np.ndarray, total: int) -> str:
    """One printable line: the stale runs found and what was done (``lines``: each scan's
    file line)."""
    first, last = stale.runs[0]
    return (
        f"odometry: {len(stale.runs)} run(s) of stale odometry ({stale.scans} of {total} scans "
        f"repeat the previous pose while moving, then the pose jumps by the whole run's motion; "
        f"first: lines {lines[first + 1]}-{lines[last]}, {times[last] - times[first]:.2f} s): "
        "spread over each run at constant velocity (stale_odometry=keep keeps them)"
    )
