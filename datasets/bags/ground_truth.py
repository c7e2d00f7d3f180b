"""A bag's ground-truth topic: read whole (``read_ground_truth``), made the sequence's
``GroundTruth`` (``ground_truth_from_topic``), and the initial state it gives
(``initial_state_from_truth``).

Reading takes the poses of an Odometry, PoseStamped or PoseWithCovarianceStamped topic,
stamp-ordered, with the checks of what a pose can show, each violation skipped and counted in
the ``ReadReport``: a stamp not after the previous one; non-finite, an orientation that is
not a unit quaternion (within ``UNIT_QUATERNION_TOLERANCE``), a position beyond
``MAX_POSITION_M`` or reached from the previous pose faster than ``MAX_TRUTH_SPEED_M_S``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from datasets.bags.bag_file import iter_messages, open_bag
from datasets.bags.convert import UNIT_QUATERNION_TOLERANCE, pose_of
from datasets.bags.read_report import ReadReport
from datasets.lidar.corner_truth import CornerTruth, interpolate_poses
from datasets.sequence import InitialState
from datasets.state import Frame, GroundTruth, LandmarkMap, StateHistory
from datasets.trajectory import Trajectory
from datasets.trajectory_io import MAX_POSITION_M
from datasets.truth_quality.assess import assess_trajectory

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


def ground_truth_from_topic(
    times: np.ndarray,
    positions: np.ndarray,
    quats: np.ndarray,
    truth: CornerTruth | None,
    topic: str | None,
    warnings: list[str],
) -> GroundTruth | None:
    """The named truth topic's poses and the sidecar's corners, or None without poses: the
    sidecar's corners are in the truth topic's world frame, while without it the first body
    frame is the world, so a map scored against them would compare two frames (a 9 m
    "landmark RMSE" on a 3 s corridor bag whose map is fine). Where the topic cannot be
    trusted (``datasets.truth_quality``: dropouts, freezes, jumps, ...) is excluded from
    the scoring and said in ``warnings``."""
    if len(times) < 2:
        return None
    pose = Trajectory(times, positions, quats)
    landmarks = (
        LandmarkMap(ids=truth.ids.copy(), positions=truth.positions.copy(), frame=Frame.WORLD)
        if truth is not None
        else None
    )
    excluded, lines = assess_trajectory(times, positions, quats, f"truth topic {topic}")
    warnings.extend(lines)
    return GroundTruth(history=StateHistory(pose=pose), landmarks=landmarks, excluded=excluded)


def initial_state_from_truth(start_s: float, truth: Trajectory | None) -> InitialState:
    """At ``start_s`` (the start of the common time base): from the ground truth there when
    the bag has one (velocity by differences); otherwise the first body frame defines the
    world."""
    if truth is None or len(truth) < 2:
        return InitialState(
            t=start_s, position=np.zeros(3), rotation=np.array([1.0, 0.0, 0.0, 0.0]), velocity=None
        )
    t0 = max(start_s, float(truth.t[0]))
    step = float(np.median(np.diff(truth.t)))
    positions, quats = interpolate_poses(truth, np.array([t0, t0 + step]))
    velocity = (positions[1] - positions[0]) / step
    return InitialState(t=t0, position=positions[0], rotation=quats[0], velocity=velocity)
