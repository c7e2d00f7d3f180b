"""A scan's sightings and their association (Guerreiro et al. 2013, sections IV-B and V).

The sightings of a ``LandmarkScan`` as the filter takes them: body-frame points with the
scan's stated covariances, or the paper's laser model (section V, ``tuning=paper``), and the
rows that are finite (``scan_sightings``). One decision per sighting by the shared policy
(``filters.association``, ``associate_scan``): by the scan's ids against every landmark in
the state, else JCBB against the current set I_cur only (landmarks seen within
``association_window_s``), as the paper does; an unassociated measurement starts a new
landmark only when it lies outside every current landmark's gate even at
``new_landmark_probability`` (otherwise it is ambiguous: recorded, neither used nor mapped).
"""

from __future__ import annotations

import numpy as np

from datasets.errors import InputError
from datasets.estimate import EstimateRecorder
from datasets.measurements import LandmarkScan
from datasets.range_bearing import first_order_covariance
from filters.association import AssociationPolicy, Reason, ScanAssociation
from filters.sensor_based.config import (
    PAPER_BEARING_SIGMA_RAD,
    PAPER_RANGE_SIGMA_M,
    PAPER_RANGE_SWITCH_M,
)
from filters.sensor_based.landmark_management import LandmarkManager
from filters.sensor_based.state import FilterState, landmark_predictor


def paper_laser_covariances(points: np.ndarray) -> np.ndarray:
    """The paper's laser model (section V) for body-frame points (k, 2): the first-order
    covariance of range ``sigma_rho`` and bearing ``sigma_alpha`` at the measured range and
    bearing (``datasets.range_bearing``; the printed ``Theta_p`` is not a covariance, see
    there), shape (k, 2, 2)."""
    ranges = np.linalg.norm(points, axis=1)
    bearings = np.arctan2(points[:, 1], points[:, 0])
    near, far = PAPER_RANGE_SIGMA_M
    range_sigma = np.where(ranges <= PAPER_RANGE_SWITCH_M, near, far)
    return first_order_covariance(ranges, bearings, range_sigma, PAPER_BEARING_SIGMA_RAD)


def scan_sightings(
    scan: LandmarkScan, dimension: int, name: str, paper_tuning: bool
) -> tuple[np.ndarray, np.ndarray]:
    """(points (k, d), covariances (k, d, d)) of a scan: its own covariances, or the paper's
    laser model with ``paper_tuning``. Raises ``InputError`` when their counts differ
    (``name``: the sequence's, for the message)."""
    d = dimension
    points = (
        np.asarray(scan.points, dtype=float).reshape(-1, d)
        if np.size(scan.points)
        else np.zeros((0, d))
    )
    covs = (
        np.asarray(scan.covariances, dtype=float).reshape(-1, d, d)
        if np.size(scan.covariances)
        else np.zeros((0, d, d))
    )
    if points.shape[0] != covs.shape[0]:
        raise InputError(
            f"{name}: scan at t={scan.t:.6f} s has {points.shape[0]} points but {covs.shape[0]} covariances"
        )
    if paper_tuning:
        covs = paper_laser_covariances(points)
    return points, covs


def usable_sightings(points: np.ndarray, covs: np.ndarray) -> np.ndarray:
    """(k,) bool: the sightings whose point and covariance are finite."""
    k, d = points.shape
    return np.all(np.isfinite(points), axis=1) & np.all(np.isfinite(covs.reshape(k, d * d)), axis=1)


def associate_scan(
    state: FilterState,
    policy: AssociationPolicy,
    manager: LandmarkManager,
    source_of: dict[int, int],
    recorder: EstimateRecorder,
    window_s: float,
    t: float,
    scan_ids: np.ndarray | None,
    points: np.ndarray,
    covs: np.ndarray,
    usable: np.ndarray,
) -> ScanAssociation:
    """One decision per sighting (the shared policy): by ids against every landmark in
    the state (``source_of``: map id -> the scan id it was created from), else JCBB against
    the current set I_cur only (seen within ``window_s``; the paper's section IV-B);
    non-finite sightings are rejected and counted. Matched candidates are map ids."""
    ids, positions = state.landmark_positions()
    mode = policy.mode(scan_ids, t)
    rows = np.flatnonzero(usable)
    if mode == "ids":
        sources = np.array([source_of.get(int(i), -1) for i in ids], dtype=int)
        predictor = landmark_predictor(state, np.arange(len(ids)))
        found = policy.by_ids(scan_ids[rows], points[rows], covs[rows], sources, predictor)
    else:
        current = (
            np.flatnonzero(manager.recently_seen(ids, t, window_s))
            if len(ids)
            else np.zeros(0, dtype=int)
        )
        predictor = landmark_predictor(state, current)
        found = policy.by_geometry(points[rows], covs[rows], len(current), predictor, mode)
        found = policy.distinct_new(points[rows], covs[rows], found)
        if found.search is not None and found.search.truncated:
            recorder.event(t, "jcbb_truncated", nodes=found.search.nodes)
        found = found.relabelled(current)  # candidate index -> landmark index
    return found.relabelled(ids).embedded(rows, len(points), Reason.NOT_FINITE)
