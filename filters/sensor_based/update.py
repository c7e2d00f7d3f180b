"""Kalman update of the sensor-based filter (Guerreiro et al. 2013, section IV-B, eq. (11)).

The output matrix ``H`` only selects the measured features (``y_i = x_i``, eq. (2)), so the
update is the shared Kalman core (``filters.kalman.update``) with a selection ``H``: ``H P``
is a row gather and the update costs O(n^2 m) for m measured rows.
"""

from __future__ import annotations

import numpy as np

from filters import kalman


def selection_update(
    x: np.ndarray,
    covariance: np.ndarray,
    state_indices: np.ndarray,
    measured: np.ndarray,
    measurement_cov: np.ndarray,
    groups: list[np.ndarray],
    model_cov: np.ndarray | None = None,
) -> tuple[np.ndarray, kalman.UpdateOutcome]:
    """The section IV-B update ``nu = y - H x``, ``S = H Sigma H^T + Theta`` of the measured
    features; eq. (11) ``NIS_i = nu_i^T S_i^-1 nu_i`` per associated landmark ``i`` (its
    diagonal block of ``S``) and the stacked NIS of the whole scan.

    Args:
        x: (n,) prior mean. covariance: (n, n) prior, replaced by the posterior in place.
        state_indices: (m,) state indices measured, in the order of ``measured``.
        measured: (m,) stacked measurement.
        measurement_cov: (m, m) ``Theta`` the update uses.
        groups: positions within the stacked vector of each landmark's block (for NIS).
        model_cov: the ``Theta`` the NIS is computed with when it differs (a sighting used
            with inflated noise is scored against the stated noise).

    Returns:
        (posterior mean (n,), the core's ``UpdateOutcome``); the mean is unchanged when the
        update was refused.
    """
    residual = measured - x[state_indices]
    outcome = kalman.update(
        covariance,
        residual,
        kalman.SparseJacobian.selection(state_indices),
        measurement_cov,
        groups,
        model_noise=model_cov,
    )
    if outcome.correction is None:
        return x, outcome
    return x + outcome.correction, outcome
