"""The EKF-SLAM's scan update: the map's predicted observations, their Jacobians and the
stacked Kalman update of a scan's associated sightings.

- *Prediction* of map landmarks with the configured Jacobians (``predict``; ``standard``,
  ``first-estimate`` or ``observability-constrained``: ``observation``).
- *Association* input (``predictor``, the shared ``filters.landmark_predictor`` over this
  module's ``measure``): the predictions and ``H P H^T`` with the state's correlations,
  individually (the policy's gates) or jointly (JCBB's joint predicted covariance), for
  ``filters.association.AssociationPolicy``.
- *Update* (``update``): all associated sightings of a scan stacked in one block-sparse
  update of the shared Kalman core (``filters.kalman.update``; each row block touches the
  vehicle and its own landmark only, ``observation_jacobian``), with the noise the
  association says (inflated outside the id gate); the correction added to the mean
  (``inject``).

The functions take the filter (``filter.EkfSlam``) whose state they read and change.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from datasets.rotations import so3_exp, wrap_angle
from filters import kalman
from filters.association import ScanAssociation
from filters.ekf_slam.motion import VehicleMean
from filters.ekf_slam.observation import observability_constrained, predict_observations
from filters.landmark_predictor import LandmarkMeasurement, LandmarkPredictor

if TYPE_CHECKING:
    from filters.ekf_slam.filter import EkfSlam


def predictor(ekf: EkfSlam) -> LandmarkPredictor:
    """The association ``Predictor`` of the EKF's map (world landmarks seen from the
    vehicle; candidates are map indices): predictions and ``H P H^T`` with the state's
    correlations (``filters.landmark_predictor``)."""
    return LandmarkPredictor(ekf.registry, ekf.covariance, lambda indices: measure(ekf, indices))


def measure(ekf: EkfSlam, indices: np.ndarray) -> LandmarkMeasurement:
    """The linearised observation of map landmarks ``indices`` (``predict``): it depends
    on the whole vehicle block and each landmark's position."""
    indices = np.asarray(indices, dtype=int)
    predicted, vehicle_jac, landmark_jac = predict(ekf, indices)
    return LandmarkMeasurement(
        predicted,
        ekf.map_ids[indices],
        vehicle=None,
        vehicle_jacobian=vehicle_jac,
        landmark_jacobian=landmark_jac,
    )


def predict(ekf: EkfSlam, indices: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``predict_observations`` of map landmarks ``indices`` with the configured
    Jacobians: predicted (m, d), vehicle Jacobians (m, d, n_v), landmark Jacobians
    (m, d, d)."""
    indices = np.asarray(indices, dtype=int)
    first = ekf.first_landmarks[indices]
    predicted, vehicle_jac, landmark_jac = predict_observations(
        ekf.vehicle,
        ekf.layout,
        ekf.landmarks[indices],
        first if ekf.jacobians == "first-estimate" else None,
    )
    if ekf.jacobians == "observability-constrained":
        return predicted, *observability_constrained(
            ekf.layout, vehicle_jac, landmark_jac, ekf.predicted_position, first
        )
    d = ekf.dimension
    return predicted, vehicle_jac, np.broadcast_to(landmark_jac, (len(indices), d, d))


def observation_jacobian(
    ekf: EkfSlam, indices: np.ndarray
) -> tuple[np.ndarray, kalman.SparseJacobian]:
    """Predicted observations (n, d) of map landmarks ``indices`` and the stacked ``H``
    (n d rows) by its non-zero columns: the vehicle block and each landmark's own."""
    return predictor(ekf).jacobian(indices)


def update(
    ekf: EkfSlam,
    t: float,
    points: np.ndarray,
    noise: np.ndarray,
    association: ScanAssociation,
    rows: np.ndarray,
) -> None:
    """One stacked update of the sightings ``rows`` (the shared core), with the noise the
    association says (inflated outside the id gate), scored against ``noise``."""
    d = ekf.dimension
    indices = association.candidates[rows]
    predicted, jacobian = ekf.observation_jacobian(indices)
    groups = [np.arange(row * d, row * d + d) for row in range(len(indices))]
    outcome = kalman.update(
        ekf.covariance,
        (points - predicted).ravel(),
        jacobian,
        association.noise[rows],
        groups,
        model_noise=noise,
    )
    if outcome.innovation is not None:
        innovation = outcome.innovation
        ekf.recorder.innovation(
            t, innovation.nis, innovation.dof, innovation.group_nis, innovation.group_dof
        )
    if outcome.correction is None:
        ekf.recorder.event(t, "update_refused", reason=outcome.refused)
        return
    inject(ekf, outcome.correction)


def inject(ekf: EkfSlam, correction: np.ndarray) -> None:
    """Add the error-state correction to the mean (multiplicatively on the 3-D rotation)."""
    layout = ekf.layout
    vehicle = ekf.vehicle
    dr = correction[layout.rotation]
    if ekf.dimension == 2:
        rotation: float | np.ndarray = float(wrap_angle(float(vehicle.rotation) + dr[0]))
    else:
        rotation = so3_exp(dr) @ np.asarray(vehicle.rotation)
    ekf.vehicle = VehicleMean(
        position=vehicle.position + correction[layout.position],
        rotation=rotation,
        velocity=None
        if layout.velocity is None
        else vehicle.velocity + correction[layout.velocity],
        gyro_bias=None
        if layout.gyro_bias is None
        else vehicle.gyro_bias + correction[layout.gyro_bias],
    )
    if len(ekf.map_ids):
        ekf.landmarks = ekf.landmarks + correction[ekf.vehicle_size :].reshape(-1, ekf.dimension)
