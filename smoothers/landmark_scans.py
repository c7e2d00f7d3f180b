"""Landmark scans in the smoother: each sighting decided, recorded, and turned into factors.

For every scan of a keyframe:
1. the scan is checked (shapes, finite points, positive-definite covariances: bad input is
   an ``InputError``) and its noise scaled by ``measurement_noise_scale``; a 3-D sighting
   at the sensor origin has no bearing and is rejected (``AT_SENSOR_ORIGIN``);
2. every sighting is decided by the shared policy (``smoothers.scan_association``) against
   the keyframe's prediction: the keyframe's motion (and GPS) factors solved first, so the
   prediction is the solved pose with the joint marginal of that pose and the observed
   landmarks (``smoothers.keyframe_prediction``);
3. the scan's NIS is recorded as every filter records it (``EstimateRecorder.innovation``):
   the stacked NIS of its matched sightings against that prediction *before* the scan's own
   factors are added, ``nu^T (H J H^T + R)^-1 nu`` with dof = rows, and each landmark's own
   (d dof), with ids or geometric association alike. ``R`` is the noise the scan states
   (scaled), even where the id gate inflated the noise a sighting is used with. A
   landmark created by this scan (or an earlier scan of the same keyframe) has no
   prediction: it is not in the NIS;
4. matched sightings add a body-frame point factor to their landmark, new ones create a
   landmark (a variable placed from the sighting, an anchor's prior again if it is one);
5. every sighting is recorded with its typed decision and, when not used, the reason
   (``EstimateRecorder.association``), so none is dropped silently.
"""

from __future__ import annotations

import numpy as np

from datasets.errors import InputError
from datasets.estimate import AssociationDecision, EstimateRecorder
from datasets.measurements import LandmarkScan
from filters.association import AssociationPolicy, ScanAssociation
from smoothers.config import SmootherConfig
from smoothers.keyframe_prediction import KeyframePredictor
from smoothers.landmark_book import LandmarkBook, MapLandmark
from smoothers.landmark_factors import (
    MIN_RANGE_M,
    check_measurement_covariance,
    landmark_marginal_prior,
    landmark_prior,
    point_factor,
)
from smoothers.pending_update import PendingUpdate
from smoothers.scan_association import associate_scan

AT_SENSOR_ORIGIN = "at the sensor origin"
"""Reason of a 3-D sighting nearer than ``MIN_RANGE_M``: it has no bearing, so it is
rejected before association (it could neither place a landmark nor make a bearing-range
factor, and its direction would be noise in the NIS)."""


class LandmarkScans:
    """The map's landmarks and what each scan does to them (module docstring).

    Args:
        config: the smoother's options. dimension: d, 2 or 3.
        policy: the shared association policy. recorder: where decisions and NIS go.
        backend: the incremental solver (``contains``, ``values``, ``joint``).
        pending: the next backend update, which the scans' factors and variables join.

    Attributes:
        book: the map (ids, current variables).
        first_sightings: landmark key -> (keyframe, sighting (d,) [m]) that created it
            (the batch mode's dead-reckoning start places landmarks from it).
    """

    def __init__(
        self,
        config: SmootherConfig,
        dimension: int,
        policy: AssociationPolicy,
        recorder: EstimateRecorder,
        backend,
        pending: PendingUpdate,
    ) -> None:
        self.config = config
        self.dimension = dimension
        self.policy = policy
        self.recorder = recorder
        self.backend = backend
        self.pending = pending
        self.book = LandmarkBook()
        # map id -> (position, covariance) of landmarks that left a fixed-lag window
        self.departed: dict[int, tuple[np.ndarray, np.ndarray]] = {}
        self.first_sightings: dict[int, tuple[int, np.ndarray]] = {}

    # ------------------------------------------------------------------ the map
    def add_anchor(self, map_id: int, position: np.ndarray, t: float) -> None:
        """A known landmark at its surveyed ``position`` (d,) [m] with its tight prior."""
        landmark = self._new_variable(map_id, position, t)
        landmark.anchor_position = np.asarray(position, dtype=float)
        self.pending.add(landmark_prior(landmark.key, position, self.config.anchor_sigma_m))

    def _new_variable(self, map_id: int, position: np.ndarray, t: float) -> MapLandmark:
        """A new variable for landmark ``map_id`` at ``position`` (created when unknown)."""
        landmark = self.book.variable(map_id, t)
        self.pending.insert_point(landmark.key, position, t)
        return landmark

    def solved(self) -> list[MapLandmark]:
        """The landmarks whose current variables the backend holds, by map id."""
        return [lm for lm in self.book.sorted() if self.backend.contains(lm.key)]

    def alive_count(self) -> int:
        """Landmarks with a variable in the backend or the pending update."""
        return sum(
            1
            for lm in self.book.landmarks.values()
            if self.pending.holds(lm.key) or self.backend.contains(lm.key)
        )

    # ------------------------------------------------------------------ scans
    def needs_prediction(self, scan: LandmarkScan) -> bool:
        """Whether the scan is scored or associated against a prediction (NIS, the id gate,
        JCBB) and the map has a landmark it could see. A landmark whose variable is still
        pending counts (the anchors before the first update): solved first, it is a
        candidate, where unsolved it would be mapped a second time from its sighting."""
        uses = (
            self.config.innovation_nis
            or self.config.id_gate_probability is not None
            or self.policy.mode(scan.ids, scan.t) != "ids"
        )
        return uses and any(
            self.backend.contains(lm.key) or self.pending.holds(lm.key)
            for lm in self.book.landmarks.values()
        )

    def check(self, scan: LandmarkScan) -> tuple[np.ndarray, np.ndarray]:
        """(points (k, d) [m], covariances (k, d, d) [m^2] scaled by the noise option);
        ``InputError`` on malformed input."""
        points = np.asarray(scan.points, dtype=float)
        covariances = np.asarray(scan.covariances, dtype=float)
        d = self.dimension
        if points.ndim != 2 or points.shape[1] != d or covariances.shape != (points.shape[0], d, d):
            raise InputError(
                f"landmark scan at t={scan.t:.6f} s: points {points.shape} / covariances "
                f"{covariances.shape} do not match dimension {d}"
            )
        if not np.all(np.isfinite(points)):
            raise InputError(f"landmark scan at t={scan.t:.6f} s contains non-finite points")
        for index, covariance in enumerate(covariances):
            check_measurement_covariance(covariance, scan.t, index)
        return points, covariances * self.config.measurement_noise_scale

    def add(self, scan: LandmarkScan, k: int, pose_key: int, pose) -> None:
        """Decide, score, record and add the factors of ``scan`` at keyframe ``k``.

        Args:
            pose_key: keyframe ``k``'s pose key. pose: its pose (``gtsam.Pose3``/``Pose2``):
                the solved one when ``needs_prediction`` said so (the prediction), else the
                motion model's (only places new landmarks then).
        """
        points, covariances = self.check(scan)
        usable = np.arange(len(points))
        if self.dimension == 3:  # a 3-D point at the sensor has no bearing
            usable = np.flatnonzero(np.linalg.norm(points, axis=1) >= MIN_RANGE_M)
        decided = associate_scan(
            self.policy,
            None if scan.ids is None else np.asarray(scan.ids)[usable],
            scan.t,
            points[usable],
            covariances[usable],
            self.solved(),
            lambda candidates: self._predict(candidates, pose_key, pose),
            self.needs_prediction(scan),
        )
        association = decided.association.embedded(usable, len(points), AT_SENSOR_ORIGIN)
        matched = association.rows(AssociationDecision.MATCHED)
        landmarks = np.full(len(points), -1, dtype=int)
        landmarks[matched] = [
            decided.candidates[int(i)].map_id for i in association.candidates[matched]
        ]
        association = self.policy.decorrelated(association, scan.t, points, covariances, landmarks)
        if association.search is not None and association.search.truncated:
            self.recorder.event(scan.t, "jcbb_truncated", nodes=association.search.nodes)
        if decided.predictor is not None and self.config.innovation_nis:
            self._record_nis(scan.t, association, decided.predictor, points, covariances)
        for index, decision in enumerate(association.decisions):
            point = points[index]
            reason = association.reasons[index]
            landmark: MapLandmark | None = None
            if decision == AssociationDecision.MATCHED:
                landmark = decided.candidates[int(association.candidates[index])]
            elif decision == AssociationDecision.NEW:
                landmark = self._unsolved_with_id(scan, index, association)
                if landmark is not None:
                    decision = AssociationDecision.MATCHED
                    # correlated with the sighting that created it moments ago
                    association.noise[index] = self.policy.correlated_noise(
                        landmark.map_id, scan.t, point, covariances[index], association.noise[index]
                    )
                else:
                    returning = association.mode == "ids" and int(scan.ids[index]) in self.departed
                    landmark = self._map_new(k, scan, index, pose, point, association)
                    self.policy.sighted(landmark.map_id, scan.t)
                    if returning:
                        # the same landmark back in the fixed-lag window (a new variable
                        # with its departure prior): scored as the association it is, not
                        # as a new landmark (which read as missed: UTIAS recall 0.96 with ids)
                        decision = AssociationDecision.MATCHED
            if landmark is None:
                self.recorder.association(
                    scan.t, index, -1, decision, reason, 1.0, association.alternatives_of(index)
                )
                continue
            self.pending.add(
                point_factor(
                    self.dimension,
                    self.config.landmark_factor,
                    pose_key,
                    landmark.key,
                    point,
                    association.noise[index],
                )
            )
            landmark.observations += 1
            landmark.last_t = scan.t
            self.pending.touch(landmark.key, scan.t)
            self.recorder.association(
                scan.t,
                index,
                landmark.map_id,
                decision,
                reason,
                association.inflation[index],
                association.alternatives_of(index),
            )
        self.recorder.landmark_count(scan.t, self.alive_count())

    def _predict(self, candidates: list[MapLandmark], pose_key: int, pose) -> KeyframePredictor:
        """The keyframe's prediction of ``candidates`` (their solved positions)."""
        keys = [landmark.key for landmark in candidates]
        values = self.backend.values(keys)
        read = values.atPoint3 if self.dimension == 3 else values.atPoint2
        positions = np.array([read(key) for key in keys], dtype=float)
        return KeyframePredictor(
            pose,
            pose_key,
            candidates,
            positions.reshape(len(keys), self.dimension),
            self.backend.joint,
            self.dimension,
        )

    def _record_nis(
        self,
        t: float,
        association: ScanAssociation,
        predictor: KeyframePredictor,
        points: np.ndarray,
        covariances: np.ndarray,
    ) -> None:
        """The stacked and per-landmark NIS of the matched sightings (module docstring)."""
        matched = association.rows(AssociationDecision.MATCHED)
        if not len(matched):
            return
        innovation = predictor.innovation(
            association.candidates[matched], points[matched], covariances[matched]
        )
        if innovation is None:
            self.recorder.event(t, "scan_nis_skipped", reason="S not positive definite")
            return
        self.recorder.innovation(
            t, innovation.nis, innovation.dof, innovation.group_nis, innovation.group_dof
        )

    def _unsolved_with_id(
        self, scan: LandmarkScan, index: int, association: ScanAssociation
    ) -> MapLandmark | None:
        """With ids: the landmark of this sighting's id when an earlier scan of the same
        keyframe gave it its (not yet solved) variable: the same landmark, not a new one."""
        if association.mode != "ids":
            return None
        landmark = self.book.landmarks.get(int(scan.ids[index]))
        if landmark is None or not self.pending.holds(landmark.key):
            return None
        return landmark

    def _map_new(
        self,
        k: int,
        scan: LandmarkScan,
        index: int,
        pose,
        point: np.ndarray,
        association: ScanAssociation,
    ) -> MapLandmark:
        """A new landmark (or a new variable of a known one that left the window) placed
        from a sighting; an anchor re-created keeps its prior."""
        map_id = int(scan.ids[index]) if association.mode == "ids" else self.book.new_map_id()
        world = np.asarray(pose.transformFrom(point), dtype=float)
        landmark = self._new_variable(map_id, world, scan.t)
        self.first_sightings[landmark.key] = (k, np.asarray(point, dtype=float))
        if landmark.anchor_position is not None:
            self.pending.add(
                landmark_prior(landmark.key, landmark.anchor_position, self.config.anchor_sigma_m)
            )
        elif map_id in self.departed:
            # back after leaving the fixed-lag window: its marginal at departure as a prior,
            # so the loop closes (an approximation: the marginal's correlation with the
            # states still in the window is dropped, which makes the closure optimistic)
            position, covariance = self.departed.pop(map_id)
            self.pending.add(landmark_marginal_prior(landmark.key, position, covariance))
            self.recorder.event(scan.t, "landmark_returned", map_id=map_id)
        return landmark
