"""The ``motion`` check: windows where the truth's relative motion disagrees with the
vehicle's odometry (composed by dead reckoning), each as a ``_Jump`` whose net change is the
truth's motion beyond the odometry's, so that it pairs like a step."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from datasets.errors import InputError
from datasets.rotations import matrix_from_quat_wxyz, so3_log, wrap_angle
from datasets.truth_quality.jumps import _Jump
from datasets.truth_quality.settings import TruthQualitySettings
from datasets.truth_quality.steps import _broken_windows, _robust_sigma

if TYPE_CHECKING:
    from datasets.odometry_calibration import Increments


def _dead_reckoning(motion: Increments) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Composed odometry: (times (M+1,), planar poses (M+1, 3) as x, y, unwrapped theta,
    (M,) bool: increment k starts later than increment k-1 ends (a gap))."""
    t_end = np.asarray(motion.t_end, dtype=float)
    dt = np.asarray(motion.dt, dtype=float)
    values = np.asarray(motion.values, dtype=float)
    if values.ndim != 2 or values.shape != (len(t_end), 3) or dt.shape != t_end.shape:
        raise InputError(
            f"motion increments must be t_end (M,), dt (M,), values (M, 3); got "
            f"{t_end.shape}, {dt.shape}, {values.shape}"
        )
    heading = np.concatenate([[0.0], np.cumsum(values[:, 2])])
    cos, sin = np.cos(heading[:-1]), np.sin(heading[:-1])
    world = np.column_stack(
        [cos * values[:, 0] - sin * values[:, 1], sin * values[:, 0] + cos * values[:, 1]]
    )
    xy = np.vstack([np.zeros((1, 2)), np.cumsum(world, axis=0)])
    times = np.concatenate([[t_end[0] - dt[0]], t_end])
    starts = t_end - dt
    gap = np.zeros(len(t_end), dtype=bool)
    gap[1:] = starts[1:] > t_end[:-1] + 0.5 * np.median(dt)
    return times, np.column_stack([xy, heading]), gap


def _relative_planar(xy: np.ndarray, heading: np.ndarray, a: np.ndarray, b: np.ndarray):
    """(dx, dy, dtheta) from pose a to pose b in frame a, shape (W, 3)."""
    delta = xy[b] - xy[a]
    cos, sin = np.cos(heading[a]), np.sin(heading[a])
    return np.column_stack(
        [
            cos * delta[:, 0] + sin * delta[:, 1],
            -sin * delta[:, 0] + cos * delta[:, 1],
            np.asarray(wrap_angle(heading[b] - heading[a]), dtype=float),
        ]
    )


def _motion(
    t: np.ndarray,
    positions: np.ndarray,
    rotations: np.ndarray | None,
    planar: bool,
    motion: Increments,
    broken: np.ndarray,
    thresholds: tuple[float, float],
    settings: TruthQualitySettings,
) -> tuple[list[_Jump], dict[str, float]]:
    """Windows where the truth's relative motion disagrees with the odometry's, merged where
    they overlap, each as a jump whose net change is the truth's motion beyond the
    odometry's (world frame, the truth's heading at its start), so that a smooth departure
    pairs with its return like a step does. ``thresholds``: (position [m], rotation [rad])
    above which a net change is significant."""
    odo_t, odo_pose, odo_gap = _dead_reckoning(motion)
    count = len(t)
    length = settings.motion_window_steps
    stride = max(length // 2, 1)
    lower = np.arange(0, max(count - length, 0), stride)
    upper = lower + length
    usable = ~_broken_windows(broken, lower, upper)
    usable &= (t[lower] >= odo_t[0]) & (t[upper] <= odo_t[-1])
    if np.any(odo_gap):
        # a window that spans a gap in the odometry has no odometry motion to compare
        gap_starts = (np.asarray(motion.t_end) - np.asarray(motion.dt))[odo_gap]
        gap_ends = np.asarray(motion.t_end)[np.flatnonzero(odo_gap) - 1]
        for start, end in zip(gap_ends, gap_starts):
            usable &= ~((t[lower] < start) & (t[upper] > end))
    lower, upper = lower[usable], upper[usable]
    stats = {"motion_windows": float(len(lower))}
    if len(lower) < 10:
        return [], stats  # too few windows for a robust spread
    odo = np.column_stack([np.interp(t, odo_t, odo_pose[:, k]) for k in range(3)])
    truth_rel, odo_rel, names = _relative_motions(positions, rotations, planar, odo, lower, upper)
    difference = truth_rel - odo_rel
    if difference.shape[1] == 3:
        difference[:, 2] = np.asarray(wrap_angle(difference[:, 2]), dtype=float)
    centre = np.median(difference, axis=0)
    floors = np.array([settings.jump_floor_m] * 2 + [settings.jump_floor_rad])[: len(names)]
    spread = np.maximum(_robust_sigma(difference), floors)
    score = np.abs(difference - centre) / spread
    worst = np.max(score, axis=1)
    for name, value in zip(names, spread):
        stats[f"motion_spread_{name}"] = float(value)
    stats["motion_largest_spreads"] = float(np.max(worst))
    flagged = np.flatnonzero(worst > settings.motion_min_spreads)
    groups: list[list[int]] = []
    for k in flagged:
        if groups and lower[k] <= upper[groups[-1][-1]]:
            groups[-1].append(int(k))
        else:
            groups.append([int(k)])
    found: list[_Jump] = []
    for group in groups:
        a, b = int(lower[group[0]]), int(upper[group[-1]])
        k = group[int(np.argmax(worst[group]))]
        axis = int(np.argmax(score[k]))
        evidence = (
            f"truth moved {np.round(truth_rel[k], 3).tolist()} ({', '.join(names)}) in "
            f"{t[upper[k]] - t[lower[k]]:.2f} s where the odometry says "
            f"{np.round(odo_rel[k], 3).tolist()}: {names[axis]} {score[k, axis]:.0f} robust "
            f"spreads ({spread[axis]:.3g}) off the median"
            + (f" ({len(group)} overlapping windows)" if len(group) > 1 else "")
        )
        pos_net, rot_net = _motion_net(positions, rotations, planar, odo, a, b)
        found.append(
            _Jump(
                a,
                b - 1,
                pos_net,
                rot_net,
                bool(np.linalg.norm(pos_net) > thresholds[0]),
                bool(np.linalg.norm(rot_net) > thresholds[1]),
                evidence,
            )
        )
    return found, stats


def _relative_motions(
    positions: np.ndarray,
    rotations: np.ndarray | None,
    planar: bool,
    odo: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """Truth and odometry motion from ``lower`` to ``upper`` in the frame at ``lower``:
    (dx, dy, dtheta) each (W, 3); positions only: the travelled distance (W, 1)."""
    odo_rel = _relative_planar(odo[:, :2], odo[:, 2], lower, upper)
    if rotations is None:
        # positions only: the travelled distance is all that has no frame
        truth_rel = np.linalg.norm(positions[upper] - positions[lower], axis=1)[:, None]
        return truth_rel, np.linalg.norm(odo_rel[:, :2], axis=1)[:, None], ("distance",)
    if planar:
        truth_rel = _relative_planar(positions[:, :2], rotations, lower, upper)
    else:
        matrices = matrix_from_quat_wxyz(rotations)
        body = np.einsum("nji,nj->ni", matrices[lower], positions[upper] - positions[lower])
        turn = so3_log(np.einsum("nji,njk->nik", matrices[lower], matrices[upper]))
        truth_rel = np.column_stack([body[:, :2], np.asarray(turn).reshape(-1, 3)[:, 2]])
    return truth_rel, odo_rel, ("dx", "dy", "dtheta")


def _motion_net(
    positions: np.ndarray,
    rotations: np.ndarray | None,
    planar: bool,
    odo: np.ndarray,
    a: int,
    b: int,
) -> tuple[np.ndarray, np.ndarray]:
    """The truth's change from sample a to b beyond the odometry's: world-frame position
    (odometry turned by the truth's heading at a), and heading (planar only; 3-D and
    positions-only truth give no rotation part)."""
    delta = positions[b] - positions[a]
    odo_rel = _relative_planar(odo[:, :2], odo[:, 2], np.array([a]), np.array([b]))[0]
    if rotations is None:
        return np.zeros_like(delta), np.zeros(1)  # no frame: no direction to pair by
    if planar:
        cos, sin = math.cos(rotations[a]), math.sin(rotations[a])
        odo_world = np.array(
            [cos * odo_rel[0] - sin * odo_rel[1], sin * odo_rel[0] + cos * odo_rel[1]]
        )
        position = delta[:2] - odo_world
        turn = float(wrap_angle(rotations[b] - rotations[a] - odo_rel[2]))
        return position, np.array([turn])
    matrix = matrix_from_quat_wxyz(rotations[a])
    return delta - matrix @ np.array([odo_rel[0], odo_rel[1], 0.0]), np.zeros(3)
