"""Absolute trajectory error (ATE): position error after alignment.

Definition (evo's APE with ``pose_relation=translation_part``): pair the poses by time
(``timestamps.associate``), align the estimate to the reference (``alignment``), and take
``e_i = || p_est_aligned(t_i) - p_ref(t_i) ||`` [m]. ``ate_report`` with ``align="se3"``
reproduces ``evo_ape tum REF EST -a`` (RMSE and the other statistics), ``"sim3"``
``evo_ape ... -as``, ``"none"`` plain ``evo_ape``.
"""

from __future__ import annotations

import math

import numpy as np

from datasets.errors import InputError
from datasets.trajectory import Trajectory
from workbench.metrics.alignment import (
    ALIGNMENTS,
    Alignment,
    apply_alignment,
    estimate_alignment,
    lift_to_3d,
)
from workbench.metrics.timestamps import DEFAULT_MAX_DIFF_S, _span, associate


def error_statistics(errors: np.ndarray) -> dict[str, float]:
    """rmse, mean, median, std, min, max of an error array (evo's statistics), as floats."""
    errors = np.asarray(errors, dtype=float)
    if errors.size == 0:
        raise InputError("no errors to summarise (no pose pairs)")
    return {
        "rmse": math.sqrt(float(np.mean(errors**2))),
        "mean": float(np.mean(errors)),
        "median": float(np.median(errors)),
        "std": float(np.std(errors)),
        "min": float(np.min(errors)),
        "max": float(np.max(errors)),
    }


def paired_trajectories(
    reference: Trajectory, estimate: Trajectory, max_diff_s: float = DEFAULT_MAX_DIFF_S
) -> tuple[Trajectory, Trajectory]:
    """The two trajectories reduced to their time-paired poses (evo's association).

    A planar and a spatial trajectory are paired after lifting the planar one to 3-D.
    ``InputError`` when their time spans do not overlap (at most their ends touch, within
    ``max_diff_s``): the one or two pairs there are no trajectory to compare.
    """
    if len(reference) > 1 and len(estimate) > 1:
        shared_s = min(reference.t[-1], estimate.t[-1]) - max(reference.t[0], estimate.t[0])
        if shared_s <= 0:
            raise InputError(
                f"the reference ({_span(reference.t)}) and the estimate ({_span(estimate.t)}) "
                "do not overlap in time: no matching timestamps to compare"
            )
    if reference.dimension != estimate.dimension:
        reference, estimate = lift_to_3d(reference), lift_to_3d(estimate)
    ref_indices, est_indices = associate(reference, estimate, max_diff_s)
    return reference.select(ref_indices), estimate.select(est_indices)


def ate_errors(
    reference: Trajectory, estimate: Trajectory, align: str = "se3", allow_degenerate: bool = False
) -> tuple[np.ndarray, Alignment, Trajectory]:
    """Per-pose position errors of already paired trajectories.

    Args:
        reference, estimate: equally long, pose i of one paired with pose i of the other.
        align: one of ``ALIGNMENTS``.
        allow_degenerate: see ``alignment.umeyama`` (a static or straight-line trajectory).

    Returns:
        (errors [m] shape (N,), the alignment used, the aligned estimate).
    """
    alignment = estimate_alignment(reference, estimate, align, allow_degenerate)
    aligned = apply_alignment(estimate, alignment)
    ref_positions = (
        reference.positions
        if aligned.dimension == reference.dimension
        else lift_to_3d(reference).positions
    )
    return np.linalg.norm(aligned.positions - ref_positions, axis=1), alignment, aligned


def ate_report(
    reference: Trajectory,
    estimate: Trajectory,
    align: str = "se3",
    max_diff_s: float = DEFAULT_MAX_DIFF_S,
    allow_degenerate: bool = False,
) -> dict[str, object]:
    """ATE of ``estimate`` against ``reference`` as a JSON-serialisable dict.

    Keys: ``rmse_m``, ``mean_m``, ``median_m``, ``std_m``, ``min_m``, ``max_m``, ``pairs``,
    ``reference_poses``, ``estimate_poses``, ``align``, ``max_diff_s``, ``alignment``
    (rotation, translation_m, scale).

    Raises:
        InputError: unknown ``align``, no stamps within ``max_diff_s``, or a degenerate
            alignment (evo refuses those too) unless ``allow_degenerate``.
    """
    if align not in ALIGNMENTS:
        raise InputError(f"unknown alignment {align!r}; choose one of {', '.join(ALIGNMENTS)}")
    ref_paired, est_paired = paired_trajectories(reference, estimate, max_diff_s)
    errors, alignment, _ = ate_errors(ref_paired, est_paired, align, allow_degenerate)
    stats = error_statistics(errors)
    return {
        **{f"{name}_m": value for name, value in stats.items()},
        "pairs": int(len(errors)),
        "reference_poses": int(len(reference)),
        "estimate_poses": int(len(estimate)),
        "align": align,
        "max_diff_s": float(max_diff_s),
        "alignment": alignment.as_dict(),
    }
