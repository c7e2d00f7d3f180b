"""Bursts of unexplained steps: each either a ``_Jump`` (a net change that a later jump
must undo) or a spike (steps that cancel: a ``wrong_track`` of the samples inside it);
and the words that describe a jump."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from datasets.rotations import wrap_angle
from datasets.truth_quality.settings import TruthQualitySettings
from datasets.truth_quality.steps import _Increments, _runs


@dataclass
class _Jump:
    """Consecutive flagged steps ``first..last`` (step k joins samples k and k+1), their
    net change beyond the local motion and which parts of it are significant. A jump found
    by the motion check (a smooth departure that odometry contradicts) carries its evidence
    and, left unpaired, stays a ``motion`` interval."""

    first: int
    last: int
    position: np.ndarray
    rotation: np.ndarray
    position_significant: bool
    rotation_significant: bool
    motion_evidence: str | None = None


def _jump_words(jump: _Jump, planar: bool) -> str:
    parts = []
    if jump.position_significant:
        parts.append(f"{np.linalg.norm(jump.position):.3f} m")
    if jump.rotation_significant:
        angle = float(jump.rotation[0]) if planar else float(np.linalg.norm(jump.rotation))
        parts.append(f"{angle:+.2f} rad" if planar else f"{angle:.2f} rad")
    return " and ".join(parts)


def _wrapped_rotation(vector: np.ndarray) -> np.ndarray:
    """The rotation vector (or heading) of the same rotation with the smallest angle."""
    vector = np.asarray(vector, dtype=float)
    size = float(np.linalg.norm(vector))
    if size <= math.pi:
        return vector
    if len(vector) == 1:
        return np.atleast_1d(np.asarray(wrap_angle(vector), dtype=float))
    return vector * (1.0 - 2.0 * math.pi * math.ceil((size - math.pi) / (2.0 * math.pi)) / size)


def _net_significant(
    net: np.ndarray, steps: np.ndarray, threshold: float, settings: TruthQualitySettings
) -> bool:
    """A burst's net change is a step of its own: above the jump threshold and above
    ``spike_max_net_fraction`` of the burst's largest step."""
    size = float(np.linalg.norm(net))
    largest = float(np.max(np.linalg.norm(steps, axis=1)))
    return size > threshold and size > settings.spike_max_net_fraction * largest


def _bursts(
    position: _Increments,
    rotation: _Increments | None,
    explained: np.ndarray,
    settings: TruthQualitySettings,
) -> tuple[list[_Jump], list[tuple[int, int, str]]]:
    """Runs of consecutive flagged steps not explained by a freeze ("bursts").

    A burst whose steps cancel (``_net_significant`` false in every part; headings and
    rotations modulo a full turn, so a heading interpolated the long way round across
    +-pi cancels) is a spike: the samples inside it are off and the track returns. Any
    other burst is a jump whose net change is what a later jump must undo.

    Returns:
        (jumps, spikes as (first step, last step, evidence)).
    """
    flagged = position.flagged | (rotation.flagged if rotation is not None else False)
    flagged = flagged & ~explained
    jumps: list[_Jump] = []
    spikes: list[tuple[int, int, str]] = []
    for first, last in _runs(flagged):
        p_steps = position.residuals[first : last + 1]
        p_net = p_steps.sum(axis=0)
        p_sig = _net_significant(p_net, p_steps, position.threshold, settings)
        if rotation is not None:
            r_steps = rotation.residuals[first : last + 1]
            r_net = _wrapped_rotation(r_steps.sum(axis=0))
            r_sig = _net_significant(r_net, r_steps, rotation.threshold, settings)
        else:
            r_net, r_sig = np.zeros(1), False
        if p_sig or r_sig:
            jumps.append(_Jump(first, last, p_net, r_net, p_sig, r_sig))
            continue
        largest = f"{np.max(np.linalg.norm(position.residuals[first : last + 1], axis=1)):.3f} m"
        if rotation is not None:
            size = np.max(np.linalg.norm(rotation.residuals[first : last + 1], axis=1))
            largest += f" / {size:.2f} rad"
        spikes.append(
            (
                first,
                last,
                f"{last - first} samples off and back: {last - first + 1} unexplained steps of "
                f"up to {largest} that cancel (net {np.linalg.norm(p_net):.3f} m"
                + (f", {np.linalg.norm(r_net):.3f} rad)" if rotation is not None else ")"),
            )
        )
    return jumps, spikes
