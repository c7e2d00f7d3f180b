"""The ``heading`` check: a sustained disagreement of the heading with the direction of
travel of the truth's own positions while moving (assumes forward driving)."""

from __future__ import annotations

import numpy as np

from datasets.truth_quality.intervals import TruthInterval, TruthKind
from datasets.truth_quality.settings import TruthQualitySettings
from datasets.truth_quality.steps import _broken_windows, _Increments


def _heading(
    t: np.ndarray,
    positions: np.ndarray,
    forward: np.ndarray,
    position: _Increments,
    broken: np.ndarray,
    settings: TruthQualitySettings,
) -> tuple[list[TruthInterval], dict[str, float]]:
    """Sustained disagreement of the heading (body x axis ``forward``, (N, d)) with the
    direction of travel (the chord over +-``heading_window_steps``)."""
    count = len(t)
    index = np.arange(count)
    lower = np.clip(index - settings.heading_window_steps, 0, count - 1)
    upper = np.clip(index + settings.heading_window_steps, 0, count - 1)
    chord = positions[upper] - positions[lower]
    length = np.linalg.norm(chord, axis=1)
    travel = max(
        settings.jump_min_sigmas * position.sigma,
        settings.heading_min_travel_fraction
        * 2
        * settings.heading_window_steps
        * position.fast_step,
        settings.jump_floor_m,
    )
    moving = (length > travel) & ~_broken_windows(broken, lower, upper)
    cosine = np.einsum("nd,nd->n", chord, forward) / np.maximum(
        length * np.linalg.norm(forward, axis=1), 1e-300
    )
    angle = np.arccos(np.clip(cosine, -1.0, 1.0))
    disagree = moving & (angle > settings.heading_max_angle_rad)
    agree = moving & ~disagree
    found: list[TruthInterval] = []
    samples = np.flatnonzero(disagree)
    if len(samples):
        groups = np.cumsum(agree)[samples]
        for part in np.split(samples, np.flatnonzero(np.diff(groups)) + 1):
            if len(part) < settings.heading_min_steps:
                continue
            found.append(
                TruthInterval(
                    float(t[part[0]]),
                    float(t[part[-1]]),
                    TruthKind.HEADING,
                    f"heading {np.median(angle[part]):.2f} rad (median; max "
                    f"{np.max(angle[part]):.2f}) off the direction of travel on {len(part)} "
                    f"moving samples (threshold {settings.heading_max_angle_rad:.2f} rad; "
                    "assumes forward driving)",
                )
            )
    return found, {"heading_min_travel_m": travel, "heading_moving_fraction": float(moving.mean())}
