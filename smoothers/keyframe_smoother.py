"""The keyframe factor-graph smoother shared by the batch, iSAM2 and fixed-lag modes.

Data flow: motion samples (IMU in 3-D; odometry or a rate gyro in 2-D) are accumulated by a
motion model (``smoothers.imu_graph.ImuMotion``, ``smoothers.planar_graph.PlanarMotion``,
chosen by the sequence's dimension); measurements that need a state at their own time
(landmark scans, GPS fixes) open a keyframe at that time. A keyframe is committed once the
stream has moved past its time, so every motion sample up to it is in and measurements with
the same time stamp (duplicates) share one keyframe. Each committed keyframe goes to an
incremental backend (iSAM2 or the fixed-lag smoother).

Keyframe policy (``keyframe_imu_stride``): a keyframe at every landmark scan and GPS fix
always (a measurement needs a state at its own time; attaching it to a nearby keyframe would
inject a timing error), plus, when set, one every k motion samples (e.g. between sparse GPS
fixes, or to bound the preintegration length).

Scans (``smoothers.landmark_scans``): when a keyframe's scans may see landmarks already in
the map, its motion (and GPS) factors are solved first, so the backend's estimate of the new
pose is the prediction and the joint marginal of that pose and the landmarks its covariance.
Against that prediction every sighting is decided by the shared association policy
(``filters.association``: the scan's ids, or JCBB on the landmarks within reach), and the
matched sightings' stacked NIS is recorded, as every filter records it
(``innovation_nis=false`` skips the joint marginal query when association does not need it:
about a millisecond on sparse maps, 0.2-0.3 s per keyframe with 200 landmarks in view).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

import gtsam
import numpy as np
from pydantic import BaseModel

from datasets.errors import InputError
from datasets.estimate import AssociationDecision, Estimate, EstimateRecorder
from datasets.measurements import (
    GpsFix,
    ImuSample,
    LandmarkScan,
    Measurement,
    Odometry,
    Sensor,
)
from datasets.sequence import Sequence
from datasets.state import Frame, LandmarkMap, StateHistory
from datasets.stream_clock import StreamClock
from filters.association import AssociationPolicy, ScanAssociation
from smoothers.backends import FixedLagBackend, Isam2Backend, JointMarginals
from smoothers.config import SmootherConfig
from smoothers.covariances import symmetric
from smoothers.imu_graph import ImuMotion, ImuNoise
from smoothers.initialization import InitialPriors
from smoothers.landmark_factors import (
    body_point_factor_2d,
    body_point_factor_3d,
    cartesian_point_factor_3d,
    check_measurement_covariance,
    landmark_prior,
)
from smoothers.landmark_scans import (
    KeyframePredictor,
    LandmarkBook,
    MapLandmark,
    pose_and_positions,
)
from smoothers.odometry_factors import RelativePoseAccumulator
from smoothers.planar_graph import PlanarMotion

KEYFRAMES_PER_MARGINAL_QUERY = 32
"""Keyframes whose states share one batched joint marginal query in the smoothed history."""


@dataclass
class _Group:
    """Keyframe-creating measurements sharing one time stamp."""

    t: float
    scans: list[LandmarkScan] = field(default_factory=list)
    fixes: list[GpsFix] = field(default_factory=list)


class KeyframeSmoother:
    """Shared machinery of the smoother modes (see the module docstring).

    Subclasses choose the backend (``_make_backend``), whether to record the causal history
    (``record_causal``) and how to finish (``estimate``).
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
        if self.dimension == 3 and Sensor.IMU not in sequence.sensors:
            raise InputError(f"{sequence.name}: the 3-D smoother needs IMU samples")
        self.start = sequence.initial_state
        self.priors = self._priors(sequence)
        self.motion = self._motion_model(sequence)
        self.recorder = EstimateRecorder(self.dimension, config.snapshot_interval_s)
        self.policy = AssociationPolicy(config, self.dimension)
        self.clock = StreamClock(f"{self.mode} smoother on {sequence.name}")
        self.backend = self._make_backend()
        self.full_graph = gtsam.NonlinearFactorGraph()
        self.notes: list[str] = []
        self.book = LandmarkBook()
        self.keyframe_t: list[float] = []
        self.group: _Group | None = None
        self.estimate_values = gtsam.Values()
        self.causal_covariances = True
        self.has_gps = Sensor.GPS in sequence.sensors and config.use_gps
        self.odometry_3d = (
            RelativePoseAccumulator()
            if self.dimension == 3 and config.use_odometry and Sensor.ODOMETRY in sequence.sensors
            else None
        )
        graph, values = self.motion.initial(self.start, self.priors)
        self.pending_graph = graph
        self.pending_values = values
        self.pending_times = {key: float(self.start.t) for key in self.motion.keys(0)}
        self.keyframe_t.append(float(self.start.t))
        self.first_sightings: dict[int, tuple[int, np.ndarray]] = {}
        self._add_anchors(sequence)
        self.start_values = gtsam.Values(self.pending_values)
        self._fallback_reported = False

    @property
    def landmarks(self) -> dict[int, MapLandmark]:
        """Map id -> ``MapLandmark`` of every landmark ever mapped."""
        return self.book.landmarks

    # ------------------------------------------------------------------ set-up
    def _priors(self, sequence: Sequence) -> InitialPriors:
        c, s, n = self.config, sequence.initial_state, sequence.noise
        assert s is not None
        return InitialPriors(
            position_sigma_m=c.position_sigma_m or s.position_sigma_m,
            rotation_sigma_rad=c.rotation_sigma_rad or s.rotation_sigma_rad,
            velocity_sigma_m_s=c.velocity_sigma_m_s or s.velocity_sigma_m_s,
            gyro_bias_sigma_rad_s=c.gyro_bias_sigma_rad_s or n.gyro_bias_sigma_rad_s or 0.01,
            accel_bias_sigma_m_s2=c.accel_bias_sigma_m_s2 or n.accel_bias_sigma_m_s2 or 0.1,
        )

    def _motion_model(self, sequence: Sequence) -> ImuMotion | PlanarMotion:
        c = self.config
        if sequence.dimension == 3:
            gravity = c.gravity_m_s2 or float(sequence.metadata.get("gravity_m_s2", 9.81))
            return ImuMotion(
                ImuNoise.from_spec(sequence.noise, sequence.name),
                gravity,
                c.max_imu_gap_s,
                c.imu_interpolation,
            )
        if Sensor.ODOMETRY in sequence.sensors:
            source = "odometry"
        elif Sensor.GYRO in sequence.sensors:
            source = "gyro"
        else:
            raise InputError(f"{sequence.name}: the planar smoother needs odometry or a rate gyro")
        gyro_density = c.planar_gyro_density or sequence.noise.gyro_noise_density
        if source == "gyro" and not gyro_density:
            raise InputError(
                f"{sequence.name}: gyro-only planar smoother needs the gyro noise density (sequence.noise or planar_gyro_density)"
            )
        gyro_walk = sequence.noise.gyro_bias_walk or 1e-4
        return PlanarMotion(
            source,
            c.planar_velocity_walk_m_s2,
            gyro_density or 0.0,
            gyro_walk,
            c.odometry_lateral_sigma_m_s,
            c.max_imu_gap_s,
        )

    def _add_anchors(self, sequence: Sequence) -> None:
        count = self.config.anchors
        if count is None:
            count = 3 if sequence.known_landmarks is not None and self.dimension == 3 else 0
        self.anchor_count = count
        if count == 0:
            return
        known = sequence.known_landmarks
        if known is None or len(known) < count:
            have = 0 if known is None else len(known)
            raise InputError(
                f"{sequence.name}: anchors={count} but the dataset offers {have} known landmarks"
            )
        if known.dimension != self.dimension:
            raise InputError(
                f"{sequence.name}: known landmarks are {known.dimension}-D, the sequence is {self.dimension}-D"
            )
        for index in range(count):
            position = np.asarray(known.positions[index], dtype=float)
            landmark = self._new_variable(int(known.ids[index]), position, self.start.t)
            landmark.anchor_position = position
            self.pending_graph.add(
                landmark_prior(landmark.key, position, self.config.anchor_sigma_m)
            )

    def _new_variable(self, map_id: int, position: np.ndarray, t: float) -> MapLandmark:
        """A new variable for landmark ``map_id`` at ``position`` (created when unknown)."""
        landmark = self.book.variable(map_id, t)
        self.pending_values.insert(landmark.key, position)
        self.pending_times[landmark.key] = float(t)
        return landmark

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
        """Hook run before each backend update (fixed lag records leaving keyframes)."""

    # ------------------------------------------------------------------ stream
    def process(self, measurement: Measurement) -> None:
        t = float(measurement.t)
        self.clock.advance(t, type(measurement).__name__)
        if self.group is not None and t > self.group.t:
            if self.motion.accepts(measurement):
                self.motion.look_ahead(measurement)  # type: ignore[arg-type]
            self._commit_group()
        if self.motion.accepts(measurement):
            if (
                t < self.start.t
                and isinstance(measurement, Odometry)
                and measurement.relative_pose is not None
            ):
                return
            if isinstance(measurement, ImuSample):
                before = self.motion.integrator.held_t  # type: ignore[union-attr]
                self.motion.add(measurement)  # type: ignore[arg-type]
                if before == measurement.t:
                    self.recorder.event(t, "duplicate_imu_sample_skipped")
            else:
                self.motion.add(measurement)  # type: ignore[arg-type]
            stride = self.config.keyframe_imu_stride
            if stride and self.motion.since_keyframe() >= stride and t > self.keyframe_t[-1]:
                self._open_group(t)
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

    def _open_group(self, t: float) -> _Group:
        if self.group is None:
            self.group = _Group(t)
        return self.group

    def _commit_group(self) -> None:
        group = self.group
        assert group is not None
        self.group = None
        t = group.t
        k = len(self.keyframe_t) - 1
        created = t > self.keyframe_t[-1]
        if created:
            k += 1
            graph, values = self.motion.close(k, t, self._current_values())
            self.pending_graph.push_back(graph)
            self.pending_values.insert(values)
            for key in self.motion.keys(k):
                self.pending_times[key] = t
            self.keyframe_t.append(t)
            if self.odometry_3d is not None:
                factor = self.odometry_3d.factor(
                    self.motion.pose_key(k - 1), self.motion.pose_key(k)
                )
                if factor is not None:
                    self.pending_graph.add(factor)
                self.odometry_3d.start()
        for fix in group.fixes:
            self._add_gps(k, fix)
        if any(self._needs_prediction(scan) for scan in group.scans):
            # The prediction: this keyframe's motion (and GPS) factors solved first.
            self._solve_pending(t)
        for scan in group.scans:
            self._add_scan(k, scan)
        self._update(t)
        if created:
            self.motion.restart(t, self.estimate_values, k)

    def _needs_prediction(self, scan: LandmarkScan) -> bool:
        """Whether the scan is scored or associated against a prediction (NIS, the id gate,
        JCBB) and the map has a landmark it could see."""
        uses = (
            self.config.innovation_nis
            or self.config.id_gate_probability is not None
            or self.policy.mode(scan.ids, scan.t) != "ids"
        )
        return uses and any(self.backend.contains(lm.key) for lm in self.landmarks.values())

    def _current_values(self) -> gtsam.Values:
        """Newest keyframe's estimate, with the not yet committed values layered on top."""
        values = gtsam.Values(self.estimate_values)
        for key in self.pending_values.keys():
            if values.exists(key):
                values.erase(key)
        values.insert(self.pending_values)
        return values

    def _solve_pending(self, t: float) -> None:
        """Send the pending factors to the backend without recording a causal state."""
        self._before_update(t)
        self.full_graph.push_back(self.pending_graph)
        self.backend.update(self.pending_graph, self.pending_values, self.pending_times, t)
        self.pending_graph = gtsam.NonlinearFactorGraph()
        self.pending_values = gtsam.Values()
        self.pending_times = {}
        self._report_fallback()
        # Only the newest keyframe's state is needed to go on (the full estimate is O(n)).
        self.estimate_values = self.backend.values(self.motion.keys(len(self.keyframe_t) - 1))

    def _report_fallback(self) -> None:
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
        k = len(self.keyframe_t) - 1
        if self.record_causal:
            marginals = self.keyframe_marginals([k], t) if self.causal_covariances else None
            self.motion.record(self.recorder, t, self.estimate_values, k, marginals)
            self._report_fallback()

    def keyframe_marginals(self, keyframes: list[int], t: float = float("nan")) -> JointMarginals:
        """One batched marginal query over the states of ``keyframes``."""
        return self.backend.joint([key for k in keyframes for key in self.motion.keys(k)], t)

    # ------------------------------------------------------------------ measurements
    def _add_gps(self, k: int, fix: GpsFix) -> None:
        position = np.asarray(fix.position, dtype=float)
        covariance = np.asarray(fix.covariance, dtype=float)
        if self.dimension != 3 or position.shape != (3,) or covariance.shape != (3, 3):
            raise InputError(
                f"GPS fix at t={fix.t:.6f} s: expected a 3-D position and a (3, 3) covariance"
            )
        if not (np.all(np.isfinite(position)) and np.all(np.isfinite(covariance))):
            raise InputError(f"GPS fix at t={fix.t:.6f} s is not finite")
        self.pending_graph.add(
            gtsam.GPSFactor(
                self.motion.pose_key(k), position, gtsam.noiseModel.Gaussian.Covariance(covariance)
            )
        )

    def _check_scan(self, scan: LandmarkScan) -> tuple[np.ndarray, np.ndarray]:
        points = np.asarray(scan.points, dtype=float)
        covariances = np.asarray(scan.covariances, dtype=float)
        d = self.dimension
        if points.ndim != 2 or points.shape[1] != d or covariances.shape != (points.shape[0], d, d):
            raise InputError(
                f"landmark scan at t={scan.t:.6f} s: points {points.shape} / covariances {covariances.shape} do not match dimension {d}"
            )
        if not np.all(np.isfinite(points)):
            raise InputError(f"landmark scan at t={scan.t:.6f} s contains non-finite points")
        for index, covariance in enumerate(covariances):
            check_measurement_covariance(covariance, scan.t, index)
        return points, covariances * self.config.measurement_noise_scale

    def _point_factor(
        self, pose_key: int, landmark_key: int, point: np.ndarray, covariance: np.ndarray
    ) -> gtsam.NonlinearFactor:
        if self.dimension == 2:
            return body_point_factor_2d(pose_key, landmark_key, point, covariance)
        if self.config.landmark_factor == "cartesian":
            return cartesian_point_factor_3d(pose_key, landmark_key, point, covariance)
        return body_point_factor_3d(pose_key, landmark_key, point, covariance)

    def _predictor(self, k: int, candidates: list[MapLandmark]) -> KeyframePredictor:
        """Predictions of ``candidates`` from keyframe ``k``'s solved pose."""
        keys = [landmark.key for landmark in candidates]
        values = gtsam.Values(self.estimate_values)
        values.insert(self.backend.values(keys))
        pose, positions = pose_and_positions(values, self.motion.pose_key(k), keys, self.dimension)
        return KeyframePredictor(
            pose, self.motion.pose_key(k), candidates, positions, self.backend.joint, self.dimension
        )

    def _associate(
        self, k: int, scan: LandmarkScan, points: np.ndarray, covariances: np.ndarray
    ) -> tuple[ScanAssociation, list[MapLandmark], KeyframePredictor | None]:
        """Decisions for the scan's sightings, the candidates their indices refer to, and the
        prediction they were made against (None without candidates)."""
        alive = [lm for lm in self.book.sorted() if self.backend.contains(lm.key)]
        mode = self.policy.mode(scan.ids, scan.t)
        if mode == "ids":
            wanted = {int(i) for i in scan.ids}
            candidates = [lm for lm in alive if lm.map_id in wanted]
            predictor = (
                self._predictor(k, candidates)
                if candidates and self._needs_prediction(scan)
                else None
            )
            ids = np.array([lm.map_id for lm in candidates], dtype=int)
            association = self.policy.by_ids(scan.ids, points, covariances, ids, predictor)
            return association, candidates, predictor
        candidates, predictor = [], None
        if alive:
            # only landmarks within reach of this scan can be seen (bounded JCBB input)
            everything = self._predictor(k, alive)
            reach = float(np.max(np.linalg.norm(points, axis=1), initial=0.0)) * 1.5 + 5.0
            near = np.flatnonzero(np.linalg.norm(everything.predicted, axis=1) < reach)
            if near.size:
                predictor = everything.subset(near)
                candidates = predictor.candidates
        association = self.policy.by_geometry(points, covariances, len(candidates), predictor, mode)
        if association.search is not None and association.search.truncated:
            self.recorder.event(scan.t, "jcbb_truncated", nodes=association.search.nodes)
        return association, candidates, predictor

    def _add_scan(self, k: int, scan: LandmarkScan) -> None:
        points, covariances = self._check_scan(scan)
        association, candidates, predictor = self._associate(k, scan, points, covariances)
        matched = association.rows(AssociationDecision.MATCHED)
        if len(matched) and predictor is not None and self.config.innovation_nis:
            innovation = predictor.innovation(
                association.candidates[matched], points[matched], covariances[matched]
            )
            if innovation is not None:
                self.recorder.innovation(
                    scan.t,
                    innovation.nis,
                    innovation.dof,
                    innovation.group_nis,
                    innovation.group_dof,
                )
        values = self._current_values()
        pose = self.motion.pose_of(values, k)
        for index, decision in enumerate(association.decisions):
            point = points[index]
            reason = association.reasons[index]
            landmark: MapLandmark | None = None
            if decision == AssociationDecision.MATCHED:
                landmark = candidates[int(association.candidates[index])]
            elif decision == AssociationDecision.NEW:
                if self.dimension == 3 and np.linalg.norm(point) < 1e-3:
                    decision, reason = AssociationDecision.REJECTED, "at the sensor origin"
                else:
                    landmark = self._map_new(k, scan, index, pose, point)
            if landmark is None:
                self.recorder.association(scan.t, index, -1, decision, reason)
                continue
            self.pending_graph.add(
                self._point_factor(
                    self.motion.pose_key(k), landmark.key, point, association.noise[index]
                )
            )
            landmark.observations += 1
            landmark.last_t = scan.t
            self.pending_times[landmark.key] = float(scan.t)
            self.recorder.association(
                scan.t, index, landmark.map_id, decision, reason, association.inflation[index]
            )
        self.recorder.landmark_count(
            scan.t, sum(1 for lm in self.landmarks.values() if self._key_alive(lm.key))
        )

    def _map_new(
        self, k: int, scan: LandmarkScan, index: int, pose, point: np.ndarray
    ) -> MapLandmark:
        """A new landmark (or a new variable of a known one that left the window) from a
        sighting; an anchor re-created keeps its prior."""
        with_ids = scan.ids is not None and self.policy.mode(scan.ids, scan.t) == "ids"
        map_id = int(scan.ids[index]) if with_ids else self.book.new_map_id()
        world = np.asarray(pose.transformFrom(point), dtype=float)
        landmark = self._new_variable(map_id, world, scan.t)
        self.first_sightings[landmark.key] = (k, np.asarray(point, dtype=float))
        if landmark.anchor_position is not None:
            self.pending_graph.add(
                landmark_prior(landmark.key, landmark.anchor_position, self.config.anchor_sigma_m)
            )
        return landmark

    def _key_alive(self, key: int) -> bool:
        return self.pending_values.exists(key) or self.backend.contains(key)

    # ------------------------------------------------------------------ output
    def _flush(self) -> None:
        if self.group is not None:
            self._commit_group()
        if self.pending_graph.size() or self.pending_values.size():
            self._update(self.keyframe_t[-1])

    def landmark_map(self, values: gtsam.Values, joint) -> LandmarkMap:
        """World-frame map of the landmarks whose variables ``values`` holds, with their
        joint covariance from one batched query (``joint``: keys -> ``JointMarginals``)."""
        present = [lm for lm in self.book.sorted() if values.exists(lm.key)]
        if not present:
            return LandmarkMap.empty(self.dimension)
        keys = [lm.key for lm in present]
        read = values.atPoint3 if self.dimension == 3 else values.atPoint2
        positions = np.array([read(key) for key in keys], dtype=float)
        covariance = symmetric(joint(keys).matrix(keys))
        t = self.keyframe_t[-1]
        return LandmarkMap.from_joint(
            [lm.map_id for lm in present], positions, covariance, Frame.WORLD, t
        )

    def smoothed_history(
        self, values: gtsam.Values, joint, keyframes: list[int] | None = None
    ) -> StateHistory:
        """Every keyframe's (or ``keyframes``') state at ``values`` with marginals from
        batched queries (``joint``: keys -> ``JointMarginals``)."""
        recorder = EstimateRecorder(self.dimension)
        chosen = list(range(len(self.keyframe_t))) if keyframes is None else keyframes
        for start in range(0, len(chosen), KEYFRAMES_PER_MARGINAL_QUERY):
            chunk = chosen[start : start + KEYFRAMES_PER_MARGINAL_QUERY]
            marginals = joint([key for k in chunk for key in self.motion.keys(k)])
            for k in chunk:
                self.motion.record(recorder, self.keyframe_t[k], values, k, marginals)
        return recorder.history()

    def estimate(self) -> Estimate:  # pragma: no cover - subclasses
        raise NotImplementedError
