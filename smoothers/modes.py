"""The three smoother modes, each registered in ``workbench/registry.py``.

- ``smoother-isam2`` (``SmootherIsam2``): iSAM2, one update per keyframe. Causal history:
  the estimate right after each keyframe's update, with iSAM2 marginal covariances of
  its pose, velocity and biases. Smoothed history: the final iSAM2 estimate of every
  keyframe with marginals.
- ``smoother-batch`` (``SmootherBatch``): the reference. The graph is built (and the
  association decided) by an incremental iSAM2 pass, whose final solution is the initial
  guess of Levenberg-Marquardt over the whole graph (``smoothers.initialization``: why not
  dead reckoning). A batch solution exists only at the end, so its causal history *is* its
  smoothed history (stated in the Estimate's notes); covariances from ``gtsam.Marginals``.
- ``smoother-fixed-lag`` (``SmootherFixedLag``): ``gtsam.IncrementalFixedLagSmoother`` with a
  lag in seconds. Causal history as for iSAM2. Smoothed history: each keyframe's estimate
  and marginals at the moment it leaves the window (the most it is ever smoothed), the
  rest at the end. A landmark re-observed after it was marginalised starts a new variable
  (its old information lives on in the marginal factor of the window; anchors get their
  prior again).
"""

from __future__ import annotations

import time
from typing import ClassVar, Literal

import gtsam
import numpy as np
from pydantic import Field

from datasets.errors import InputError
from datasets.estimate import Estimate, EstimateRecorder
from datasets.sequence import Sequence
from datasets.state import Frame, LandmarkMap
from smoothers.backends import FixedLagBackend, Isam2Backend
from smoothers.covariances import vector_covariance
from smoothers.initialization import levenberg_marquardt
from smoothers.keyframe_smoother import KeyframeSmoother, SmootherConfig


class Isam2Config(SmootherConfig):
    """Options of ``smoother-isam2``."""

    causal_covariances: bool = Field(
        True, description="marginal covariances after every keyframe (NEES of the causal history)"
    )


class BatchConfig(SmootherConfig):
    """Options of ``smoother-batch``."""

    max_iterations: int = Field(100, ge=1, description="Levenberg-Marquardt iterations")
    initial_guess: Literal["incremental", "dead-reckoning"] = Field(
        "incremental",
        description="LM start: the incremental (iSAM2) solution, or dead reckoning (the trap, for comparison)",
    )


class FixedLagConfig(SmootherConfig):
    """Options of ``smoother-fixed-lag``."""

    lag_s: float = Field(5.0, gt=0, description="window length [s]")
    causal_covariances: bool = Field(True, description="marginal covariances after every keyframe")


class SmootherIsam2(KeyframeSmoother):
    """Incremental smoothing with iSAM2 (Kaess et al. 2012) over IMU keyframes and landmarks."""

    Config: ClassVar = Isam2Config
    mode: ClassVar[str] = "isam2"

    def __init__(self, config: Isam2Config, sequence: Sequence) -> None:
        super().__init__(config, sequence)
        self.causal_covariances = config.causal_covariances

    def _make_backend(self) -> Isam2Backend:
        return Isam2Backend(
            self.config.relinearize_threshold,
            self.config.relinearize_skip,
            self.config.extra_iterations,
            self.dimension,
        )

    def estimate(self) -> Estimate:
        self._flush()
        values = self.backend.estimate()
        marginals = self.backend_marginals()
        smoothed = self.smoothed_history(values, marginals)
        self.recorder.extra("gtsam_update_seconds_total", self.backend.gtsam_seconds)
        return self.recorder.build(
            landmarks=self.landmark_map(values, marginals),
            smoothed=smoothed,
            notes=tuple(self.notes),
        )


class SmootherBatch(KeyframeSmoother):
    """Levenberg-Marquardt over the whole keyframe graph, started from an iSAM2 pass."""

    Config: ClassVar = BatchConfig
    record_causal: ClassVar[bool] = False
    mode: ClassVar[str] = "batch"

    def _make_backend(self) -> Isam2Backend:
        return Isam2Backend(
            self.config.relinearize_threshold,
            self.config.relinearize_skip,
            self.config.extra_iterations,
            self.dimension,
        )

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
            marginals = gtsam.Marginals(self.full_graph, result)
        except RuntimeError as error:
            raise InputError(
                f"batch optimisation of {self.sequence_name} failed inside GTSAM: {str(error).splitlines()[0]}"
            ) from None
        self.recorder.extra("batch_seconds", time.perf_counter() - start)
        self.recorder.extra("batch_iterations", iterations)
        self.recorder.extra("batch_error_start", start_error)
        self.recorder.extra("batch_error_final", final_error)
        self.recorder.extra("incremental_error", self.full_graph.error(incremental))
        smoothed = self.smoothed_history(result, marginals)
        notes = tuple(self.notes) + (
            f"batch LM from the {self.config.initial_guess} solution: graph error {start_error:.6g} -> {final_error:.6g} in {iterations} iterations",
            "batch smoother: causal history = smoothed history (a batch solution exists only at the end)",
        )
        self.final_values = result
        return _replace_causal(
            self.recorder.build(
                landmarks=self.landmark_map(result, marginals), smoothed=smoothed, notes=notes
            )
        )

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


def _replace_causal(estimate: Estimate) -> Estimate:
    from dataclasses import replace

    assert estimate.smoothed is not None
    return replace(estimate, causal=estimate.smoothed)


class SmootherFixedLag(KeyframeSmoother):
    """GTSAM's incremental fixed-lag smoother over a window of ``lag_s`` seconds."""

    Config: ClassVar = FixedLagConfig
    mode: ClassVar[str] = "fixed-lag"

    def __init__(self, config: FixedLagConfig, sequence: Sequence) -> None:
        self.leaving_records: dict[int, tuple[float, object]] = {}
        self.departed_landmarks: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.keyframe_exports: dict[int, tuple[np.ndarray, ...]] = {}
        super().__init__(config, sequence)
        self.causal_covariances = config.causal_covariances
        self.smoothed_recorder_rows: dict[int, EstimateRecorder] = {}

    def _make_backend(self) -> FixedLagBackend:
        return FixedLagBackend(
            self.config.lag_s,
            self.config.relinearize_threshold,
            self.config.relinearize_skip,
            self.dimension,
        )

    def _before_update(self, t_new: float) -> None:
        leaving = set(self.backend.leaving(t_new))
        if not leaving:
            return
        values = self.backend.values(sorted(leaving))
        marginals = self.backend_marginals()
        for k, t in enumerate(self.keyframe_t):
            if k in self.keyframe_exports or self.motion.pose_key(k) not in leaving:
                continue
            if t_new - t > 0 and not values.exists(self.motion.pose_key(k)):
                continue
            recorder = EstimateRecorder(self.dimension)
            self.motion.record(recorder, t, values, k, marginals)
            self.keyframe_exports[k] = (recorder,)
        for landmark in self.landmarks.values():
            if landmark.key in leaving and values.exists(landmark.key):
                position = (
                    values.atPoint3(landmark.key)
                    if self.dimension == 3
                    else values.atPoint2(landmark.key)
                )
                self.departed_landmarks[landmark.map_id] = (
                    np.asarray(position),
                    vector_covariance(marginals.marginalCovariance(landmark.key)),
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
        marginals = self.backend_marginals()
        recorder = EstimateRecorder(self.dimension)
        for k, t in enumerate(self.keyframe_t):
            if k in self.keyframe_exports:
                history = self.keyframe_exports[k][0].history()  # type: ignore[union-attr]
                _append_history(recorder, history, self.dimension)
            elif values.exists(self.motion.pose_key(k)):
                self.motion.record(recorder, t, values, k, marginals)
        smoothed = recorder.history()
        current = self.landmark_map(values, marginals)
        landmark_map = _merge_maps(current, self.departed_landmarks, self.dimension)
        return self.recorder.build(
            landmarks=landmark_map, smoothed=smoothed, notes=tuple(self.notes)
        )


def _append_history(recorder: EstimateRecorder, history, dimension: int) -> None:
    """Copy a one-keyframe history into ``recorder``."""
    pose = history.pose
    cov = None if pose.covariances is None else pose.covariances[0]
    recorder.pose(pose.t[0], pose.positions[0], pose.rotations[0], cov)
    for name, block in history.blocks.items():
        recorder.block(
            name,
            block.t[0],
            block.values[0],
            None if block.covariances is None else block.covariances[0],
            block.frame,
        )


def _merge_maps(
    current: LandmarkMap, departed: dict[int, tuple[np.ndarray, np.ndarray]], dimension: int
) -> LandmarkMap:
    """Current window landmarks, plus those last seen only before leaving the window."""
    entries = {
        int(i): (p, c)
        for i, p, c in zip(
            current.ids,
            current.positions,
            current.covariances if current.covariances is not None else [],
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
