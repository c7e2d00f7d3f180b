"""The EKF-SLAM's map bookkeeping: landmark initialisation, sighting counts and probation.

- *Landmark initialisation* on first sight with the full cross-covariances
  (``filters.kalman.augment``; ``add_landmark``): ``l = p + R z``,
  ``P_ll = G_v P_vv G_v^T + R Sigma_z R^T``, ``P_lx = G_v P_vx``.
- *Sighting counts and the association record* (``record_associations``): each
  sighting's decision with the landmark it went to, and one more sighting for each matched
  landmark.
- *Probation* (``prune``): with ``probation_s`` (the initialisation delay) a landmark stays
  provisional until its second sighting (``min_observations``) and is marginalised out if
  none comes in time: exact, since one sighting of a new landmark carries no information on
  the rest of the state.

The functions take the filter (``filter.EkfSlam``) whose state they read and change.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from datasets.estimate import AssociationDecision
from filters import kalman
from filters.association import ScanAssociation
from filters.ekf_slam.observation import initialise_landmark

if TYPE_CHECKING:
    from filters.ekf_slam.filter import EkfSlam


def add_landmark(ekf: EkfSlam, t: float, point: np.ndarray, noise: np.ndarray, source: int) -> int:
    """Augment the state with a new landmark and its cross-covariances; returns its map
    index. ``source``: the scan id it was created from (-1 without ids)."""
    position, vehicle_jac, point_jac = initialise_landmark(ekf.vehicle, ekf.layout, point)
    jacobian = kalman.SparseJacobian(ekf.registry.columns(None), vehicle_jac)  # whole vehicle
    ekf.covariance = kalman.augment(ekf.covariance, jacobian, point_jac @ noise @ point_jac.T)
    ekf.registry.augment(ekf.next_id, [("position", ekf.dimension)])
    ekf.landmarks = np.vstack([ekf.landmarks, position])
    ekf.first_landmarks = np.vstack([ekf.first_landmarks, position])
    ekf.source_ids.append(int(source))
    ekf.next_id += 1
    ekf.sightings.append(1)
    ekf.created_t.append(float(t))
    return len(ekf.map_ids) - 1


def record_associations(
    ekf: EkfSlam, t: float, association: ScanAssociation, created: dict[int, int]
) -> None:
    """Record every sighting's decision with its landmark's map id (``created``: sighting
    -> map index of the landmarks it created) and count the matched landmarks' sightings."""
    for j, decision in enumerate(association.decisions):
        if decision == AssociationDecision.NEW:
            landmark_id = int(ekf.map_ids[created[j]])
        elif decision == AssociationDecision.MATCHED:
            ekf.sightings[association.candidates[j]] += 1
            landmark_id = int(ekf.map_ids[association.candidates[j]])
        else:
            landmark_id = -1
        ekf.recorder.association(
            t,
            j,
            landmark_id,
            decision,
            association.reasons[j],
            association.inflation[j],
            association.alternatives_of(j),
        )


def prune(ekf: EkfSlam, t: float) -> None:
    """Marginalise out the provisional landmarks (seen fewer than ``min_observations``
    times) older than ``probation_s``: the landmark initialisation delay (module
    docstring)."""
    horizon = ekf.config.probation_s
    if horizon is None:
        return
    needed = ekf.config.min_observations
    drop = {
        i
        for i in range(len(ekf.map_ids))
        if ekf.sightings[i] < needed and t - ekf.created_t[i] > horizon
    }
    if not drop:
        return
    keep = [i for i in range(len(ekf.map_ids)) if i not in drop]
    removed = [int(ekf.map_ids[i]) for i in sorted(drop)]
    ekf.covariance = kalman.marginalize(ekf.covariance, ekf.registry.marginalize(removed))
    ekf.landmarks = ekf.landmarks[keep]
    ekf.first_landmarks = ekf.first_landmarks[keep]
    ekf.source_ids = [ekf.source_ids[i] for i in keep]
    ekf.sightings = [ekf.sightings[i] for i in keep]
    ekf.created_t = [ekf.created_t[i] for i in keep]
    reason = "seen once" if needed == 2 else f"seen fewer than {needed} times"
    ekf.recorder.event(t, "landmarks_pruned", map_ids=removed, reason=reason)
