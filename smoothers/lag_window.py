"""What leaves the fixed-lag window, kept: ``WindowExports``.

``gtsam.IncrementalFixedLagSmoother`` marginalises the keys older than ``latest - lag`` in
each update; their estimates and marginals are gone afterwards. So right *before* an update
the keyframes and landmarks about to leave are exported with their marginals from one
batched joint query (a keyframe leaving is smoothed as much as it will ever be). At the end
the smoothed history is the exported keyframes followed by those still in the window, and
the map is the window's (with its joint covariance) plus the landmarks last seen before
they left it (their marginals only: a fixed lag keeps no joint covariance of the whole map).
"""

from __future__ import annotations

import gtsam
import numpy as np

from datasets.estimate import EstimateRecorder
from datasets.state import Frame, LandmarkMap, StateHistory
from smoothers.landmark_book import MapLandmark
from smoothers.motion_model import MotionModel


class WindowExports:
    """Keyframe states and landmark positions exported as they left the window.

    Attributes:
        keyframes: the exported keyframes' indices.
        landmarks: map id -> (position (d,) [m], marginal covariance (d, d) [m^2]) at the
            moment its variable left the window (the latest such variable).
    """

    def __init__(self, motion: MotionModel, dimension: int) -> None:
        self.motion = motion
        self.dimension = dimension
        self.keyframes: set[int] = set()
        self.landmarks: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self._exported = EstimateRecorder(dimension)

    def export(
        self,
        backend,
        leaving: list[int],
        keyframe_t: list[float],
        landmarks: list[MapLandmark],
        t: float,
        departed: dict[int, tuple[np.ndarray, np.ndarray]] | None = None,
    ) -> None:
        """Record the keyframes and ``landmarks`` whose variables are among the ``leaving``
        keys of ``backend``, with marginals from one joint query (``t`` [s]: the update's
        time, for errors); the departing landmarks' marginals also go to ``departed`` (map
        id -> (position, covariance)), from which a returning landmark gets its prior."""
        pose_keys = {self.motion.pose_key(k): k for k in self._keyframes_in(leaving)}
        keyframes = sorted(k for key, k in pose_keys.items() if k not in self.keyframes)
        leaving_set = set(leaving)
        departing = [landmark for landmark in landmarks if landmark.key in leaving_set]
        keys = [key for k in keyframes for key in self.motion.keys(k)]
        keys = [key for key in keys + [lm.key for lm in departing] if backend.contains(key)]
        if not keys:
            return
        values = backend.values(keys)
        marginals = backend.joint(keys, t)
        for k in keyframes:
            if values.exists(self.motion.pose_key(k)):
                self.motion.record(self._exported, keyframe_t[k], values, k, marginals)
                self.keyframes.add(k)
        read = values.atPoint3 if self.dimension == 3 else values.atPoint2
        for landmark in departing:
            if values.exists(landmark.key) and landmark.anchor_position is None:
                self.landmarks[landmark.map_id] = (
                    np.asarray(read(landmark.key), dtype=float),
                    marginals.marginalCovariance(landmark.key),
                )
                if departed is not None:
                    departed[landmark.map_id] = self.landmarks[landmark.map_id]

    @staticmethod
    def _keyframes_in(keys: list[int]) -> list[int]:
        """Keyframe indices of the pose keys among ``keys`` (``x`` symbols)."""
        symbols = [gtsam.Symbol(key) for key in keys]
        return [int(symbol.index()) for symbol in symbols if chr(symbol.chr()) == "x"]

    def history(self, in_window: StateHistory) -> StateHistory:
        """The exported keyframes followed by ``in_window`` (the states still in the window,
        all later: keys leave in time order)."""
        recorder = EstimateRecorder(self.dimension)
        for part in (self._exported.history(), in_window):
            _copy_into(recorder, part)
        return recorder.history()

    def merged_map(self, window_map: LandmarkMap) -> LandmarkMap:
        """The window's landmarks, plus those that left it and were not seen again."""
        entries = {
            int(i): (p, c)
            for i, p, c in zip(
                window_map.ids,
                window_map.positions,
                window_map.covariances if window_map.covariances is not None else [],
                strict=False,
            )
        }
        for map_id, entry in self.landmarks.items():
            entries.setdefault(map_id, entry)
        if not entries:
            return LandmarkMap.empty(self.dimension)
        ids = np.array(sorted(entries), dtype=int)
        return LandmarkMap(
            ids,
            np.array([entries[i][0] for i in ids]),
            np.array([entries[i][1] for i in ids]),
            Frame.WORLD,
        )


def _copy_into(recorder: EstimateRecorder, history: StateHistory) -> None:
    """Append every pose and block entry of ``history`` to ``recorder``."""
    pose = history.pose
    if pose is not None:
        for index in range(len(pose)):
            covariance = None if pose.covariances is None else pose.covariances[index]
            recorder.pose(pose.t[index], pose.positions[index], pose.rotations[index], covariance)
    for name, block in history.blocks.items():
        for index in range(len(block.t)):
            recorder.block(
                name,
                block.t[index],
                block.values[index],
                None if block.covariances is None else block.covariances[index],
                block.frame,
            )
