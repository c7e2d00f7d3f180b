"""Kalman update of the sensor-based filter (Guerreiro et al. 2013, section IV-B, eq. (11)).

The output matrix ``H`` only selects the measured features (``y_i = x_i``, eq. (2)), so
``H Sigma`` is a row selection and the update costs O(n^2 * measured) rather than O(n^3).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class UpdateResult:
    """Per-group innovations of one update.

    Attributes:
        nis: NIS of each group (one landmark with its directions), eq. (11), shape (G,).
        dof: degrees of freedom of each, shape (G,).
    """

    nis: np.ndarray
    dof: np.ndarray


def kalman_update(
    x: np.ndarray,
    covariance: np.ndarray,
    state_indices: np.ndarray,
    measured: np.ndarray,
    measurement_cov: np.ndarray,
    groups: list[np.ndarray],
) -> tuple[np.ndarray, np.ndarray, UpdateResult]:
    """Standard discrete Kalman update with a selection ``H`` and the Joseph-form covariance.

    Guerreiro et al. section IV-B: ``nu = y - H x``, ``S = H Sigma H^T + Theta``; eq. (11)
    ``NIS_i = nu_i^T S_i^-1 nu_i`` per associated landmark ``i`` (its diagonal block of ``S``).

    Args:
        x: (n,) prior mean. covariance: (n, n) prior covariance.
        state_indices: (m,) state indices measured, in the order of ``measured``.
        measured: (m,) stacked measurement.
        measurement_cov: (m, m) ``Theta``.
        groups: positions within the stacked vector of each landmark's block (for NIS).

    Returns:
        (posterior mean, posterior covariance, ``UpdateResult``).

    Joseph form ``(I-KH) P (I-KH)^T + K Theta K^T`` expanded with ``HP`` a row selection:
    ``P - K HP - (K HP)^T + K S K^T``; it holds for any gain, so round-off in ``K`` does not
    break symmetry or positive semi-definiteness the way ``(I - KH) P`` can.
    """
    hp = covariance[state_indices, :]
    innovation = measured - x[state_indices]
    s = hp[:, state_indices] + measurement_cov
    s = 0.5 * (s + s.T)
    gain = np.linalg.solve(s, hp).T  # P H^T S^-1, (n, m)
    x_post = x + gain @ innovation
    khp = gain @ hp
    post = covariance - khp - khp.T + gain @ s @ gain.T
    post = 0.5 * (post + post.T)
    nis = np.array(
        [float(innovation[g] @ np.linalg.solve(s[np.ix_(g, g)], innovation[g])) for g in groups]
    )
    dof = np.array([len(g) for g in groups], dtype=int)
    return x_post, post, UpdateResult(nis, dof)
