"""Landmark management (section V): intermittent, unseen-in-view, and the cap."""

from __future__ import annotations

import numpy as np

from datasets.measurements import LandmarkScan
from filters.sensor_based.config import SensorBasedConfig
from filters.sensor_based.filter import SensorBasedSlam
from filters.sensor_based.landmark_management import LandmarkManager, ManagementPolicy
from tests.sensor_based_support import planar_sequence, run

LANDMARKS = np.array([[3.0, 1.0], [2.0, -2.0], [5.0, 0.5]])


def _with_extra_point(sequence, at_t: float, point: np.ndarray):
    out = []
    for measurement in sequence.measurements():
        if isinstance(measurement, LandmarkScan) and abs(measurement.t - at_t) < 1e-9:
            measurement = LandmarkScan(
                t=measurement.t,
                points=np.vstack([measurement.points, point]),
                covariances=np.concatenate([measurement.covariances, measurement.covariances[:1]]),
            )
        out.append(measurement)
    return out


def test_a_landmark_seen_once_is_deleted_as_intermittent() -> None:
    sequence = planar_sequence(10.0, (0.2, 0.0), 0.0, LANDMARKS, seed=1)
    measurements = _with_extra_point(sequence, 1.0, np.array([[-4.0, 6.0]]))
    estimator, estimate = run(
        SensorBasedSlam,
        SensorBasedConfig(association="jcbb", probation_s=3.0, min_observations=3),
        sequence,
        measurements,
    )
    assert estimator.manager.deleted["intermittent"] == 1
    assert len(estimator.state.landmark_ids()) == len(LANDMARKS)
    counts = estimate.diagnostics.landmark_count
    assert counts.max() == len(LANDMARKS) + 1 and counts[-1] == len(LANDMARKS)


def test_unseen_in_view_deletion_and_cap() -> None:
    policy = ManagementPolicy(
        in_view_range_m=5.0, max_missed_in_view=3, min_observations=1, max_landmarks=2
    )
    manager = LandmarkManager(policy)
    for landmark_id in range(3):
        manager.created(landmark_id, 0.0)
    ids = np.arange(3)
    positions = np.array([[1.0, 0.0], [20.0, 0.0], [30.0, 0.0]])  # only id 0 is in view
    covs = np.repeat((0.01 * np.eye(2))[None], 3, axis=0)
    covs[2] *= 100.0  # id 2 is the most uncertain
    seen = np.array([False, True, False])
    # Three landmarks, cap two: the most uncertain non-visible one (id 2) goes at once.
    assert manager.after_scan(0.1, ids, seen, positions, covs) == [2]
    manager.removed([2])
    ids, positions, covs, seen = ids[:2], positions[:2], covs[:2], seen[:2]
    doomed, step = [], 1
    while not doomed:
        step += 1
        doomed = manager.after_scan(0.1 * step, ids, seen, positions, covs)
    assert doomed == [0] and step == 3  # in view and missed three scans in a row (counting t=0.1)
    assert manager.deleted == {"unseen_in_view": 1, "intermittent": 0, "cap": 1}
