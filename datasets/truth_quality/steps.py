"""How a step is judged (``datasets.truth_quality`` docstring): per-step increments of
positions or rotations, their residuals against the running-median velocity, the robust
sigma, the fast step and the jump threshold (``_Increments``); and the run and window
helpers over (N-1,) step masks that the checks share."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.rotations import matrix_from_quat_wxyz, so3_log, wrap_angle
from datasets.truth_quality.settings import TruthQualitySettings


@dataclass(frozen=True)
class _Increments:
    """Per-step increments of one part (positions or rotations) and their judgement.

    Attributes:
        steps: increments (N-1, k) (rotations: body-frame rotation vectors, or headings).
        residuals: steps minus the local median velocity times the step duration (N-1, k).
        flagged: (N-1,) bool, residual norm above ``threshold``.
        threshold: the jump threshold used.
        sigma: robust sigma of the residuals (largest over the axes).
        fast_step: the fast step length.
    """

    steps: np.ndarray
    residuals: np.ndarray
    flagged: np.ndarray
    threshold: float
    sigma: float
    fast_step: float


def _robust_sigma(values: np.ndarray) -> np.ndarray:
    """1.4826 x median absolute deviation per column of (M, k) values (0 without rows)."""
    if len(values) == 0:
        return np.zeros(values.shape[1])
    centre = np.median(values, axis=0)
    return 1.4826 * np.median(np.abs(values - centre), axis=0)


def _judge(
    steps: np.ndarray,
    dt: np.ndarray,
    assessed: np.ndarray,
    settings: TruthQualitySettings,
    floor: float,
    angular: bool,
) -> _Increments:
    """Residuals of ``steps`` (N-1, k) against the running-median velocity, and the flags."""
    from scipy.ndimage import median_filter

    rates = steps / dt[:, None]
    size = 2 * settings.jump_window_steps + 1
    local = median_filter(rates, size=(size, 1), mode="nearest")
    residuals = steps - local * dt[:, None]
    if angular and steps.shape[1] == 1:
        residuals = np.asarray(wrap_angle(residuals), dtype=float)
    residuals = np.where(assessed[:, None], residuals, 0.0)
    sigma = float(np.max(_robust_sigma(residuals[assessed]))) if np.any(assessed) else 0.0
    lengths = np.linalg.norm(steps[assessed], axis=1)
    fast = float(np.percentile(lengths, settings.fast_step_percentile)) if len(lengths) else 0.0
    threshold = max(settings.jump_min_sigmas * sigma, settings.jump_min_fast_steps * fast, floor)
    flagged = assessed & (np.linalg.norm(residuals, axis=1) > threshold)
    return _Increments(steps, residuals, flagged, threshold, sigma, fast)


def _rotation_increments(rotations: np.ndarray, planar: bool) -> np.ndarray:
    """Per-step rotation increments: wrapped heading changes (N-1, 1) for planar truth,
    body-frame rotation vectors Log(R_k^T R_k+1) (N-1, 3) in 3-D."""
    if planar:
        return np.asarray(wrap_angle(np.diff(rotations)), dtype=float)[:, None]
    matrices = matrix_from_quat_wxyz(rotations)
    relative = np.einsum("nji,njk->nik", matrices[:-1], matrices[1:])
    return np.asarray(so3_log(relative), dtype=float).reshape(-1, 3)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) index of every run of True in a 1-D bool array."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(np.int8), [0]])))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2])]


def _broken_windows(broken: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """True where the steps ``lower..upper-1`` contain a broken step."""
    cumulative = np.concatenate([[0], np.cumsum(broken)])
    return (cumulative[upper] - cumulative[lower]) > 0
