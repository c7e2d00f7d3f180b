"""Individual compatibility: the chi-square gate of one (measurement, landmark) pair
(Neira and Tardos 2001, eq. (8)) and the input checks every association call shares. (The
innovation statistics of an update are the Kalman core's: ``filters.kalman``.)

The innovation of pairing measurement ``j`` with landmark ``i`` is ``nu = z_j - h_i`` with
covariance ``R_jj + P_ii - C_ji - C_ji^T`` (``C = cov(z, h)``, zero for an ordinary scan).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy.stats import chi2

from datasets.errors import InputError


@lru_cache(maxsize=1024)
def chi2_gate(dof: int, probability: float) -> float:
    """Chi-square quantile: the gate ``D^2 < chi2_gate(dof, probability)`` (dimensionless)."""
    if dof <= 0:
        return 0.0
    return float(chi2.ppf(probability, dof))


def as_blocks(cov: np.ndarray, count: int, d: int, name: str) -> np.ndarray:
    """Per-item (count, d, d) diagonal blocks of a (count, d, d) or (count*d, count*d) input."""
    cov = np.asarray(cov, dtype=float)
    if cov.shape == (count, d, d):
        return cov
    if cov.shape == (count * d, count * d):
        idx = np.arange(count)[:, None] * d + np.arange(d)[None, :]
        return cov[idx[:, :, None], idx[:, None, :]]
    raise InputError(
        f"association: {name} must have shape ({count}, {d}, {d}) or ({count * d}, {count * d}), got {cov.shape}"
    )


def full_from(cov: np.ndarray, count: int, d: int) -> np.ndarray:
    """Full (count*d, count*d) matrix from blocks or a full matrix."""
    cov = np.asarray(cov, dtype=float)
    if cov.shape == (count * d, count * d):
        return cov
    full = np.zeros((count * d, count * d))
    for j in range(count):
        full[j * d : (j + 1) * d, j * d : (j + 1) * d] = cov[j]
    return full


def check_inputs(
    measured: np.ndarray,
    measured_cov: np.ndarray,
    predicted: np.ndarray,
    predicted_cov: np.ndarray,
    cross_cov: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray, int, int, int]:
    measured = np.asarray(measured, dtype=float)
    predicted = np.asarray(predicted, dtype=float)
    if measured.ndim != 2 or predicted.ndim != 2:
        raise InputError(
            f"association: measured (k, d) and predicted (m, d) must be 2-D, got {measured.shape} and {predicted.shape}"
        )
    k, d = measured.shape
    m = predicted.shape[0]
    if m and predicted.shape[1] != d:
        raise InputError(
            f"association: measured has dimension {d} but predicted has {predicted.shape[1]}"
        )
    for name, array in (
        ("measured", measured),
        ("predicted", predicted),
        ("measured_cov", measured_cov),
        ("predicted_cov", predicted_cov),
    ):
        if not np.all(np.isfinite(np.asarray(array, dtype=float))):
            raise InputError(f"association: {name} contains NaN or inf")
    if cross_cov is not None and np.asarray(cross_cov).shape != (k * d, m * d):
        raise InputError(
            f"association: cross_cov must have shape ({k * d}, {m * d}), got {np.asarray(cross_cov).shape}"
        )
    return measured, predicted, k, m, d


def individual_compatibility(
    measured: np.ndarray,
    measured_cov: np.ndarray,
    predicted: np.ndarray,
    predicted_cov: np.ndarray,
    cross_cov: np.ndarray | None = None,
) -> np.ndarray:
    """Squared Mahalanobis distance of every (measurement, landmark) pair.

    Neira and Tardos (2001), eq. (8): ``D2[j, i] = nu^T S^-1 nu`` with ``nu = z_j - h_i`` and
    ``S = R_jj + P_ii - C_ji - C_ji^T``.

    Args:
        measured: (k, d). measured_cov: (k, d, d) or (k*d, k*d).
        predicted: (m, d). predicted_cov: (m, d, d) blocks or the joint (m*d, m*d).
        cross_cov: cov(z, h), (k*d, m*d), or None (independent).

    Returns:
        (k, m) array of ``D^2`` (d degrees of freedom); ``inf`` where ``S`` is singular.
    """
    measured, predicted, k, m, d = check_inputs(
        measured, measured_cov, predicted, predicted_cov, cross_cov
    )
    if k == 0 or m == 0:
        return np.zeros((k, m))
    r_blocks = as_blocks(measured_cov, k, d, "measured_cov")
    p_blocks = as_blocks(predicted_cov, m, d, "predicted_cov")
    s = r_blocks[:, None, :, :] + p_blocks[None, :, :, :]
    if cross_cov is not None:
        c = np.asarray(cross_cov, dtype=float).reshape(k, d, m, d).transpose(0, 2, 1, 3)
        s = s - c - np.swapaxes(c, -1, -2)
    nu = measured[:, None, :] - predicted[None, :, :]
    distances = np.full((k, m), np.inf)
    try:
        solved = np.linalg.solve(s, nu[..., None])[..., 0]
        distances = np.einsum("kmi,kmi->km", nu, solved)
    except np.linalg.LinAlgError:
        # A singular block somewhere: fall back pair by pair so only that pair is rejected.
        for j in range(k):
            for i in range(m):
                try:
                    distances[j, i] = float(nu[j, i] @ np.linalg.solve(s[j, i], nu[j, i]))
                except np.linalg.LinAlgError:
                    distances[j, i] = np.inf
    distances = np.where(np.isfinite(distances) & (distances >= 0), distances, np.inf)
    return distances
