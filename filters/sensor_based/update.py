"""Kalman update of the sensor-based filter (Guerreiro et al. 2013, section IV-B, eq. (11)).

The output matrix ``H`` only selects the measured features (``y_i = x_i``, eq. (2)), so the
update is the shared Kalman core (``filters.kalman.update``) with a selection ``H``: ``H P``
is a row gather and the update costs O(n^2 m) for m measured rows. ``update_matched`` is a
scan's update: every matched landmark's position with its direction features, after which
those features are the visible set I_O and their measured values the ``y`` of ``A(t, y)``.
"""

from __future__ import annotations

import numpy as np

from datasets.estimate import EstimateRecorder
from filters import kalman
from filters.association import Decision, ScanAssociation
from filters.sensor_based.directions import direction_covariance, match_direction
from filters.sensor_based.rigid_correction import apply_rigid_correction
from filters.sensor_based.state import FilterState


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


def update_matched(
    state: FilterState,
    recorder: EstimateRecorder,
    direction_sigma_rad: float,
    t: float,
    points: np.ndarray,
    covs: np.ndarray,
    directions: np.ndarray | None,
    association: ScanAssociation,
    rigid_correction: str = "exact",
) -> np.ndarray:
    """Section IV-B update of every matched landmark (with its direction features);
    returns the map id per sighting (-1 unless matched). ``rigid_correction``: "exact"
    applies the correction's rigid part as an exact rotation (``rigid_correction``), "linear"
    leaves the Kalman correction as it is."""
    d = state.dimension
    assignment = np.where(
        np.array([decision == Decision.MATCHED for decision in association.decisions]),
        association.candidates,
        -1,
    )
    measured_features: list[int] = []
    values: list[np.ndarray] = []
    cov_blocks: list[np.ndarray] = []  # the noise each block is used with
    model_blocks: list[np.ndarray] = []  # the stated noise, for the NIS
    groups: list[np.ndarray] = []
    position_of = {
        int(owner): index for index, owner in zip(state.position_features(), state.landmark_ids())
    }
    for j in np.flatnonzero(assignment >= 0):
        landmark_id = int(assignment[j])
        start = len(values) * d
        measured_features.append(position_of[landmark_id])
        values.append(points[j])
        cov_blocks.append(association.noise[j])  # inflated where the policy says
        model_blocks.append(covs[j])
        if directions is not None:
            for feature in state.direction_features(landmark_id):
                unit = match_direction(state.features[feature], directions[j])
                if unit is not None:
                    measured_features.append(int(feature))
                    values.append(unit)
                    block = direction_covariance(unit, direction_sigma_rad)
                    cov_blocks.append(block)
                    model_blocks.append(block)
        groups.append(np.arange(start, len(values) * d))
    if not measured_features:
        return assignment
    features = np.array(measured_features)
    indices = state.state_indices(features)
    prior_x = state.x.copy()
    state.x, outcome = selection_update(
        state.x,
        state.covariance,
        indices,
        np.concatenate(values),
        kalman.block_diagonal(np.stack(cov_blocks)),
        groups,
        kalman.block_diagonal(np.stack(model_blocks)),
    )
    if outcome.innovation is not None:
        found = outcome.innovation
        recorder.innovation(t, found.nis, found.dof, found.group_nis, found.group_dof)
    if outcome.correction is None:
        recorder.event(t, "update_refused", reason=outcome.refused)
        return assignment
    if rigid_correction == "exact":
        apply_rigid_correction(state, prior_x)
    state.measured[features] = np.stack(values)
    state.visible[features] = True
    return assignment
