"""The three smoother modes, each registered in ``workbench/registry.py``.

- ``smoother-isam2`` (``SmootherIsam2``): iSAM2, one update per keyframe. Causal history:
  the estimate right after each keyframe's update, with iSAM2 marginal covariances of
  its pose, velocity and biases. Smoothed history: the final iSAM2 estimate of every
  keyframe with marginals, and the final map with its joint covariance.
- ``smoother-batch`` (``SmootherBatch``): the reference. The graph is built (and the
  association decided) by an incremental iSAM2 pass, whose final solution is the initial
  guess of Levenberg-Marquardt over the whole graph (``smoothers.initialization``: why not
  dead reckoning). A batch solution exists only at the end: the Estimate has *no* causal
  history (nothing the batch knew at a time before the end), only the smoothed one, with
  covariances from ``gtsam.Marginals``. Its NIS and association records are those of the
  incremental pass that built the graph.
- ``smoother-fixed-lag`` (``SmootherFixedLag``): ``gtsam.IncrementalFixedLagSmoother`` with a
  lag in seconds. Causal history as for iSAM2. Smoothed history: each keyframe's estimate
  and marginals at the moment it leaves the window (the most it is ever smoothed), the
  rest at the end; the map of the window at the end with its joint covariance. A landmark
  re-observed after it was marginalised starts a new variable (its old information lives
  on in the marginal factor of the window; anchors get their prior again).

Marginals are always queried in batches (``backends.JointMarginals``): a keyframe's states
together, the keys leaving the window together, the map together.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import ClassVar

import gtsam
import numpy as np

from datasets.errors import InputError
from datasets.estimate import Estimate, EstimateRecorder
from datasets.sequence import Sequence
from datasets.state import Frame, LandmarkMap, StateHistory
from smoothers.backends import FixedLagBackend, JointMarginals, gtsam_message
from smoothers.config import BatchConfig, FixedLagConfig, Isam2Config
from smoothers.initialization import levenberg_marquardt
from smoothers.keyframe_smoother import KeyframeSmoother


def _with_map(history: StateHistory, final_map: LandmarkMap) -> StateHistory:
    """The history with the final map as its landmark snapshot (what the smoothed map is)."""
    return replace(
        history, landmarks=(*history.landmarks, final_map) if len(final_map) else history.landmarks
    )


class SmootherIsam2(KeyframeSmoother):
    """Incremental smoothing with iSAM2 (Kaess et al. 2012) over IMU keyframes and landmarks."""

    Config: ClassVar = Isam2Config
    mode: ClassVar[str] = "isam2"

    def __init__(self, config: Isam2Config, sequence: Sequence) -> None:
        super().__init__(config, sequence)
        self.causal_covariances = config.causal_covariances

    def estimate(self) -> Estimate:
        self._flush()
        values = self.backend.estimate()
        final_map = self.landmark_map(values, self.backend.joint)
        smoothed = _with_map(self.smoothed_history(values, self.backend.joint), final_map)
        self._report_fallback()
        self.recorder.extra("gtsam_update_seconds_total", self.backend.gtsam_seconds)
        return self.recorder.build(landmarks=final_map, smoothed=smoothed, notes=tuple(self.notes))


class SmootherBatch(KeyframeSmoother):
    """Levenberg-Marquardt over the whole keyframe graph, started from an iSAM2 pass."""

    Config: ClassVar = BatchConfig
    record_causal: ClassVar[bool] = False
    mode: ClassVar[str] = "batch"

    def _marginals(self, result: gtsam.Values) -> gtsam.Marginals:
        """``gtsam.Marginals`` of the whole graph, Cholesky first, QR when it fails."""
        try:
            return gtsam.Marginals(self.full_graph, result)
        except RuntimeError as error:
            self.recorder.event(
                self.keyframe_t[-1], "factorization_fallback", to="QR", reason=gtsam_message(error)
            )
            self.notes.append(
                f"batch marginals: Cholesky failed, QR used (GTSAM: {gtsam_message(error)})"
            )
            return gtsam.Marginals(self.full_graph, result, gtsam.Marginals.Factorization.QR)

    def estimate(self) -> Estimate:
        self._flush()
        incremental = self.backend.estimate()
        guess = (
            incremental
            if self.config.initial_guess == "incremental"
            else self._dead_reckoning_start()
        )
        start = time.perf_counter()
        try:
            result, iterations, start_error, final_error = levenberg_marquardt(
                self.full_graph, guess, self.config.max_iterations
            )
            marginals = self._marginals(result)
        except RuntimeError as error:
            raise InputError(
                f"batch optimisation of {self.sequence_name} failed inside GTSAM: {gtsam_message(error)}"
            ) from None

        def joint(keys: list[int]) -> JointMarginals:
            return JointMarginals(marginals.jointMarginalCovariance(list(keys)), keys)

        self.recorder.extra("batch_seconds", time.perf_counter() - start)
        self.recorder.extra("batch_iterations", iterations)
        self.recorder.extra("batch_error_start", start_error)
        self.recorder.extra("batch_error_final", final_error)
        self.recorder.extra("incremental_error", self.full_graph.error(incremental))
        final_map = self.landmark_map(result, joint)
        smoothed = _with_map(self.smoothed_history(result, joint), final_map)
        self._report_fallback()
        notes = tuple(self.notes) + (
            f"batch LM from the {self.config.initial_guess} solution: graph error {start_error:.6g} -> {final_error:.6g} in {iterations} iterations",
            "batch smoother: no causal history (a batch solution exists only at the end); "
            "every state and the map are smoothed",
        )
        self.final_values = result
        return self.recorder.build(landmarks=final_map, smoothed=smoothed, notes=notes)

    def _dead_reckoning_start(self) -> gtsam.Values:
        """Open-loop start: motion increments chained from the prior, landmarks placed from
        their first sighting seen from that chain, anchors at their known positions."""
        values = gtsam.Values(self.start_values)
        for k in range(1, len(self.keyframe_t)):
            values.insert(self.motion.dead_reckoning_step(k, values))
        for key, (k, point) in self.first_sightings.items():
            if not values.exists(key):
                values.insert(
                    key,
                    np.asarray(self.motion.pose_of(values, k).transformFrom(point), dtype=float),
                )
        return values


class SmootherFixedLag(KeyframeSmoother):
    """GTSAM's incremental fixed-lag smoother over a window of ``lag_s`` seconds."""

    Config: ClassVar = FixedLagConfig
    mode: ClassVar[str] = "fixed-lag"

    def __init__(self, config: FixedLagConfig, sequence: Sequence) -> None:
        self.departed_landmarks: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.keyframe_exports: dict[int, EstimateRecorder] = {}
        super().__init__(config, sequence)
        self.causal_covariances = config.causal_covariances

    def _make_backend(self) -> FixedLagBackend:
        return FixedLagBackend(
            self.config.lag_s,
            self.config.relinearize_threshold,
            self.config.relinearize_skip,
            self.dimension,
            self.config.factorization,
        )

    def _before_update(self, t_new: float) -> None:
        """Export what leaves the window with this update: the keyframes' states and the
        landmarks' positions with their marginals, from one batched query."""
        leaving = set(self.backend.leaving(t_new))
        if not leaving:
            return
        keyframes = [
            k
            for k in range(len(self.keyframe_t))
            if k not in self.keyframe_exports and self.motion.pose_key(k) in leaving
        ]
        landmarks = [lm for lm in self.landmarks.values() if lm.key in leaving]
        keys = [key for k in keyframes for key in self.motion.keys(k)] + [
            lm.key for lm in landmarks
        ]
        keys = [key for key in keys if self.backend.contains(key)]
        if not keys:
            return
        values = self.backend.values(keys)
        marginals = self.backend.joint(keys, t_new)
        for k in keyframes:
            if not values.exists(self.motion.pose_key(k)):
                continue
            recorder = EstimateRecorder(self.dimension)
            self.motion.record(recorder, self.keyframe_t[k], values, k, marginals)
            self.keyframe_exports[k] = recorder
        read = values.atPoint3 if self.dimension == 3 else values.atPoint2
        for landmark in landmarks:
            if values.exists(landmark.key):
                self.departed_landmarks[landmark.map_id] = (
                    np.asarray(read(landmark.key), dtype=float),
                    marginals.marginalCovariance(landmark.key),
                )

    def _update(self, t: float) -> None:
        latest = self.keyframe_t[-1]
        if len(self.keyframe_t) > 1 and latest - self.keyframe_t[-2] >= self.config.lag_s:
            raise InputError(
                f"fixed lag: keyframes at t={self.keyframe_t[-2]:.3f} and {latest:.3f} s are further apart than lag_s={self.config.lag_s}"
            )
        super()._update(t)

    def estimate(self) -> Estimate:
        self._flush()
        values = self.backend.estimate()
        in_window = [
            k
            for k in range(len(self.keyframe_t))
            if k not in self.keyframe_exports and values.exists(self.motion.pose_key(k))
        ]
        remaining = self.smoothed_history(values, self.backend.joint, in_window)
        recorder = EstimateRecorder(self.dimension)
        for k in range(len(self.keyframe_t)):
            history = self.keyframe_exports[k].history() if k in self.keyframe_exports else None
            if history is not None:
                _append_history(recorder, history, 0)
            elif k in in_window:
                _append_history(recorder, remaining, in_window.index(k))
        window_map = self.landmark_map(values, self.backend.joint)
        smoothed = _with_map(recorder.history(), window_map)
        self._report_fallback()
        landmark_map = _merge_maps(window_map, self.departed_landmarks, self.dimension)
        return self.recorder.build(
            landmarks=landmark_map, smoothed=smoothed, notes=tuple(self.notes)
        )


def _append_history(recorder: EstimateRecorder, history: StateHistory, index: int) -> None:
    """Copy step ``index`` of a history into ``recorder``."""
    pose = history.pose
    cov = None if pose.covariances is None else pose.covariances[index]
    recorder.pose(pose.t[index], pose.positions[index], pose.rotations[index], cov)
    for name, block in history.blocks.items():
        recorder.block(
            name,
            block.t[index],
            block.values[index],
            None if block.covariances is None else block.covariances[index],
            block.frame,
        )


def _merge_maps(
    current: LandmarkMap, departed: dict[int, tuple[np.ndarray, np.ndarray]], dimension: int
) -> LandmarkMap:
    """Current window landmarks, plus those last seen only before leaving the window (their
    marginals only: the joint covariance of the whole map is not kept by a fixed lag)."""
    entries = {
        int(i): (p, c)
        for i, p, c in zip(
            current.ids,
            current.positions,
            current.covariances if current.covariances is not None else [],
            strict=False,
        )
    }
    for map_id, entry in departed.items():
        entries.setdefault(map_id, entry)
    if not entries:
        return LandmarkMap.empty(dimension)
    ids = np.array(sorted(entries), dtype=int)
    return LandmarkMap(
        ids,
        np.array([entries[i][0] for i in ids]),
        np.array([entries[i][1] for i in ids]),
        Frame.WORLD,
    )
