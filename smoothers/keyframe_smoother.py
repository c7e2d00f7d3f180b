"""The keyframe factor-graph smoother shared by the batch, iSAM2 and fixed-lag modes: the
stream turned into keyframes, each committed to an incremental backend.

Data flow: motion samples (IMU in 3-D; odometry or a rate gyro in 2-D) are accumulated by a
motion model (``smoothers.motion_setup``); measurements that need a state at their own time
(landmark scans, GPS fixes, 3-D relative poses) open a keyframe at that time. A keyframe is
committed once the stream has moved past its time, so every motion sample up to it is in
and measurements with the same time stamp (duplicates) share one keyframe. Time stamps are
checked once, by the shared ``StreamClock``.

Keyframe policy (``keyframe_imu_stride``): a keyframe at every landmark scan and GPS fix
always (a measurement needs a state at its own time; attaching it to a nearby keyframe would
inject a timing error), plus, when set, one every k motion samples (e.g. between sparse GPS
fixes, or to bound the preintegration length).

Committing a keyframe: its motion factor and predicted state, its GPS factors; when a scan
is scored or associated against a prediction, those are solved first (the prediction:
``smoothers.landmark_scans``); then the scans' factors and new landmarks; then the backend
update, and in the causal modes the keyframe's state with the marginals of its states from
one joint query, and a map snapshot when ``snapshot_interval_s`` says one is due.

The pieces: ``motion_setup`` (priors, motion model), ``pending_update`` (what the next
backend update adds), ``landmark_scans`` (the map and what scans do to it), ``backends``
(iSAM2 / fixed lag, Cholesky with the QR fallback), ``smoothed_output`` (the end of a run).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from typing import ClassVar

import gtsam
from pydantic import BaseModel

from datasets.errors import InputError
from datasets.estimate import Estimate, EstimateRecorder
from datasets.measurements import (
    GpsFix,
    ImuSample,
    LandmarkScan,
    Measurement,
    Odometry,
    Sensor,
)
from datasets.sequence import Sequence
from datasets.state import LandmarkMap, StateHistory
from datasets.stream_clock import StreamClock
from filters.association import AssociationPolicy
from smoothers.backends import FixedLagBackend, Isam2Backend
from smoothers.config import SmootherConfig
from smoothers.gps_factors import gps_factor
from smoothers.gtsam_errors import IndeterminateSystem
from smoothers.joint_marginals import JointMarginals, JointQuery
from smoothers.landmark_book import MapLandmark, anchor_landmarks
from smoothers.landmark_scans import LandmarkScans
from smoothers.motion_setup import initial_priors, motion_model
from smoothers.odometry_factors import RelativePoseAccumulator
from smoothers.pending_update import PendingUpdate
from smoothers.smoothed_output import landmark_map, smoothed_history


@dataclass
class _Group:
    """Keyframe-creating measurements sharing one time stamp [s]."""

    t: float
    scans: list[LandmarkScan] = field(default_factory=list)
    fixes: list[GpsFix] = field(default_factory=list)


class KeyframeSmoother:
    """Shared machinery of the smoother modes (see the module docstring).

    Subclasses choose the backend (``_make_backend``), whether to record the causal history
    (``record_causal``) and how to finish (``estimate``).

    Attributes:
        keyframe_t: each keyframe's time [s], keyframe 0 at the initial state.
        motion: the motion model. backend: the incremental solver.
        scans: the map and the scans' handling. recorder: the causal record and diagnostics.
        full_graph: every factor sent to the backend (the batch mode optimises it again).
        odometry_3d: 3-D relative-pose odometry between keyframes, when used.
    """

    Config: ClassVar[type[BaseModel]] = SmootherConfig
    sensor_options: ClassVar[tuple[frozenset[Sensor], ...]] = (
        frozenset({Sensor.IMU, Sensor.LANDMARKS}),
        frozenset({Sensor.IMU, Sensor.GPS}),
        frozenset({Sensor.IMU, Sensor.ODOMETRY}),
        frozenset({Sensor.ODOMETRY, Sensor.LANDMARKS}),
        frozenset({Sensor.GYRO, Sensor.LANDMARKS}),
    )
    dimensions: ClassVar[frozenset[int]] = frozenset({2, 3})
    record_causal: ClassVar[bool] = True
    mode: ClassVar[str] = "smoother"

    def __init__(self, config: SmootherConfig, sequence: Sequence) -> None:
        self.config = config
        self.sequence_name = sequence.name
        self.dimension = sequence.dimension
        if sequence.initial_state is None:
            raise InputError(
                f"{sequence.name}: the smoother needs an initial state (sequence.initial_state) to fix the frame; "
                "the dataset gives none, so the system would be indeterminate"
            )
        self.start = sequence.initial_state
        self.priors = initial_priors(config, sequence)
        self.motion = motion_model(config, sequence)
        self.recorder = EstimateRecorder(self.dimension, config.snapshot_interval_s)
        self.clock = StreamClock(f"{self.mode} smoother on {sequence.name}")
        self.backend = self._make_backend()
        self.full_graph = gtsam.NonlinearFactorGraph()
        self.notes: list[str] = []
        self.keyframe_t: list[float] = [float(self.start.t)]
        self.group: _Group | None = None
        self.estimate_values = gtsam.Values()  # the newest keyframe's solved states
        self.causal_covariances = True
        self.has_gps = Sensor.GPS in sequence.sensors and config.use_gps
        # lidar odometry beside the IMU: extra relative-pose factors (without an IMU it is
        # the motion model itself)
        self.odometry_3d = (
            RelativePoseAccumulator()
            if self.dimension == 3
            and config.use_odometry
            and Sensor.ODOMETRY in sequence.sensors
            and Sensor.IMU in sequence.sensors
            else None
        )
        self.pending = PendingUpdate()
        graph, values = self.motion.initial(self.start, self.priors)
        self.pending.add_graph(graph)
        self.pending.insert(values, self.start.t)
        self.scans = LandmarkScans(
            config,
            self.dimension,
            AssociationPolicy(config, self.dimension, sequence.noise.sighting_correlation),
            self.recorder,
            self.backend,
            self.pending,
        )
        for map_id, position in anchor_landmarks(config.anchors, sequence, self.dimension):
            self.scans.add_anchor(map_id, position, self.start.t)
        self.start_values = gtsam.Values(self.pending.values)
        self._fallback_reported = False
        self._solved = False  # a first update went through (``_stop``)
        # the solver's failure mid-run: (time [s], message); None while it holds
        self.stopped: tuple[float, str] | None = None
        self.dropped_after_stop = 0

    @property
    def landmarks(self) -> dict[int, MapLandmark]:
        """Map id -> ``MapLandmark`` of every landmark ever mapped."""
        return self.scans.book.landmarks

    # ------------------------------------------------------------------ subclass hooks
    def _make_backend(self) -> Isam2Backend | FixedLagBackend:
        """iSAM2 over the whole history (the fixed-lag mode overrides it)."""
        return Isam2Backend(
            self.config.relinearize_threshold,
            self.config.relinearize_skip,
            self.config.extra_iterations,
            self.dimension,
            self.config.factorization,
        )

    def _before_update(self, t_new: float) -> None:
        """Hook run before each backend update (fixed lag exports leaving keyframes)."""

    # ------------------------------------------------------------------ stream
    def process(self, measurement: Measurement) -> None:
        t = float(measurement.t)
        self.clock.advance(t, type(measurement).__name__)
        if self.stopped is not None:
            self.dropped_after_stop += 1
            return
        if self.group is not None and t > self.group.t:
            if self.motion.accepts(measurement):
                self.motion.look_ahead(measurement)
            self._commit_group()
        if self.motion.accepts(measurement):
            self._add_motion(measurement, t)
            return
        if t < self.start.t:
            self.recorder.event(
                t, "measurement_before_start_skipped", kind=type(measurement).__name__
            )
            return
        if isinstance(measurement, LandmarkScan):
            self._open_group(t).scans.append(measurement)
        elif isinstance(measurement, GpsFix) and self.has_gps:
            self._open_group(t).fixes.append(measurement)
        elif (
            isinstance(measurement, Odometry) and self.odometry_3d is not None and t > self.start.t
        ):
            # A relative pose ends at a state: it opens a keyframe at its own time.
            self.odometry_3d.add(measurement)
            if measurement.relative_pose is not None:
                self._open_group(t)

    def _add_motion(self, measurement: Measurement, t: float) -> None:
        if t < self.start.t and isinstance(measurement, Odometry):
            if measurement.relative_pose is not None:
                return  # an increment ending before the start moves no state we have
        if not self.motion.add(measurement) and isinstance(measurement, ImuSample):
            self.recorder.event(t, "duplicate_imu_sample_skipped")
        stride = self.config.keyframe_imu_stride
        if stride and self.motion.since_keyframe() >= stride and t > self.keyframe_t[-1]:
            self._open_group(t)
        if isinstance(measurement, Odometry) and measurement.frame and t > self.keyframe_t[-1]:
            # a sensor frame (a lidar sweep) with or without landmarks: a pose is expected
            # there (``Estimate.frame_times``), so it is a keyframe
            self._open_group(t)
        bridge = self.bridge_interval_s()
        if bridge is not None and t - self.keyframe_t[-1] >= bridge:
            self._open_group(t)

    def _keyframe_group(self, t: float, informative: bool) -> None:
        """Hook: a keyframe group at ``t`` [s] is committed; ``informative`` when it carries
        a measurement other than motion (fixed lag advances its clock)."""

    def bridge_interval_s(self) -> float | None:
        """The longest stretch without a keyframe [s] (None: no limit); a mode whose window
        must not run empty says how long."""
        return None

    def _open_group(self, t: float) -> _Group:
        if self.group is None:
            self.group = _Group(t)
        return self.group

    def _commit_group(self) -> None:
        group = self.group
        assert group is not None
        self.group = None
        t = group.t
        self._keyframe_group(t, bool(group.scans or group.fixes))
        k = len(self.keyframe_t) - 1
        created = t > self.keyframe_t[-1]
        if created:
            k += 1
            graph, values = self.motion.close(k, t, self._current_values())
            self.pending.add_graph(graph)
            self.pending.insert(values, t)
            self.keyframe_t.append(t)
            if self.odometry_3d is not None:
                factor = self.odometry_3d.factor(
                    self.motion.pose_key(k - 1), self.motion.pose_key(k)
                )
                if factor is not None:
                    self.pending.add(factor)
                self.odometry_3d.start()
        for fix in group.fixes:
            self.pending.add(gps_factor(self.motion.pose_key(k), fix, self.dimension))
        try:
            if group.scans:
                if any(self.scans.needs_prediction(scan) for scan in group.scans):
                    # The prediction: this keyframe's motion (and GPS) factors solved first.
                    self._solve_pending(t)
                pose = self.motion.pose_of(self._current_values(), k)
                for scan in group.scans:
                    self.scans.add(scan, k, self.motion.pose_key(k), pose)
            self._update(t)
        except IndeterminateSystem as failure:
            self._stop(t, failure)
            return
        self._solved = True
        if created:
            self.motion.restart(t, self.estimate_values, k)

    def _stop(self, t: float, failure: IndeterminateSystem) -> None:
        """GTSAM found the system indeterminate at ``t`` [s]. At the first solve that is the
        input's fault (nothing fixes some state): raised. Mid-run, on a graph that solved
        before, it is the solver's numerical failure, in practice an estimate that diverged
        (values of 1e250 before the exception): the run stops there and keeps what it has,
        its causal states up to ``t``, with the failure as an event and a note
        (``workbench.metrics.divergence`` reports it as diverged). A batch smoother has
        nothing to keep before its end: raised."""
        if not self._solved or not self.record_causal:
            raise failure
        reason = f"GTSAM: {failure.gtsam or failure}"
        self.stopped = (float(t), reason)
        self.recorder.event(t, "solver_failed", reason=reason)
        self.notes.append(
            f"{self.mode} smoother: stopped at t={t:.3f} s, GTSAM could no longer solve the "
            f"system on a graph it had solved before (its estimate had diverged): no estimate "
            f"after it ({reason})"
        )

    def stopped_notes(self) -> tuple[str, ...]:
        """The run's notes, with how many measurements arrived after the solver stopped and
        were not used (``_stop``): the estimate's notes when it stopped."""
        return tuple(self.notes) + (
            f"{self.mode} smoother: {self.dropped_after_stop} measurement(s) after the stop "
            "not used",
        )

    def _current_values(self) -> gtsam.Values:
        """Newest keyframe's estimate, with the not yet committed values layered on top."""
        values = gtsam.Values(self.estimate_values)
        for key in self.pending.values.keys():
            if values.exists(key):
                values.erase(key)
        values.insert(self.pending.values)
        return values

    # ------------------------------------------------------------------ backend
    def _solve_pending(self, t: float) -> None:
        """Send the pending factors to the backend without recording a causal state."""
        self._before_update(t)
        graph, values, times = self.pending.take()
        self.full_graph.push_back(graph)
        newest = self.motion.keys(len(self.keyframe_t) - 1)
        self.backend.update(graph, values, times, t, newest)
        self._report_fallback()
        # Only the newest keyframe's state is needed to go on (the full estimate is O(n)).
        self.estimate_values = self.backend.values(self.motion.keys(len(self.keyframe_t) - 1), t)
        self._after_solve(t, graph)

    def _after_solve(self, t: float, graph: gtsam.NonlinearFactorGraph) -> None:
        """Hook run after each backend update with its new factors (fixed lag checks that
        its window took them, ``smoothers.window_health``)."""

    def _report_fallback(self) -> None:
        """The backend's switch from Cholesky to QR, once, as an event and a note."""
        fallback = self.backend.fallback
        if fallback is not None and not self._fallback_reported:
            self._fallback_reported = True
            self.recorder.event(
                fallback.t, "factorization_fallback", to="QR", reason=fallback.reason
            )
            self.notes.append(
                f"iSAM2's Cholesky factorisation failed at t={fallback.t:.3f} s; QR from there on "
                f"(GTSAM: {fallback.reason})"
            )

    def _update(self, t: float) -> None:
        self._solve_pending(t)
        if not self.record_causal:
            return
        k = len(self.keyframe_t) - 1
        marginals = self.keyframe_marginals([k], t) if self.causal_covariances else None
        self.motion.record(self.recorder, t, self.estimate_values, k, marginals)
        if self.recorder.snapshot_due(t):
            self._snapshot(t)
        self._report_fallback()

    def _snapshot(self, t: float) -> None:
        """The map the backend holds at ``t`` [s] with its joint covariance (one query)."""
        solved = self.scans.solved()
        if not solved:
            return
        values = self.backend.values([landmark.key for landmark in solved])
        joint = partial(self.backend.joint, t=t)
        self.recorder.landmarks(landmark_map(solved, values, joint, self.dimension, t))

    def keyframe_marginals(self, keyframes: list[int], t: float = float("nan")) -> JointMarginals:
        """One batched marginal query over the states of ``keyframes``."""
        return self.backend.joint([key for k in keyframes for key in self.motion.keys(k)], t)

    # ------------------------------------------------------------------ output
    def _flush(self) -> None:
        if self.stopped is None and self.group is not None:
            self._commit_group()
        if self.stopped is None and not self.pending.empty():
            try:
                self._update(self.keyframe_t[-1])
            except IndeterminateSystem as failure:
                self._stop(self.keyframe_t[-1], failure)

    def landmark_map(self, values: gtsam.Values, joint: JointQuery) -> LandmarkMap:
        """World-frame map at the last keyframe of the landmarks whose variables ``values``
        holds, with their joint covariance from one batched query."""
        return landmark_map(
            self.scans.book.sorted(), values, joint, self.dimension, self.keyframe_t[-1]
        )

    def smoothed_history(
        self, values: gtsam.Values, joint: JointQuery, keyframes: list[int] | None = None
    ) -> StateHistory:
        """Every keyframe's (or ``keyframes``') state at ``values`` with marginals from
        batched queries."""
        return smoothed_history(
            self.motion, self.keyframe_t, values, joint, self.dimension, keyframes
        )

    def estimate(self) -> Estimate:  # pragma: no cover - subclasses
        raise NotImplementedError
