"""The entry points: ``assess_truth`` runs the checks in order on one truth stream
(timing, freezes, bursts, heading, motion, then pairs jumps into wrong tracks) and
returns a ``TruthQuality``; ``assess_trajectory`` turns it into what a loader's
``Sequence`` carries (the excluded intervals and the warning lines)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from datasets.errors import InputError
from datasets.rotations import matrix_from_quat_wxyz
from datasets.truth_quality.freezes import _freezes
from datasets.truth_quality.heading import _heading
from datasets.truth_quality.intervals import TruthInterval, TruthKind, merged_spans
from datasets.truth_quality.jumps import _bursts, _Jump, _jump_words
from datasets.truth_quality.motion import _motion
from datasets.truth_quality.pairing import _pair
from datasets.truth_quality.quality import TruthQuality
from datasets.truth_quality.settings import TruthQualitySettings
from datasets.truth_quality.steps import _judge, _rotation_increments
from datasets.truth_quality.timing import _timing

if TYPE_CHECKING:
    from datasets.odometry_calibration import Increments


def _merged_same_kind(intervals: list[TruthInterval]) -> list[TruthInterval]:
    """Overlapping intervals of one kind joined (evidence of the first, with a count)."""
    result: list[TruthInterval] = []
    for kind in TruthKind:
        group = sorted((i for i in intervals if i.kind == kind), key=lambda i: i.start_s)
        current: list[TruthInterval] = []
        for interval in group:
            if current and interval.start_s <= max(i.end_s for i in current):
                current.append(interval)
                continue
            if current:
                result.append(_join(current))
            current = [interval]
        if current:
            result.append(_join(current))
    return sorted(result, key=lambda i: (i.start_s, i.end_s, i.kind.value))


def _join(group: list[TruthInterval]) -> TruthInterval:
    if len(group) == 1:
        return group[0]
    worst = group[0].evidence
    return TruthInterval(
        group[0].start_s,
        max(i.end_s for i in group),
        group[0].kind,
        f"{len(group)} overlapping windows, the first: {worst}",
    )


def assess_truth(
    t: np.ndarray,
    positions: np.ndarray,
    rotations: np.ndarray | None = None,
    motion: Increments | None = None,
    settings: TruthQualitySettings = TruthQualitySettings(),  # noqa: B008 (frozen)
) -> TruthQuality:
    """Find where a truth stream cannot be trusted (``datasets.truth_quality`` docstring: the
    kinds, the tests).

    Args:
        t: sample times [s], shape (N,), strictly increasing.
        positions: world positions [m], shape (N, 2) or (N, 3).
        rotations: planar headings [rad] shape (N,), body-to-world quaternions (w, x, y, z)
            shape (N, 4), or None (positions only, e.g. GPS).
        motion: the vehicle's odometry, independent of the truth, as planar increments
            (``datasets.odometry_calibration.Increments``: end times [s] (M,), durations [s]
            (M,), body-frame (dx [m], dy [m], dtheta [rad]) (M, 3)), on the truth's clock;
            None skips the motion check.
        settings: the thresholds.

    Returns:
        ``TruthQuality``: the intervals, sorted by start, and the thresholds used.

    Raises:
        InputError: shapes that disagree, non-finite values, times that do not increase.
    """
    t = np.asarray(t, dtype=float)
    positions = np.asarray(positions, dtype=float)
    count = len(t)
    if t.ndim != 1 or positions.ndim != 2 or positions.shape != (count, positions.shape[1]):
        raise InputError(
            f"truth times (N,) and positions (N, d) disagree: {t.shape}, {positions.shape}"
        )
    if positions.shape[1] not in (2, 3):
        raise InputError(f"truth positions must be (N, 2) or (N, 3), got {positions.shape}")
    if rotations is not None:
        rotations = np.asarray(rotations, dtype=float)
        if rotations.shape not in ((count,), (count, 4)):
            raise InputError(
                f"truth rotations must be headings (N,) or quaternions (N, 4), got {rotations.shape}"
            )
    planar = rotations.ndim == 1 if rotations is not None else positions.shape[1] == 2
    for name, values in (("times", t), ("positions", positions), ("rotations", rotations)):
        if values is not None and not np.all(np.isfinite(values)):
            raise InputError(f"truth {name} hold non-finite values")
    if count < 3:
        span = (float(t[0]), float(t[-1])) if count else (0.0, 0.0)
        return TruthQuality((), count, span[0], span[1], 0.0, {}, settings)
    dt = np.diff(t)
    if np.any(dt <= 0):
        index = int(np.flatnonzero(dt <= 0)[0])
        raise InputError(
            f"truth times must increase: sample {index + 1} at {t[index + 1]:.6f} s follows "
            f"{t[index]:.6f} s"
        )
    step = float(np.median(dt))

    intervals, dropout_steps = _timing(t, dt, step, settings)
    assessed = ~dropout_steps  # a step across a gap has no local velocity to judge it by
    position = _judge(
        np.diff(positions, axis=0), dt, assessed, settings, settings.jump_floor_m, False
    )
    rotation = None
    if rotations is not None:
        rotation = _judge(
            _rotation_increments(rotations, planar),
            dt,
            assessed,
            settings,
            settings.jump_floor_rad,
            True,
        )
    thresholds = {
        "median_step_s": step,
        "jump_threshold_m": position.threshold,
        "position_sigma_m": position.sigma,
        "fast_step_m": position.fast_step,
    }
    if rotation is not None:
        thresholds.update(
            jump_threshold_rad=rotation.threshold,
            rotation_sigma_rad=rotation.sigma,
            fast_step_rad=rotation.fast_step,
        )

    frozen, explained = _freezes(t, positions, rotations, position, rotation, settings)
    intervals += frozen
    jumps, spikes = _bursts(position, rotation, explained, settings)
    for first, last, evidence in spikes:
        intervals.append(
            TruthInterval(float(t[first + 1]), float(t[last]), TruthKind.WRONG_TRACK, evidence)
        )

    # steps whose neighbourhood is already explained: no chord or window is judged over them
    broken = dropout_steps | explained
    for first, last in [(j.first, j.last) for j in jumps] + [(a, b) for a, b, _ in spikes]:
        broken[first : last + 1] = True
    check_heading = settings.heading_check if settings.heading_check is not None else planar
    if check_heading and rotations is not None:
        if planar:
            forward = np.column_stack([np.cos(rotations), np.sin(rotations)])
        else:
            forward = matrix_from_quat_wxyz(rotations)[:, :, 0]
        chord_positions = positions[:, : forward.shape[1]]
        found, stats = _heading(t, chord_positions, forward, position, broken, settings)
        intervals += found
        thresholds.update(stats)
    motion_jumps: list[_Jump] = []
    if motion is not None:
        limits = (position.threshold, rotation.threshold if rotation is not None else math.inf)
        motion_jumps, stats = _motion(
            t, positions, rotations, planar, motion, broken, limits, settings
        )
        thresholds.update(stats)

    pairs, alone = _pair(jumps, t, settings)
    if motion_jumps:
        # the odometry's disagreements inside a wrong track the steps already bound are
        # that track; the others pair with what the steps left alone
        inside = [(away.first, back.last) for away, back in pairs]
        outside = [
            jump
            for jump in motion_jumps
            if not any(first <= jump.first and jump.last <= last for first, last in inside)
        ]
        more, alone = _pair(sorted(alone + outside, key=lambda jump: jump.first), t, settings)
        pairs += more
    for away, back in pairs:
        # the samples after the first step away up to the last step back are off
        inside = back.last - away.first
        intervals.append(
            TruthInterval(
                float(t[away.first + 1]),
                float(t[back.last]),
                TruthKind.WRONG_TRACK,
                f"away by {_jump_words(away, planar)} at {t[away.first + 1]:.3f} s and back by "
                f"{_jump_words(back, planar)} at {t[back.last + 1]:.3f} s ({inside} samples off"
                + (
                    ", smooth edges the odometry contradicts)"
                    if away.motion_evidence or back.motion_evidence
                    else ")"
                ),
            )
        )
    for jump in alone:
        if jump.motion_evidence is not None:
            intervals.append(
                TruthInterval(
                    float(t[jump.first]),
                    float(t[jump.last + 1]),
                    TruthKind.MOTION,
                    jump.motion_evidence,
                )
            )
            continue
        intervals.append(
            TruthInterval(
                float(t[jump.first]),
                float(t[jump.last + 1]),
                TruthKind.JUMP,
                f"a step of {_jump_words(jump, planar)} beyond the local motion, not undone "
                f"(thresholds {position.threshold:.3g} m"
                + (f", {rotation.threshold:.3g} rad)" if rotation is not None else ")"),
            )
        )
    return TruthQuality(
        tuple(_merged_same_kind(intervals)),
        count,
        float(t[0]),
        float(t[-1]),
        step,
        thresholds,
        settings,
    )


def assess_trajectory(
    truth_t: np.ndarray,
    positions: np.ndarray,
    rotations: np.ndarray | None,
    source: str,
    sampled_only: bool = False,
    settings: TruthQualitySettings = TruthQualitySettings(),  # noqa: B008 (frozen)
) -> tuple[tuple[TruthInterval, ...], list[str]]:
    """``assess_truth`` of a loader's truth stream, as what a ``Sequence`` carries: the
    intervals for ``GroundTruth.excluded`` and the warning lines (none when all is trusted),
    each naming ``source`` (e.g. ``topic /ground_truth``, ``held-out GPS fixes``).

    ``sampled_only``: the truth is compared only at its own samples, never interpolated
    (held-out GPS fixes): a dropout or a rate change removes nothing from the scoring, so
    only the intervals that do (freezes, jumps, wrong tracks, ...) are returned."""
    if len(truth_t) < 3:
        return (), []
    quality = assess_truth(truth_t, positions, rotations, settings=settings)
    timing = (TruthKind.DROPOUT, TruthKind.RATE_CHANGE)
    intervals = tuple(
        interval for interval in quality.intervals if not (sampled_only and interval.kind in timing)
    )
    if not intervals:
        return (), []
    spans = merged_spans(intervals)
    excluded_s = float(np.sum(spans[:, 1] - spans[:, 0]))
    shown = "; ".join(" ".join(interval.line().split()) for interval in intervals[:5])
    more = "; ..." if len(intervals) > 5 else ""
    return intervals, [
        f"{source} not trusted in {len(intervals)} interval(s), {excluded_s:.2f} s, excluded "
        f"from the scoring (datasets.truth_quality): {shown}{more}"
    ]
