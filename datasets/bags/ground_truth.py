"""Reading a ground-truth topic whole (``read_ground_truth``): the poses of an Odometry,
PoseStamped or PoseWithCovarianceStamped topic, stamp-ordered, with the checks of what a
pose can show, each violation skipped and counted in the ``ReadReport``: a stamp not after
the previous one; non-finite, an orientation that is not a unit quaternion (within
``UNIT_QUATERNION_TOLERANCE``), a position beyond ``MAX_POSITION_M`` or reached from the
previous pose faster than ``MAX_TRUTH_SPEED_M_S``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from datasets.bags.bag_file import iter_messages, open_bag
from datasets.bags.convert import UNIT_QUATERNION_TOLERANCE, pose_of
from datasets.bags.read_report import ReadReport
from datasets.trajectory_io import MAX_POSITION_M

MAX_TRUTH_SPEED_M_S = 100.0
"""Between two ground-truth poses [m/s]: 360 km/h, faster than anything a lidar bag is
recorded on; a faster step is a corrupted pose."""


def read_ground_truth(
    path: Path, topic: str, report: ReadReport, reader=None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All poses of a ground-truth topic: t (N,), positions (N, 3), quaternions wxyz (N, 4),
    stamp-ordered; backwards, non-finite or implausible poses (module docstring) skipped and
    counted. ``reader``: the bag already open (``open_bag``), else it is opened here."""
    if reader is None:
        with open_bag(path) as opened:
            return read_ground_truth(path, topic, report, opened)
    times, positions, quats = [], [], []
    for _, msgtype, stamp, message in iter_messages(reader, path, [topic], report=report):
        position, quat = pose_of(message, msgtype)
        with np.errstate(over="ignore"):  # a corrupted 1e300 overflows to inf: skipped
            norm = np.linalg.norm(quat)
        if not (np.all(np.isfinite(position)) and np.isfinite(norm) and norm > 1e-9):
            report.skip(topic, "non-finite pose", stamp)
            continue
        if times and stamp <= times[-1]:
            report.skip(topic, "stamp not after the previous one", stamp)
            continue
        if abs(norm - 1.0) > UNIT_QUATERNION_TOLERANCE:
            report.skip(topic, "orientation not a unit quaternion", stamp, f"norm {norm:.6g}")
            continue
        if np.max(np.abs(position)) > MAX_POSITION_M:
            report.skip(topic, f"position beyond {MAX_POSITION_M:g} m", stamp)
            continue
        with np.errstate(over="ignore"):
            step_m = float(np.linalg.norm(position - positions[-1])) if times else 0.0
        if times and step_m > MAX_TRUTH_SPEED_M_S * (stamp - times[-1]):
            report.skip(
                topic,
                f"pose jumps faster than {MAX_TRUTH_SPEED_M_S:g} m/s",
                stamp,
                f"{step_m:.3g} m in {stamp - times[-1]:.3g} s",
            )
            continue
        times.append(stamp)
        positions.append(position)
        quats.append(quat / norm)
    return np.array(times), np.array(positions).reshape(-1, 3), np.array(quats).reshape(-1, 4)
