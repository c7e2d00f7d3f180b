"""Pairing two trajectories by time, and looking truth up at given times.

Two jobs, both about time stamps:

* ``matching_time_indices`` / ``associate`` reproduce evo's nearest-stamp association
  (``evo.core.sync.matching_time_indices`` and ``associate_trajectories``, evo 1.38) index
  for index, so ``workbench metrics ate`` and ``evo_ape`` compare the same pose pairs.
* ``vectors_at`` / ``trajectory_at`` give a true state at an estimator's times: the exact
  sample when one lies within ``EXACT_TOLERANCE_S``, otherwise linear interpolation of
  vectors and spherical linear interpolation (slerp) of rotations between the two
  neighbouring samples. Times outside the truth's span get no value (a mask says which),
  and neither do times the truth cannot vouch for: inside an excluded interval
  (``GroundTruth.excluded``), next to an excluded sample (interpolating from it), or
  between two samples more than ``MAX_INTERPOLATION_STEPS`` median steps apart (a
  straight line across a gap is not truth).

``trusted_samples`` and ``straddles`` serve the scorers that pair by nearest stamp (ATE,
RPE, the evo result files): the former drops excluded reference samples before pairing,
the latter finds consecutive pairs whose interval holds an excluded one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from datasets.errors import InputError
from datasets.rotations import quat_wxyz_from_rotation, rotation_from_quat_wxyz, wrap_angle
from datasets.trajectory import Trajectory
from datasets.truth_quality.intervals import TruthInterval, excluded_mask, merged_spans
from datasets.truth_quality.settings import TruthQualitySettings

DEFAULT_MAX_DIFF_S = 0.01
"""evo's default ``--t_max_diff`` [s]."""

EXACT_TOLERANCE_S = 1e-6
"""Two stamps closer than this [s] are the same instant (no interpolation)."""

MAX_INTERPOLATION_STEPS = float(TruthQualitySettings.model_fields["dropout_min_steps"].default)
"""Truth is interpolated only between samples at most this many median steps apart (4):
the truth-quality detector calls a longer gap a dropout, so what one refuses the other
reports."""


def matching_time_indices(
    stamps_1: np.ndarray,
    stamps_2: np.ndarray,
    max_diff_s: float = DEFAULT_MAX_DIFF_S,
    offset_2_s: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the best-matching stamps, exactly as evo's ``matching_time_indices``.

    Every stamp of ``stamps_1`` is paired with the nearest stamp of ``stamps_2 + offset_2_s``
    when that one is at most ``max_diff_s`` away (a tie goes to the earlier stamp). A stamp
    of ``stamps_2`` may be used more than once, as in evo.

    Args:
        stamps_1: times [s], shape (N1,).
        stamps_2: times [s], shape (N2,).
        max_diff_s: largest accepted time difference [s].
        offset_2_s: offset added to ``stamps_2`` [s].

    Returns:
        (indices into stamps_1, indices into stamps_2), int arrays of equal length.
    """
    stamps_1 = np.asarray(stamps_1, dtype=float)
    stamps_2 = np.asarray(stamps_2, dtype=float) + offset_2_s
    if len(stamps_1) == 0 or len(stamps_2) == 0:
        return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
    if not np.all(np.diff(stamps_2) >= 0):
        # evo's linear fallback for unsorted stamps: argmin picks the first minimum.
        diffs = np.abs(stamps_2[None, :] - stamps_1[:, None])
        best = np.argmin(diffs, axis=1)
        keep = diffs[np.arange(len(stamps_1)), best] <= max_diff_s
        return np.flatnonzero(keep), best[keep]

    inside = ~((stamps_1 < stamps_2[0] - max_diff_s) | (stamps_1 > stamps_2[-1] + max_diff_s))
    upper = np.minimum(np.searchsorted(stamps_2, stamps_1, side="right"), len(stamps_2) - 1)
    diff_ub = stamps_2[upper] - stamps_1
    diff_lb = np.where(upper > 0, stamps_1 - stamps_2[np.maximum(upper - 1, 0)], np.inf)
    take_upper = (diff_ub <= max_diff_s) & (diff_ub < diff_lb)
    take_lower = ~take_upper & (diff_lb <= max_diff_s) & (diff_lb <= diff_ub)
    keep = inside & (take_upper | take_lower)
    best = np.where(take_upper, upper, upper - 1)
    return np.flatnonzero(keep), best[keep].astype(int)


def associate(
    reference: Trajectory, estimate: Trajectory, max_diff_s: float = DEFAULT_MAX_DIFF_S
) -> tuple[np.ndarray, np.ndarray]:
    """Pose pairs of two trajectories, as evo's ``associate_trajectories`` (nearest time).

    evo starts from the trajectory with fewer poses (the estimate when both are equally
    long) so that none of its poses is lost, and pairs each of its stamps with the nearest
    stamp of the other one within ``max_diff_s``.

    Returns:
        (reference indices, estimate indices), int arrays of equal length >= 1.

    Raises:
        InputError: when no stamps are within ``max_diff_s`` of each other.
    """
    second_longer = len(estimate) > len(reference)
    if second_longer:
        ref_indices, est_indices = matching_time_indices(reference.t, estimate.t, max_diff_s)
    else:
        est_indices, ref_indices = matching_time_indices(estimate.t, reference.t, max_diff_s)
    if len(ref_indices) == 0:
        raise InputError(
            f"no matching timestamps between reference ({_span(reference.t)}) and estimate "
            f"({_span(estimate.t)}) within {max_diff_s:g} s"
        )
    return ref_indices, est_indices


def _span(times: np.ndarray) -> str:
    if len(times) == 0:
        return "no poses"
    return f"{len(times)} poses, t {times[0]:.6f}..{times[-1]:.6f} s"


def interpolation_limit_s(sample_times: np.ndarray) -> float:
    """The longest gap [s] truth is interpolated across: ``MAX_INTERPOLATION_STEPS`` times
    the median positive step of ``sample_times`` (inf with fewer than two distinct times)."""
    steps = np.diff(np.asarray(sample_times, dtype=float))
    steps = steps[steps > 0]
    return MAX_INTERPOLATION_STEPS * float(np.median(steps)) if len(steps) else math.inf


def _brackets(
    sample_times: np.ndarray,
    query_times: np.ndarray,
    max_gap_s: float | None = None,
    excluded: Sequence[TruthInterval] = (),
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """For each query: the samples around it, the interpolation weight, and a validity mask.

    Returns (lower index, upper index, weight of the upper sample in [0, 1], valid); a query
    within ``EXACT_TOLERANCE_S`` of a sample uses that sample alone (lower == upper). A query
    is invalid outside the sampled span, between two samples more than ``max_gap_s`` apart
    (None: ``interpolation_limit_s``), inside an ``excluded`` interval, or when a sample it
    uses lies inside one.
    """
    sample_times = np.asarray(sample_times, dtype=float)
    query_times = np.asarray(query_times, dtype=float)
    count = len(sample_times)
    if count == 0:
        nothing = np.zeros(len(query_times), dtype=int)
        return nothing, nothing, np.zeros(len(query_times)), np.zeros(len(query_times), dtype=bool)

    after = np.clip(np.searchsorted(sample_times, query_times), 0, count - 1)
    before = np.clip(after - 1, 0, count - 1)
    nearest = np.where(
        np.abs(sample_times[before] - query_times) < np.abs(sample_times[after] - query_times),
        before,
        after,
    )
    exact = np.abs(sample_times[nearest] - query_times) <= EXACT_TOLERANCE_S

    upper = np.clip(np.searchsorted(sample_times, query_times, side="right"), 0, count - 1)
    lower = np.maximum(upper - 1, 0)
    gap = sample_times[upper] - sample_times[lower]
    safe_gap = np.where(gap > 0, gap, 1.0)
    weight = np.where(
        gap > 0, np.clip((query_times - sample_times[lower]) / safe_gap, 0.0, 1.0), 0.0
    )
    inside = (query_times >= sample_times[0]) & (query_times <= sample_times[-1])
    limit = interpolation_limit_s(sample_times) if max_gap_s is None else max_gap_s
    inside &= gap <= limit  # never a straight line across a gap

    lower = np.where(exact, nearest, lower)
    upper = np.where(exact, nearest, upper)
    weight = np.where(exact, 0.0, weight)
    valid = exact | inside
    if len(excluded):
        trusted_sample = ~excluded_mask(sample_times, tuple(excluded))
        valid &= ~excluded_mask(query_times, tuple(excluded))
        valid &= trusted_sample[lower] & trusted_sample[upper]
    return lower, upper, weight, valid


def vectors_at(
    sample_times: np.ndarray,
    values: np.ndarray,
    query_times: np.ndarray,
    excluded: Sequence[TruthInterval] = (),
    max_gap_s: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Vector samples at ``query_times``: exact match within 1e-6 s, else linear interpolation.

    Args:
        sample_times: shape (N,), non-decreasing [s].
        values: shape (N, k).
        query_times: shape (Q,) [s].
        excluded: intervals where the samples are not trusted (``GroundTruth.excluded``): no
            value inside them or from a sample inside them.
        max_gap_s: longest gap [s] to interpolate across; None: ``MAX_INTERPOLATION_STEPS``
            median steps of ``sample_times`` (truth); ``math.inf`` for an estimate, whose
            own stamps are what it reported.

    Returns:
        (values at the valid queries, shape (V, k); valid mask, shape (Q,)).
    """
    lower, upper, weight, valid = _brackets(sample_times, query_times, max_gap_s, excluded)
    values = np.asarray(values, dtype=float)
    if not np.any(valid):
        return np.zeros((0,) + values.shape[1:]), valid
    w = weight[valid][:, None]
    return (1.0 - w) * values[lower[valid]] + w * values[upper[valid]], valid


def trajectory_at(
    truth: Trajectory,
    query_times: np.ndarray,
    excluded: Sequence[TruthInterval] = (),
    max_gap_s: float | None = None,
) -> tuple[Trajectory, np.ndarray]:
    """``truth`` at ``query_times``: exact samples within 1e-6 s, else interpolated.

    Positions are interpolated linearly; 3-D rotations by slerp between the neighbouring
    samples; planar headings linearly along the shorter arc. Covariances are dropped.
    ``excluded`` and ``max_gap_s`` as in ``vectors_at``.

    Returns:
        (trajectory at the valid queries, valid mask of shape (Q,)).
    """
    query_times = np.asarray(query_times, dtype=float)
    lower, upper, weight, valid = _brackets(truth.t, query_times, max_gap_s, excluded)
    lower, upper, weight = lower[valid], upper[valid], weight[valid]
    w = weight[:, None]
    positions = (1.0 - w) * truth.positions[lower] + w * truth.positions[upper]
    if truth.dimension == 3:
        rotations = _slerp_pairs(truth.rotations[lower], truth.rotations[upper], weight)
    else:
        step = wrap_angle(truth.rotations[upper] - truth.rotations[lower])
        interpolated = np.asarray(wrap_angle(truth.rotations[lower] + weight * step), dtype=float)
        rotations = np.where(weight == 0.0, truth.rotations[lower], interpolated)
    return Trajectory(t=query_times[valid], positions=positions, rotations=rotations), valid


def trusted_samples(reference: Trajectory, excluded: Sequence[TruthInterval]) -> Trajectory:
    """``reference`` without its samples inside an ``excluded`` interval (the same object
    when nothing is excluded, so unaffected scores stay bit for bit)."""
    if not len(excluded):
        return reference
    return reference.select(np.flatnonzero(~excluded_mask(reference.t, tuple(excluded))))


def straddles(
    first_t: np.ndarray, second_t: np.ndarray, excluded: Sequence[TruthInterval]
) -> np.ndarray:
    """(K,) bool: True where an ``excluded`` interval meets ``[first_t, second_t]`` [s]
    (shapes (K,)): a relative error over it would span untrusted truth."""
    first_t = np.asarray(first_t, dtype=float)
    second_t = np.asarray(second_t, dtype=float)
    spans = merged_spans(tuple(excluded))
    if len(spans) == 0:
        return np.zeros(first_t.shape, dtype=bool)
    # the last span starting at or before the pair's end meets the pair if it ends after
    # the pair's start (spans are disjoint and sorted)
    index = np.searchsorted(spans[:, 0], second_t, side="right") - 1
    meets = index >= 0
    meets[meets] = spans[index[meets], 1] >= first_t[meets]
    return meets


def _slerp_pairs(quat_a: np.ndarray, quat_b: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Slerp between matching rows of two (N, 4) wxyz quaternion arrays at weights (N,)."""
    if len(weight) == 0:
        return np.zeros((0, 4))
    rot_a = rotation_from_quat_wxyz(quat_a)
    rot_b = rotation_from_quat_wxyz(quat_b)
    # a * Exp(w * Log(a^-1 b)) is slerp along the shorter arc, vectorised over rows.
    relative = (rot_a.inv() * rot_b).as_rotvec()
    result = quat_wxyz_from_rotation(rot_a * Rotation.from_rotvec(weight[:, None] * relative))
    # Exact samples are returned bit for bit (no round trip through scipy).
    at_start = weight == 0.0
    result[at_start] = quat_a[at_start]
    return result
