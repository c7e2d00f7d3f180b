"""The ``freeze`` check: a value held bit for bit over several steps while the stream
moved across it (the step out of it is itself a jump)."""

from __future__ import annotations

import numpy as np

from datasets.truth_quality.intervals import TruthInterval, TruthKind
from datasets.truth_quality.settings import TruthQualitySettings
from datasets.truth_quality.steps import _Increments, _runs


def _freezes(
    t: np.ndarray,
    positions: np.ndarray,
    rotations: np.ndarray | None,
    position: _Increments,
    rotation: _Increments | None,
    settings: TruthQualitySettings,
) -> tuple[list[TruthInterval], np.ndarray]:
    """Held values while the stream moves; returns them and the (N-1,) mask of the steps
    they explain (the held steps and the step out of the held value)."""
    same = np.all(np.diff(positions, axis=0) == 0.0, axis=1)
    if rotations is not None:
        rows = rotations.reshape(len(rotations), -1)
        same &= np.all(np.diff(rows, axis=0) == 0.0, axis=1)
    explained = np.zeros(len(same), dtype=bool)
    found: list[TruthInterval] = []
    for first, last in _runs(same):
        count = last - first + 1
        if count < settings.freeze_min_steps:
            continue
        exit_step = last + 1
        if exit_step < len(same):
            moved = bool(position.flagged[exit_step]) or (
                rotation is not None and bool(rotation.flagged[exit_step])
            )
            how = f"then moves by {np.linalg.norm(position.steps[exit_step]):.3f} m"
            if rotation is not None:
                how += f" / {np.linalg.norm(rotation.steps[exit_step]):.3f} rad"
            how += " in one step"
        else:
            # held to the end: moved if the velocity before it would have carried it
            # beyond the jump threshold in the time it was held
            before = max(first - 1, 0)
            velocity = position.steps[before] / max(float(t[before + 1] - t[before]), 1e-12)
            reach = float(np.linalg.norm(velocity)) * float(t[last + 1] - t[first])
            moved = reach > position.threshold
            how = f"to the end while moving at {np.linalg.norm(velocity):.3f} m/s before"
        if not moved:
            continue
        explained[first : min(exit_step, len(same) - 1) + 1] = True
        found.append(
            TruthInterval(
                float(t[first + 1]),
                float(t[last + 1]),
                TruthKind.FREEZE,
                f"{count + 1} samples hold the same value for {t[last + 1] - t[first]:.3f} s, "
                + how,
            )
        )
    return found, explained
