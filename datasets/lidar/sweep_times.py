"""Per-point times of spinning-lidar clouds that carry none (``--data point_times=azimuth``).

A cloud without a time field is taken as motion-compensated unless the user says otherwise:
the rule below is KITTI raw's, and applied to another sensor's clouds (another sweep
direction or start) it would distort them, so it is not applied unasked. Scan folders and
bags share it: the times come from each point's azimuth in the lidar's own frame, over one
sweep of the lidar topic's frame interval.
"""

from __future__ import annotations

import numpy as np

from datasets.errors import InputError

POINT_TIMES_DESCRIPTION = (
    "per-point times: 'field', from a time field where a cloud has one (none otherwise: the "
    "clouds are taken as motion-compensated); 'azimuth', from each point's azimuth, for "
    "clouds of a spinning lidar that are not motion-compensated and carry no times: a "
    "clockwise sweep from behind over one frame interval, the frame's stamp at mid-sweep "
    "facing forward (KITTI raw's velodyne_points; KISS-ICP's KITTI-raw loader computes the "
    "same); a cloud with times of its own is refused"
)


def azimuth_point_times(points: np.ndarray, sweep_s: float) -> np.ndarray:
    """Per-point times [s] relative to the frame's stamp, (n,), of a spinning lidar's cloud
    that carries none: ``-atan2(y, x) / (2 pi) * sweep_s``, a clockwise sweep seen from above
    that starts behind (azimuth +180 deg, ``-sweep_s / 2``), faces forward at the stamp and
    ends behind (``+sweep_s / 2``). This is KITTI raw's timing: its velodyne_points are not
    motion-compensated, and the camera is triggered as the sensor faces forward (the raw
    data's readme; KISS-ICP's KITTI-raw loader uses the same rule).

    Args:
        points: (n, 3) [m], sensor frame (x forward, y left, z up). sweep_s: one revolution [s].
    """
    return -np.arctan2(points[:, 1], points[:, 0]) / (2.0 * np.pi) * sweep_s


def point_times_for(
    points: np.ndarray, own_times: np.ndarray | None, azimuth_sweep_s: float | None, where: str
) -> np.ndarray | None:
    """The per-point times [s] a cloud is read with: its ``own_times`` (or None), or, with
    ``azimuth_sweep_s`` set (``point_times=azimuth``), ``azimuth_point_times`` of its
    lidar-frame ``points`` (n, 3) [m]. ``InputError`` naming ``where`` (file, or bag, topic
    and time) for a cloud that has times of its own under the option: it is for clouds
    without them, and does not override a sensor's own."""
    if azimuth_sweep_s is None:
        return own_times
    if own_times is not None:
        raise InputError(
            f"{where}: has per-point times of its own; point_times=azimuth is for clouds "
            "without them"
        )
    return azimuth_point_times(points, azimuth_sweep_s)


def sweep_period(stamps: np.ndarray, where: str) -> float:
    """One sweep [s]: the median positive interval of the frame ``stamps`` [s];
    ``InputError`` naming ``where`` when no two stamps differ."""
    steps = np.diff(np.asarray(stamps, dtype=float))
    steps = steps[steps > 0]
    if steps.size == 0:
        raise InputError(
            f"{where}: point_times=azimuth needs the sweep period, and fewer than two frames "
            "with increasing stamps give none"
        )
    return float(np.median(steps))
