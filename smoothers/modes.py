"""The three smoother modes, each registered in ``workbench/registry.py``.

- ``smoother-isam2`` (``SmootherIsam2``): iSAM2, one update per keyframe. Causal history:
  the estimate right after each keyframe's update, with iSAM2 marginal covariances of
  its pose, velocity and biases, and map snapshots every ``snapshot_interval_s``.
  Smoothed history: the final iSAM2 estimate of every keyframe with marginals, and the
  final map with its joint covariance.
- ``smoother-batch`` (``SmootherBatch``): the reference. The graph is built (and the
  association decided) by an incremental iSAM2 pass, whose final solution is the initial
  guess of Levenberg-Marquardt over the whole graph (``smoothers.initialization``: why not
  dead reckoning). A batch solution exists only at the end: the Estimate has *no* causal
  history (nothing the batch knew at a time before the end), only the smoothed one, with
  covariances from ``gtsam.Marginals`` (Cholesky, QR when it fails). Its NIS and
  association records are those of the incremental pass that built the graph.
- ``smoother-fixed-lag`` (``SmootherFixedLag``): ``gtsam.IncrementalFixedLagSmoother`` with a
  lag in seconds. Causal history as for iSAM2 (snapshots of the window's map). Smoothed
  history: each keyframe's estimate and marginals at the moment it leaves the window (the
  most it is ever smoothed), the rest at the end (``smoothers.lag_window``); the map of the
  window at the end with its joint covariance, plus the landmarks that left it. A landmark
  re-observed after it was marginalised starts a new variable (its old information lives
  on in the marginal factor of the window; anchors get their prior again).

Marginals are always queried in batches (``smoothers.joint_marginals``): a keyframe's states
together, the keys leaving the window together, the map together.
"""

from __future__ import annotations

import time
from typing import ClassVar

import gtsam

from datasets.errors import InputError
from datasets.estimate import Estimate, EstimateRecorder
from datasets.measurements import Sensor
from datasets.sequence import Sequence
from datasets.state import LandmarkMap
from smoothers.backends import FixedLagBackend, factor_keys
from smoothers.config import BatchConfig, FixedLagConfig, Isam2Config
from smoothers.dense_marginals import DenseQrMarginals
from smoothers.gtsam_errors import explain, gtsam_message
from smoothers.initialization import dead_reckoning_values, levenberg_marquardt
from smoothers.joint_marginals import JointMarginals
from smoothers.keyframe_smoother import KeyframeSmoother
from smoothers.lag_clock import InformationClock
from smoothers.lag_window import WindowExports
from smoothers.smoothed_output import with_map
from smoothers.window_health import (
    UNSETTLED_CHI2_PER_DOF,
    UNSETTLED_UPDATES,
    UNSETTLED_WINDOW_S,
    WindowHealth,
    new_factor_chi2_per_dof,
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
        if self.stopped is not None:  # the solver failed mid-run: its causal states only
            return self.recorder.build(
                landmarks=LandmarkMap.empty(self.dimension), notes=self.stopped_notes()
            )
        values = self.backend.estimate()
        final_map = self.landmark_map(values, self.backend.joint)
        smoothed = with_map(self.smoothed_history(values, self.backend.joint), final_map)
        self.recorder.final_snapshot(final_map)  # iSAM2's last estimate is causal too
        self._report_fallback()
        self.recorder.extra("gtsam_update_seconds_total", self.backend.gtsam_seconds)
        return self.recorder.build(landmarks=final_map, smoothed=smoothed, notes=tuple(self.notes))


class SmootherBatch(KeyframeSmoother):
    """Levenberg-Marquardt over the whole keyframe graph, started from an iSAM2 pass."""

    Config: ClassVar = BatchConfig
    record_causal: ClassVar[bool] = False
    mode: ClassVar[str] = "batch"

    def _marginals(self, result: gtsam.Values) -> gtsam.Marginals | DenseQrMarginals:
        """``gtsam.Marginals`` of the whole graph (Cholesky); a dense QR of the whole
        linearised graph when it fails (``smoothers.dense_marginals``)."""
        try:
            return gtsam.Marginals(self.full_graph, result)
        except RuntimeError as error:
            self.recorder.event(
                self.keyframe_t[-1],
                "factorization_fallback",
                to="dense QR",
                reason=gtsam_message(error),
            )
            self.notes.append(
                "batch marginals: Cholesky failed, a dense QR of the whole graph used "
                f"(GTSAM: {gtsam_message(error)})"
            )
            return DenseQrMarginals(self.full_graph, result)

    def estimate(self) -> Estimate:
        self._flush()
        incremental = self.backend.estimate()
        guess = (
            incremental
            if self.config.initial_guess == "incremental"
            else dead_reckoning_values(
                self.start_values,
                self.motion,
                len(self.keyframe_t),
                self.scans.first_sightings,
            )
        )
        start = time.perf_counter()
        try:
            result, iterations, start_error, final_error = levenberg_marquardt(
                self.full_graph, guess, self.config.max_iterations
            )
            marginals = self._marginals(result)
        except RuntimeError as error:
            raise explain(
                error, float("nan"), f"batch optimisation of {self.sequence_name}"
            ) from None

        def joint(keys) -> JointMarginals:
            try:
                return JointMarginals.query(marginals, keys)
            except RuntimeError as error:
                raise explain(error, float("nan"), "batch joint marginal covariance") from None

        self.recorder.extra("batch_seconds", time.perf_counter() - start)
        self.recorder.extra("batch_iterations", iterations)
        self.recorder.extra("batch_error_start", start_error)
        self.recorder.extra("batch_error_final", final_error)
        self.recorder.extra("incremental_error", self.full_graph.error(incremental))
        final_map = self.landmark_map(result, joint)
        smoothed = with_map(self.smoothed_history(result, joint), final_map)
        self._report_fallback()
        notes = tuple(self.notes) + (
            f"batch LM from the {self.config.initial_guess} solution: graph error {start_error:.6g} -> {final_error:.6g} in {iterations} iterations",
            "batch smoother: no causal history (a batch solution exists only at the end); "
            "every state and the map are smoothed",
        )
        self.final_values = result
        return self.recorder.build(landmarks=final_map, smoothed=smoothed, notes=notes)


class SmootherFixedLag(KeyframeSmoother):
    """GTSAM's incremental fixed-lag smoother over a window of ``lag_s`` seconds."""

    Config: ClassVar = FixedLagConfig
    mode: ClassVar[str] = "fixed-lag"

    def __init__(self, config: FixedLagConfig, sequence: Sequence) -> None:
        # what the lag is counted in (``smoothers.lag_clock``), before the backend exists;
        # a sequence without sightings or fixes has nothing to wait for: wall-clock time
        informative = {Sensor.LANDMARKS, Sensor.GPS} & set(sequence.sensors)
        self.lag_clock = (
            InformationClock(sequence.initial_state.t if sequence.initial_state else 0.0)
            if config.lag_clock == "informative" and informative
            else None
        )
        super().__init__(config, sequence)
        self.exports = WindowExports(self.motion, self.dimension)
        self.health = WindowHealth()
        self.causal_covariances = config.causal_covariances

    def _make_backend(self) -> FixedLagBackend:
        return FixedLagBackend(
            self.config.lag_s,
            self.config.relinearize_threshold,
            self.config.relinearize_skip,
            self.dimension,
            self.config.factorization,
            clock=self.lag_clock,
        )

    def _keyframe_group(self, t: float, informative: bool) -> None:
        if self.lag_clock is not None:
            self.lag_clock.advance(t, informative)

    def _after_solve(self, t: float, graph: gtsam.NonlinearFactorGraph) -> None:
        """Did the window take this update's new factors (``smoothers.window_health``)? A
        divergence is an event and a note (``workbench.metrics.divergence`` reports it); the
        run goes on, as a filter's would."""
        keys = sorted(key for key in factor_keys(graph) if self.backend.contains(key))
        if not keys:
            return
        statistic = new_factor_chi2_per_dof(graph, self.backend.values(keys, t))
        if self.health.check(t, statistic):
            began = self.health.diverged_at
            self.recorder.event(
                began,
                "window_diverged",
                reason=(
                    f"{UNSETTLED_UPDATES} updates within {UNSETTLED_WINDOW_S:g} s did not take "
                    f"their new factors (chi-square per dof above {UNSETTLED_CHI2_PER_DOF:g}: "
                    + ", ".join(f"{value:.3g}" for _, value in self.health.unsettled[-3:])
                    + ")"
                ),
            )
            self.notes.append(
                f"fixed-lag smoother: its window diverged from t={began:.3f} s "
                f"(smoothers.window_health): updates stopped fitting their own new factors"
            )

    def _before_update(self, t_new: float) -> None:
        """Export what leaves the window with this update (``smoothers.lag_window``)."""
        leaving = self.backend.leaving(t_new)
        if leaving:
            landmarks = list(self.landmarks.values())
            self.exports.export(
                self.backend, leaving, self.keyframe_t, landmarks, t_new, self.scans.departed
            )

    def bridge_interval_s(self) -> float | None:
        """Keyframes at least every half window on motion alone: a stretch without
        landmarks longer than ``lag_s`` would otherwise leave the window empty of the
        keyframe the next one must connect to."""
        return 0.5 * self.config.lag_s

    def _update(self, t: float) -> None:
        latest = self.keyframe_t[-1]
        if len(self.keyframe_t) > 1 and latest - self.keyframe_t[-2] >= self.config.lag_s:
            raise InputError(
                f"fixed lag: keyframes at t={self.keyframe_t[-2]:.3f} and {latest:.3f} s are "
                f"further apart than lag_s={self.config.lag_s} (no motion input in between)"
            )
        if self.config.keep_map:
            # re-stamp the map with the newest time: the window slides over states only
            for landmark in self.landmarks.values():
                if self.backend.contains(landmark.key) or self.pending.holds(landmark.key):
                    self.pending.touch(landmark.key, t)
        super()._update(t)

    def estimate(self) -> Estimate:
        self._flush()
        if self.stopped is not None:
            # the solver failed mid-run: the causal states, and what had left the window
            # smoothed before it failed (the window itself cannot be read any more)
            empty = LandmarkMap.empty(self.dimension)
            smoothed = with_map(
                self.exports.history(EstimateRecorder(self.dimension).history()), empty
            )
            return self.recorder.build(
                landmarks=self.exports.merged_map(empty),
                smoothed=smoothed,
                notes=self.stopped_notes(),
            )
        values = self.backend.estimate()
        in_window = [
            k
            for k in range(len(self.keyframe_t))
            if k not in self.exports.keyframes and values.exists(self.motion.pose_key(k))
        ]
        remaining = self.smoothed_history(values, self.backend.joint, in_window)
        window_map = self.landmark_map(values, self.backend.joint)
        smoothed = with_map(self.exports.history(remaining), window_map)
        self.recorder.final_snapshot(window_map)  # the window's, with its joint covariance
        self._report_fallback()
        return self.recorder.build(
            landmarks=self.exports.merged_map(window_map),
            smoothed=smoothed,
            notes=tuple(self.notes),
        )
