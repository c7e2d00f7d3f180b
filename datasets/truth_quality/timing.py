"""The timing checks: ``dropout`` (a gap of several median steps) and ``rate_change`` (a
run of steps all longer, or all shorter, than the median step by a factor)."""

from __future__ import annotations

import numpy as np

from datasets.truth_quality.intervals import TruthInterval, TruthKind
from datasets.truth_quality.settings import TruthQualitySettings
from datasets.truth_quality.steps import _runs


def _timing(
    t: np.ndarray, dt: np.ndarray, step: float, settings: TruthQualitySettings
) -> tuple[list[TruthInterval], np.ndarray]:
    """Dropouts and rate changes; returns them and the (N-1,) mask of dropout steps."""
    found: list[TruthInterval] = []
    long = dt > settings.rate_change_factor * step
    short = dt < step / settings.rate_change_factor
    in_rate_change = np.zeros(len(dt), dtype=bool)
    factor = settings.rate_change_factor
    for mask, word in (
        (long, f"longer than {factor:g}x"),
        (short, f"shorter than 1/{factor:g} of"),
    ):
        for first, last in _runs(mask):
            count = last - first + 1
            if count < settings.rate_change_min_steps:
                continue
            in_rate_change[first : last + 1] = True
            local = float(np.median(dt[first : last + 1]))
            found.append(
                TruthInterval(
                    float(t[first]),
                    float(t[last + 1]),
                    TruthKind.RATE_CHANGE,
                    f"{count} consecutive steps {word} the median step {step:.4g} s "
                    f"(median {local:.4g} s there)",
                )
            )
    dropout = (dt > settings.dropout_min_steps * step) & ~in_rate_change
    for index in np.flatnonzero(dropout):
        gap = float(dt[index])
        found.append(
            TruthInterval(
                float(t[index]) + step,
                float(t[index + 1]) - step,
                TruthKind.DROPOUT,
                f"no sample for {gap:.4g} s ({gap / step:.1f}x the median step {step:.4g} s) "
                f"after {t[index]:.3f} s",
            )
        )
    return found, dt > settings.dropout_min_steps * step
