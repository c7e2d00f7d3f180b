"""Relative pose error (RPE) and the KITTI segment metric.

RPE (evo's definition, TUM RGB-D benchmark notation): for a pose pair (i, j),
``E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j)`` with Q the reference and P the estimate; the
translation error is ``||trans(E)||`` [m], the rotation error the angle of ``rot(E)`` [deg].
Pairs are consecutive and chosen on the estimate (evo's default, ``all_pairs=False``):
by frame offset ``(0, d), (d, 2d), ...`` or by travelled distance (a new pair end whenever
the estimate's path since the last one reaches ``delta`` metres).

KITTI (Geiger et al., odometry devkit ``evaluate_odometry.cpp``): from every ``step``-th
frame, for each length L in 100, 200, ..., 800 m of *reference* path, the first frame whose
reference path distance exceeds L; pose error ``(P_i^-1 P_j)^-1 (Q_i^-1 Q_j)``; translation
error divided by L (reported in %) and rotation angle divided by L (reported in deg/100 m),
averaged over all segments.

Planar trajectories are treated as 3-D ones with z = 0 (rotation about z).
"""

from __future__ import annotations

import numpy as np

from datasets.errors import InputError
from datasets.trajectory import Trajectory
from workbench.metrics.alignment import ALIGNMENTS, apply_alignment, estimate_alignment, lift_to_3d
from workbench.metrics.ate import error_statistics, paired_trajectories
from workbench.metrics.timestamps import DEFAULT_MAX_DIFF_S

KITTI_LENGTHS_M = (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0)
RPE_UNITS = ("frames", "m")


def pairs_by_frames(count: int, delta: int) -> np.ndarray:
    """Consecutive index pairs ``(0, d), (d, 2d), ...`` among ``count`` poses, shape (K, 2)."""
    if delta < 1:
        raise InputError(f"--delta in frames must be a positive integer, got {delta}")
    starts = np.arange(0, count, int(delta))
    return np.column_stack([starts[:-1], starts[1:]]).astype(int)


def pairs_by_distance(positions: np.ndarray, delta_m: float) -> np.ndarray:
    """Consecutive index pairs whose path length just reaches ``delta_m`` (evo's
    ``filter_pairs_by_path`` without ``all_pairs``), shape (K, 2).

    Args:
        positions: shape (N, d) [m], the poses the pairs are chosen on.
        delta_m: path length per pair [m], > 0.
    """
    if not delta_m > 0:
        raise InputError(f"--delta in metres must be positive, got {delta_m}")
    steps = np.linalg.norm(np.diff(positions, axis=0), axis=1)
    ends = [0]
    travelled = 0.0
    # Sequential on purpose: the running sum restarts at each pair end, as in evo.
    for index, step in enumerate(steps, start=1):
        travelled += float(step)
        if travelled >= delta_m:
            ends.append(index)
            travelled = 0.0
    ends_array = np.array(ends, dtype=int)
    return np.column_stack([ends_array[:-1], ends_array[1:]]).astype(int)


def _inverse_se3(poses: np.ndarray) -> np.ndarray:
    """Inverse of homogeneous rigid transforms, shape (K, 4, 4)."""
    inverse = np.tile(np.eye(4), (len(poses), 1, 1))
    rotation_t = np.transpose(poses[:, :3, :3], (0, 2, 1))
    inverse[:, :3, :3] = rotation_t
    inverse[:, :3, 3] = -np.einsum("nij,nj->ni", rotation_t, poses[:, :3, 3])
    return inverse


def rotation_angles(rotations: np.ndarray) -> np.ndarray:
    """Rotation angles [rad] in [0, pi] of rotation matrices (K, 3, 3).

    ``atan2(|skew part|, trace part)`` is the angle of the logarithm, accurate also near 0
    and pi (unlike the devkit's ``acos((tr - 1) / 2)``, which it equals mathematically).
    """
    skew = np.stack(
        [
            rotations[:, 2, 1] - rotations[:, 1, 2],
            rotations[:, 0, 2] - rotations[:, 2, 0],
            rotations[:, 1, 0] - rotations[:, 0, 1],
        ],
        axis=1,
    )
    trace = np.trace(rotations, axis1=1, axis2=2)
    return np.arctan2(0.5 * np.linalg.norm(skew, axis=1), 0.5 * (trace - 1.0))


def relative_errors(
    reference: np.ndarray, estimate: np.ndarray, pairs: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """RPE of index pairs on homogeneous poses (N, 4, 4).

    Returns:
        (translation errors [m] shape (K,), rotation errors [rad] shape (K,)).
    """
    first, second = pairs[:, 0], pairs[:, 1]
    ref_relative = np.einsum("nij,njk->nik", _inverse_se3(reference[first]), reference[second])
    est_relative = np.einsum("nij,njk->nik", _inverse_se3(estimate[first]), estimate[second])
    error = np.einsum("nij,njk->nik", _inverse_se3(ref_relative), est_relative)
    return np.linalg.norm(error[:, :3, 3], axis=1), rotation_angles(error[:, :3, :3])


def rpe_errors(
    reference: Trajectory, estimate: Trajectory, delta: float, unit: str = "frames"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """RPE of already paired (and, if wanted, aligned) trajectories.

    Returns:
        (pairs (K, 2), translation errors [m] (K,), rotation errors [deg] (K,)).

    Raises:
        InputError: bad ``unit``/``delta``, or no pair at all for this ``delta``.
    """
    if unit not in RPE_UNITS:
        raise InputError(f"unknown RPE unit {unit!r}; choose one of {', '.join(RPE_UNITS)}")
    reference, estimate = lift_to_3d(reference), lift_to_3d(estimate)
    if unit == "frames":
        if not float(delta).is_integer():
            raise InputError(f"--delta in frames must be an integer, got {delta}")
        pairs = pairs_by_frames(len(estimate), int(delta))
    else:
        pairs = pairs_by_distance(estimate.positions, float(delta))
    if len(pairs) == 0:
        raise InputError(
            f"--delta {delta:g} {unit} gives no pose pair among {len(estimate)} poses; "
            "try a smaller --delta"
        )
    trans, rot = relative_errors(reference.homogeneous(), estimate.homogeneous(), pairs)
    return pairs, trans, np.rad2deg(rot)


def rpe_report(
    reference: Trajectory,
    estimate: Trajectory,
    delta: float = 1,
    unit: str = "frames",
    align: str = "none",
    max_diff_s: float = DEFAULT_MAX_DIFF_S,
    allow_degenerate: bool = False,
) -> dict[str, object]:
    """RPE of ``estimate`` against ``reference`` as a JSON-serialisable dict (``evo_rpe``).

    Poses are paired by time as in evo, the estimate optionally aligned (a rigid alignment
    does not change the RPE; ``sim3`` rescales it), then pairs chosen on the estimate.

    Keys: ``trans_rmse_m`` (and mean/median/std/min/max ``_m``), ``rot_rmse_deg`` (and the
    same statistics ``_deg``), ``pairs``, ``delta``, ``unit``, ``align``, ``max_diff_s``.
    """
    if align not in ALIGNMENTS:
        raise InputError(f"unknown alignment {align!r}; choose one of {', '.join(ALIGNMENTS)}")
    ref_paired, est_paired = paired_trajectories(reference, estimate, max_diff_s)
    alignment = estimate_alignment(ref_paired, est_paired, align, allow_degenerate)
    aligned = apply_alignment(est_paired, alignment)
    pairs, trans, rot_deg = rpe_errors(ref_paired, aligned, delta, unit)
    report: dict[str, object] = {}
    report.update({f"trans_{name}_m": value for name, value in error_statistics(trans).items()})
    report.update({f"rot_{name}_deg": value for name, value in error_statistics(rot_deg).items()})
    report.update(
        {
            "pairs": int(len(pairs)),
            "delta": float(delta),
            "unit": unit,
            "align": align,
            "max_diff_s": float(max_diff_s),
        }
    )
    return report


def kitti_segment_errors(
    reference: Trajectory,
    estimate: Trajectory,
    lengths_m: tuple[float, ...] = KITTI_LENGTHS_M,
    step: int = 10,
) -> dict[str, float | int | None]:
    """KITTI odometry segment metric of already paired trajectories.

    Args:
        reference, estimate: paired pose for pose.
        lengths_m: segment lengths along the reference path [m].
        step: start a segment at every ``step``-th frame (the devkit uses 10 at 10 Hz).

    Returns:
        ``translation_percent`` (mean of t_err / L, x 100), ``rotation_deg_per_100m`` (mean
        of r_err / L in deg/m, x 100), ``segments``; None values when the path is shorter
        than the shortest length.
    """
    reference, estimate = lift_to_3d(reference), lift_to_3d(estimate)
    distances = np.concatenate(
        [[0.0], np.cumsum(np.linalg.norm(np.diff(reference.positions, axis=0), axis=1))]
    )
    starts = np.arange(0, len(reference), step)
    first_parts, last_parts, length_parts = [], [], []
    for length in lengths_m:
        # First frame whose travelled distance exceeds the segment length (devkit's
        # lastFrameFromSegmentLength, strict ">").
        ends = np.searchsorted(distances, distances[starts] + length, side="right")
        found = ends < len(reference)
        first_parts.append(starts[found])
        last_parts.append(ends[found])
        length_parts.append(np.full(int(np.sum(found)), length))
    firsts, lasts = np.concatenate(first_parts), np.concatenate(last_parts)
    if len(firsts) == 0:
        return {"translation_percent": None, "rotation_deg_per_100m": None, "segments": 0}
    pairs = np.column_stack([firsts, lasts])
    # The devkit's error (P_rel^-1 Q_rel) is the inverse of evo's (Q_rel^-1 P_rel): same
    # angle; the translation norms differ by a rotation only, so the norm is the same too.
    trans, rot = relative_errors(reference.homogeneous(), estimate.homogeneous(), pairs)
    lengths_array = np.concatenate(length_parts)
    return {
        "translation_percent": float(100.0 * np.mean(trans / lengths_array)),
        "rotation_deg_per_100m": float(100.0 * np.rad2deg(np.mean(rot / lengths_array))),
        "segments": int(len(pairs)),
    }
