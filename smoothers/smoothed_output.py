"""The smoothers' output at the end of a run: the smoothed history of every keyframe and the
final map, each with marginal covariances from batched joint queries.

- the map: one joint query over every landmark, so the map carries its joint covariance
  (``LandmarkMap.from_joint``: the map NEES needs the cross-covariances);
- the history: the states of ``KEYFRAMES_PER_MARGINAL_QUERY`` keyframes per joint query.
  One query per keyframe would repeat the elimination of the shared part of the Bayes tree
  for each; one query over every keyframe would build a dense (15 n)^2 matrix (1000
  keyframes: 1.8 GB) of which only the diagonal blocks are used.
"""

from __future__ import annotations

from dataclasses import replace

import gtsam
import numpy as np

from datasets.estimate import EstimateRecorder
from datasets.state import Frame, LandmarkMap, StateHistory
from smoothers.covariances import symmetric
from smoothers.joint_marginals import JointQuery
from smoothers.landmark_book import MapLandmark
from smoothers.motion_model import MotionModel

KEYFRAMES_PER_MARGINAL_QUERY = 32
"""Keyframes whose states share one batched joint marginal query in the smoothed history."""


def landmark_map(
    landmarks: list[MapLandmark],
    values: gtsam.Values,
    joint: JointQuery,
    dimension: int,
    t: float,
) -> LandmarkMap:
    """World-frame map at time ``t`` [s] of those ``landmarks`` whose variables ``values``
    holds, with their joint covariance from one query. Anchors (known landmarks held by a
    tight prior at their surveyed position) are inputs, not estimates: left out, as the
    filters leave theirs out (scored, their near-zero error against a 1 mm prior would pull
    the map NEES down: 0.89 per dof on the circle calibration with 3 of 28 anchored)."""
    present = [
        landmark
        for landmark in landmarks
        if values.exists(landmark.key) and landmark.anchor_position is None
    ]
    if not present:
        return LandmarkMap.empty(dimension)
    keys = [landmark.key for landmark in present]
    read = values.atPoint3 if dimension == 3 else values.atPoint2
    positions = np.array([read(key) for key in keys], dtype=float)
    covariance = symmetric(joint(keys).matrix(keys))
    return LandmarkMap.from_joint(
        [landmark.map_id for landmark in present], positions, covariance, Frame.WORLD, t
    )


def smoothed_history(
    motion: MotionModel,
    keyframe_t: list[float],
    values: gtsam.Values,
    joint: JointQuery,
    dimension: int,
    keyframes: list[int] | None = None,
) -> StateHistory:
    """Every keyframe's (or ``keyframes``') state at ``values`` with marginals from batched
    queries (``keyframe_t``: each keyframe's time [s])."""
    recorder = EstimateRecorder(dimension)
    chosen = list(range(len(keyframe_t))) if keyframes is None else keyframes
    for start in range(0, len(chosen), KEYFRAMES_PER_MARGINAL_QUERY):
        chunk = chosen[start : start + KEYFRAMES_PER_MARGINAL_QUERY]
        marginals = joint([key for k in chunk for key in motion.keys(k)])
        for k in chunk:
            motion.record(recorder, keyframe_t[k], values, k, marginals)
    return recorder.history()


def with_map(history: StateHistory, final_map: LandmarkMap) -> StateHistory:
    """The history with the final map as its landmark snapshot (what the smoothed map is)."""
    return replace(
        history, landmarks=(*history.landmarks, final_map) if len(final_map) else history.landmarks
    )
