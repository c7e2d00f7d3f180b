"""Which map landmarks a scan's sightings are, decided by the shared policy
(``filters.association.AssociationPolicy``) against the keyframe's prediction
(``smoothers.keyframe_prediction``).

The smoother's part is only the choice of *candidates*:
- with ids: the landmarks whose variables the backend holds and whose id the scan carries;
  a prediction is made (one joint marginal query) only when something uses it: the id gate
  or the scan's NIS;
- geometrically (JCBB, nearest neighbour): the landmarks the backend holds within reach of
  the scan, which bounds the joint query and the JCBB search.
Landmarks created by an earlier scan of the same keyframe are not solved yet, so they have
no prediction and are no candidates (with ids the smoother pairs a repeated id with them
itself: ``smoothers.landmark_scans``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from filters.association import AssociationPolicy, ScanAssociation
from smoothers.keyframe_prediction import KeyframePredictor
from smoothers.landmark_book import MapLandmark

REACH_FACTOR = 1.5
REACH_MARGIN_M = 5.0
"""Geometric candidates: landmarks predicted within ``REACH_FACTOR`` x the scan's farthest
sighting + ``REACH_MARGIN_M`` of the sensor. Farther ones cannot be seen (their individual
gate would reject them anyway); leaving them out keeps the joint marginal query and the JCBB
input bounded by what is near, not by the map's size."""


@dataclass(frozen=True)
class ScanDecisions:
    """The association of one scan.

    Attributes:
        association: the policy's decisions; its candidate indices refer to ``candidates``.
        candidates: the landmarks the scan was associated against.
        predictor: the prediction it was made against (None when none was needed).
    """

    association: ScanAssociation
    candidates: list[MapLandmark]
    predictor: KeyframePredictor | None


def associate_scan(
    policy: AssociationPolicy,
    ids: np.ndarray | None,
    t: float,
    points: np.ndarray,
    covariances: np.ndarray,
    solved: list[MapLandmark],
    predict: Callable[[list[MapLandmark]], KeyframePredictor],
    predict_ids: bool,
) -> ScanDecisions:
    """Decide every sighting of a scan at time ``t`` [s].

    Args:
        ids: the sightings' source ids (k,), or None.
        points: the sightings (k, d) [m]. covariances: their noise (k, d, d) [m^2].
        solved: the map landmarks whose variables the backend holds, by map id.
        predict: the keyframe's prediction of given landmarks.
        predict_ids: with ids, whether to predict (the id gate or the NIS uses it).
    """
    mode = policy.mode(ids, t)
    if mode == "ids":
        assert ids is not None
        wanted = {int(i) for i in ids}
        candidates = [landmark for landmark in solved if landmark.map_id in wanted]
        predictor = predict(candidates) if candidates and predict_ids else None
        candidate_ids = np.array([landmark.map_id for landmark in candidates], dtype=int)
        association = policy.by_ids(ids, points, covariances, candidate_ids, predictor)
        return ScanDecisions(association, candidates, predictor)
    candidates, predictor = [], None
    if solved:
        everything = predict(solved)
        farthest = float(np.max(np.linalg.norm(points, axis=1), initial=0.0))
        reach = farthest * REACH_FACTOR + REACH_MARGIN_M
        near = np.flatnonzero(np.linalg.norm(everything.predicted, axis=1) < reach)
        if near.size:
            predictor = everything.subset(near)
            candidates = predictor.candidates
    association = policy.by_geometry(points, covariances, len(candidates), predictor, mode)
    return ScanDecisions(association, candidates, predictor)
