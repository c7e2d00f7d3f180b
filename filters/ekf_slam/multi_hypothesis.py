"""EKF-SLAM with multi-hypothesis association (``ekf-slam-mht``).

A single-hypothesis filter decides each scan's association once and for good; on UTIAS
MRCLAM without ids (a camera that sees one or two of 15 landmarks, 0.7-3 m apart, after
gaps of a minute) one wrong pairing corrupts the map and the rest of the run follows it
(``docs/association.md``). This estimator keeps several world-centric EKF-SLAM filters
(``filter.EkfSlam``), each the posterior under one history of association decisions: multiple
hypothesis tracking (Reid 1979) applied to a landmark map as in Cox and Leonard (1994), with
the hypotheses' filters as in their section 3 (one Kalman filter per hypothesis).

At each scan every hypothesis is extended by the scan's most likely interpretations
(``filters.association.hypotheses.ranked_hypotheses``: each sighting paired with a distinct
landmark inside its ``new_landmark_probability`` gate, or a new landmark of density
``new_landmark_density``), scored by the scan's joint likelihood under that hypothesis's
prediction. A hypothesis's score is the sum of its scans' log likelihoods, so the probability
of a history of decisions given the data, up to a common constant (Reid 1979, eq. 16). The
``max_hypotheses`` best survive, and none less likely than the best by more than
``hypothesis_log_window``; decisions older than ``commit_after_s`` are settled to the best
hypothesis's (N-scan-back pruning, ``_committed``). With the sequence's detection model
(``NoiseSpec.landmark_detection``) the score includes Reid's missed-detection term: a
landmark predicted in view and not sighted costs ``log(1 - P_D)`` at its range. With ids
the scan is decided by them (one child, no branching).

What the run records:
- **causal**: after each step, the posterior of the hypothesis most likely *at that time*
  (what the estimator would answer then), with that hypothesis's covariance (not a mixture);
- **associations, innovations, landmark counts and the final map**: those of the hypothesis
  most likely at the end. Its decisions are the ones the estimator stands by after seeing
  all the data: association precision and recall score the map it delivers, not what the
  leading hypothesis said at each scan (an event ``hypothesis_switch`` marks every scan after
  which the leader is not a continuation of the previous leader, and their count is in the
  notes).

Cost: with odometry input in 2-D the hypotheses other than the leader compose the odometry
samples between two scans into one increment (``motion.compose_planar``) and predict once
per scan, which gives the same mean and covariance as predicting every sample; the leader
predicts every sample, for the causal record. With other inputs every hypothesis predicts
every sample.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from pydantic import BaseModel

from datasets.detection_probability import in_view
from datasets.errors import InputError
from datasets.estimate import Estimate, EstimateRecorder
from datasets.measurements import LandmarkScan, Measurement, Odometry, Sensor
from datasets.sequence import Sequence
from datasets.stream_clock import StreamClock
from filters.association.hypotheses import ranked_hypotheses
from filters.ekf_slam import scan_update
from filters.ekf_slam.config import MultiHypothesisEkfSlamConfig
from filters.ekf_slam.filter import EkfSlam
from filters.ekf_slam.motion import compose_planar
from filters.ekf_slam.motion_input import motion_gap, planar_odometry_step

INTERPRETATIONS_PER_SCAN = 6
"""Interpretations of a scan each hypothesis is extended by (before the global pruning)."""


class _BranchLog:
    """What one hypothesis's filter records, kept as calls to replay into the run's
    ``EstimateRecorder`` if the hypothesis wins. Poses and map snapshots are not kept (the
    run records the leader's itself)."""

    KEPT = frozenset({"association", "innovation", "nis", "event", "extra", "landmark_count"})

    def __init__(self, calls: list[tuple[str, tuple, dict]] | None = None) -> None:
        self.calls = [] if calls is None else calls

    def __getattr__(self, name: str) -> Any:
        if name in self.KEPT:
            return lambda *args, **kwargs: self.calls.append((name, args, kwargs))
        if name == "snapshot_due":
            return lambda t: False
        if name in {"pose", "block", "landmarks", "final_snapshot"}:
            return lambda *args, **kwargs: None
        raise AttributeError(name)

    def take(self) -> tuple[tuple[str, tuple, dict], ...]:
        calls, self.calls = tuple(self.calls), []
        return calls


@dataclass
class _Hypothesis:
    """One history of association decisions: its filter, its log likelihood, and its
    recorded calls as a chain ``(earlier chain, calls of one scan, the scan's time [s])``
    shared with its siblings (a common ancestor is the same node object)."""

    filter: EkfSlam
    log_likelihood: float
    history: tuple | None


class MultiHypothesisEkfSlam:
    """World-centric EKF-SLAM keeping several association hypotheses (module docstring)."""

    Config: ClassVar[type[BaseModel]] = MultiHypothesisEkfSlamConfig
    sensor_options = EkfSlam.sensor_options
    dimensions = EkfSlam.dimensions

    def __init__(self, config: MultiHypothesisEkfSlamConfig, sequence: Sequence) -> None:
        if config.association in ("jcbb", "nearest"):
            raise InputError(
                f"ekf-slam-mht decides sightings without ids by its hypotheses; association={config.association} "
                "is ekf-slam's (use association=auto or ids)"
            )
        self.config = config
        first = EkfSlam(config, sequence)  # records the initial pose into its recorder
        self.recorder: EstimateRecorder = first.recorder
        first.recorder = _BranchLog()
        self.hypotheses = [_Hypothesis(first, 0.0, None)]
        self.leader = self.hypotheses[0]
        self.composing = first.input is Sensor.ODOMETRY and first.dimension == 2
        self.odometry_model = sequence.noise.odometry
        self.pending: tuple[np.ndarray, np.ndarray] | None = None
        self.motion_t = first.motion_t
        self.clock = StreamClock(f"ekf-slam-mht on {sequence.name}", first.t)
        self.t = first.t
        self.log_density = math.log(config.new_landmark_density)
        self.detection = _detection_model(config.detection_probability, sequence)
        stated = sequence.noise.landmark_detection
        self.detection_note = (
            "no missed-detection term"
            if self.detection is None
            else f"missed detections priced with P_D {config.detection_probability:g} in view"
            if not isinstance(config.detection_probability, str)
            else f"missed detections priced with the sequence's P_D by range ({stated.source})"
        )
        self.gaps = 0
        self.switches = 0
        self.peak = 1

    # ------------------------------------------------------------------ inputs
    def process(self, measurement: Measurement) -> None:
        self.clock.advance(measurement.t, type(measurement).__name__)
        self.t = max(self.t, float(measurement.t))
        if isinstance(measurement, LandmarkScan):
            self._catch_up()
            self._scan(measurement)
        elif measurement.sensor is self.leader.filter.input:
            if self.composing:
                self._odometry(measurement)  # type: ignore[arg-type]
            else:
                for hypothesis in self.hypotheses:
                    hypothesis.filter.process(measurement)
        else:
            return
        self.leader.filter.t = max(self.leader.filter.t, self.t)
        self.leader.filter.record_state(self.recorder)
        if isinstance(measurement, LandmarkScan) and self.recorder.snapshot_due(measurement.t):
            self.recorder.landmarks(self.leader.filter.map_snapshot(measurement.t))

    def _odometry(self, odometry: Odometry) -> None:
        """The leader predicts the sample; the others' composed increment grows by it."""
        dt = float(odometry.t) - self.motion_t
        if dt > self.config.max_gap_s:
            motion_gap(self.config, self.leader.filter.name, float(odometry.t), dt)
            self.gaps += 1
            self.recorder.event(odometry.t, "motion_gap", gap_s=dt, input=Sensor.ODOMETRY.value)
        step = planar_odometry_step(self.config, self.odometry_model, odometry, dt)
        self.leader.filter.advance_planar(*step, float(odometry.t))
        if len(self.hypotheses) > 1:  # the others' increment
            self.pending = step if self.pending is None else compose_planar(*self.pending, *step)
        self.motion_t = float(odometry.t)

    def _catch_up(self) -> None:
        """Every hypothesis but the leader predicts the odometry composed since the last scan."""
        if self.pending is not None:
            for hypothesis in self.hypotheses:
                if hypothesis is not self.leader:
                    hypothesis.filter.advance_planar(*self.pending, self.motion_t)
        self.pending = None

    # ------------------------------------------------------------------ scans
    def _scan(self, scan: LandmarkScan) -> None:
        children: list[tuple[float, _Hypothesis, Any]] = []
        for hypothesis in self.hypotheses:
            ekf = hypothesis.filter
            ekf.t = max(ekf.t, float(scan.t))
            points, noise = ekf.scan_inputs(scan)
            if ekf.policy.mode(scan.ids, scan.t) == "ids":
                association = ekf.policy.by_ids(
                    scan.ids,
                    points,
                    noise,
                    np.array(ekf.source_ids, dtype=int),
                    scan_update.predictor(ekf),
                )
                children.append((hypothesis.log_likelihood, hypothesis, association))
                continue
            for interpretation in ranked_hypotheses(
                points,
                noise,
                len(ekf.map_ids),
                scan_update.predictor(ekf),
                gate_probability=self.config.new_landmark_probability,
                new_landmark_log_density=self.log_density,
                count=INTERPRETATIONS_PER_SCAN,
                detection=self.detection,
            ):
                children.append(
                    (
                        hypothesis.log_likelihood + interpretation.log_likelihood,
                        hypothesis,
                        interpretation.association(noise),
                    )
                )
        children.sort(key=lambda child: -child[0])
        best = children[0][0]
        survivors = [c for c in children if c[0] >= best - self.config.hypothesis_log_window]
        survivors = survivors[: self.config.max_hypotheses]
        # copies first: a parent's filter is changed by the child that continues it
        uses: dict[int, int] = {}
        for _, parent, _ in survivors:
            uses[id(parent)] = uses.get(id(parent), 0) + 1
        filters: dict[int, list[EkfSlam]] = {}
        for _, parent, _ in survivors:
            if id(parent) not in filters:
                copies = [parent.filter.branch() for _ in range(uses[id(parent)] - 1)]
                filters[id(parent)] = [*copies, parent.filter]
        previous_leader = self.leader
        kept = []
        for score, parent, association in survivors:
            ekf = filters[id(parent)].pop()
            log = _BranchLog(list(parent.filter.recorder.calls))
            ekf.recorder = log
            points, noise = ekf.scan_inputs(scan)
            ekf.apply_association(scan, points, noise, association)
            kept.append(_Hypothesis(ekf, score, (parent.history, log.take(), float(scan.t))))
        kept = self._committed(kept, float(scan.t))
        self.hypotheses = kept
        self.leader = kept[0]
        if survivors[0][1] is not previous_leader:
            self.switches += 1
            self.recorder.event(scan.t, "hypothesis_switch", hypotheses=len(kept))
        self.peak = max(self.peak, len(kept))
        self.recorder.extra("hypotheses", [scan.t, len(kept)])

    def _committed(self, kept: list[_Hypothesis], t: float) -> list[_Hypothesis]:
        """N-scan-back pruning (Blackman 2004; Cox and Hingorani 1996): the
        decisions made more than ``commit_after_s`` before ``t`` are those of the best
        hypothesis; every hypothesis that differs from it there is dropped. Without it the
        kept hypotheses fill up with variants of old, settled choices (which of two copies
        of one landmark an old sighting went to), and a recent alternative, the true one
        among them, is pruned for want of room (UTIAS robot 2 without ids)."""
        horizon = self.config.commit_after_s
        if horizon is None or len(kept) == 1:
            return kept

        def ancestor(history: tuple | None) -> tuple | None:
            while history is not None and history[2] > t - horizon:
                history = history[0]
            return history

        settled = ancestor(kept[0].history)
        if settled is None:
            return kept
        return [hypothesis for hypothesis in kept if ancestor(hypothesis.history) is settled]

    # ------------------------------------------------------------------ output
    def estimate(self) -> Estimate:
        self._catch_up()
        winner = max(self.hypotheses, key=lambda hypothesis: hypothesis.log_likelihood)
        chain = []
        history = winner.history
        while history is not None:
            history, calls, _ = history
            chain.append(calls)
        chain.reverse()
        chain.append(winner.filter.recorder.calls)  # after the last scan
        for calls in chain:
            for name, args, kwargs in calls:
                getattr(self.recorder, name)(*args, **kwargs)
        ekf = winner.filter
        final_map = ekf.map_snapshot(self.t)
        self.recorder.final_snapshot(final_map)
        notes = (
            ekf.summary_note("ekf-slam-mht", extra_gaps=self.gaps),
            f"ekf-slam-mht: up to {self.peak} hypotheses kept (max_hypotheses={self.config.max_hypotheses}), "
            f"the leader switched to another history after {self.switches} scans; associations, NIS "
            "and the map are the final most likely hypothesis's, the causal trajectory each time's leader",
            f"ekf-slam-mht: {self.detection_note}; decisions settled after "
            + (
                "never (commit_after_s=None)"
                if self.config.commit_after_s is None
                else f"{self.config.commit_after_s:g} s (N-scan-back pruning)"
            ),
        )
        return self.recorder.build(landmarks=final_map, notes=notes)


def _detection_model(
    setting: float | str, sequence: Sequence
) -> Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]] | None:
    """The missed-detection term's model (``hypotheses.ranked_hypotheses``): predicted
    sightings (m, d) in the body frame -> (``P_D`` (m,), inside the landmark sensor's view
    (m,)), the view being the sequence's horizontal field of view and range (a missing limit
    does not limit). ``setting``: a constant ``P_D``, ``"sequence"`` (the sequence's
    ``P_D`` by range, ``NoiseSpec.landmark_detection``; None where it states none) or
    ``"none"`` (None)."""
    noise = sequence.noise
    if setting == "none" or (setting == "sequence" and noise.landmark_detection is None):
        return None
    stated = noise.landmark_detection if setting == "sequence" else None

    def model(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        points = np.asarray(points, dtype=float)
        visible = in_view(points, noise.landmark_field_of_view_deg, noise.landmark_range_m)
        if stated is None:
            return np.full(len(points), float(setting)), visible
        return stated.at(np.linalg.norm(points, axis=1)), visible

    return model
