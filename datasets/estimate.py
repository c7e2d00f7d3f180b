"""``Estimate``: what every estimator returns, and the protocol every estimator follows.

Metrics read only an ``Estimate``. Estimators fill it through ``EstimateRecorder`` so that
every one of them records histories and diagnostics the same way (filterpy's lesson:
keep prior/posterior and innovation diagnostics, and NEES/NIS come for free).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol

import numpy as np
from pydantic import BaseModel

from datasets.measurements import Measurement, Sensor
from datasets.sequence import Sequence
from datasets.state import BlockName, Frame, LandmarkMap, StateBlock, StateHistory
from datasets.trajectory import Trajectory


@dataclass(frozen=True)
class Event:
    """A discrete event, e.g. a loop closure: time [s], kind, JSON-serialisable details."""

    t: float
    kind: str
    details: dict[str, Any] = field(default_factory=dict)


class AssociationDecision(enum.StrEnum):
    """What became of one landmark sighting (``filters.association`` decides; every
    estimator records one decision per sighting, so nothing is dropped silently)."""

    MATCHED = "matched"
    """paired with a map landmark and used in the update"""
    NEW = "new"
    """started a new landmark"""
    REJECTED = "rejected"
    """not used: inconsistent with its landmark, repeated, or unusable (the reason says)"""
    AMBIGUOUS = "ambiguous"
    """near some landmark but not paired with it: neither used nor mapped"""


@dataclass(frozen=True)
class Diagnostics:
    """Per-step diagnostics of a run.

    Attributes:
        nis_t, nis, nis_dof: one entry per associated measurement (a landmark, with its
            direction features where it has them): its innovation against its own
            diagonal block of S, shapes (M,).
        scan_nis_t, scan_nis, scan_nis_dof: one entry per update (a scan, or a keyframe's
            measurements for a smoother): the stacked innovation ``nu^T S^-1 nu`` of all
            its rows, dof = rows, shapes (U,). This is the NIS every estimator reports
            alike (sum NIS / sum dof).
        assoc_t, assoc_measurement_index, assoc_landmark_id, assoc_decision, assoc_reason,
        assoc_inflation: one entry per sighting in every scan, shapes (A,): the estimator's
            map id it was associated with or created (``-1`` otherwise), the
            ``AssociationDecision`` value, why it was not used ("" when matched or new), and
            the factor its noise was inflated by (1 unless a known id fell outside the gate).
        assoc_alternatives: (A,) how many other interpretations a geometric decision had
            within the new-landmark gate (``ScanAssociation.alternatives``), -1 where not
            judged (ids, multiple hypotheses); empty when the run recorded none.
        landmark_count_t, landmark_count: landmarks in the state after each scan, (S,).
        events: discrete events (loop closures, skipped inputs, ...).
        extras: estimator-specific per-step arrays saved into the run's npz.
    """

    nis_t: np.ndarray
    nis: np.ndarray
    nis_dof: np.ndarray
    scan_nis_t: np.ndarray
    scan_nis: np.ndarray
    scan_nis_dof: np.ndarray
    assoc_t: np.ndarray
    assoc_measurement_index: np.ndarray
    assoc_landmark_id: np.ndarray
    assoc_decision: np.ndarray
    assoc_reason: np.ndarray
    assoc_inflation: np.ndarray
    landmark_count_t: np.ndarray
    landmark_count: np.ndarray
    events: tuple[Event, ...] = ()
    extras: dict[str, np.ndarray] = field(default_factory=dict)
    assoc_alternatives: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))

    @property
    def assoc_is_new(self) -> np.ndarray:
        """(A,) bool: the sighting created its landmark."""
        return self.assoc_decision == AssociationDecision.NEW.value


@dataclass(frozen=True)
class StepTiming:
    """Wall-clock cost: per processed measurement (t [s], seconds), plus a final step."""

    t: np.ndarray
    seconds: np.ndarray
    finalize_seconds: float = 0.0


@dataclass(frozen=True)
class Estimate:
    """The result of one estimator on one sequence.

    Attributes:
        causal: what the estimator knew at each time (filters: the posterior after each
            step; incremental smoothers: the estimate right after each keyframe).
        smoothed: the full-information estimate (smoothers), or None.
        landmarks: the final map with marginal covariances, or None.
        diagnostics: innovations, NIS, associations, landmark counts, events.
        timing: per-step cost (filled by the runner, which times every estimator alike).
        notes: human-readable remarks the run should report (e.g. "anchors from first
            observation: NEES against truth not comparable").
        frame_times: times [s] where the data expect a pose, shape (F,): every landmark scan
            and every relative-pose increment (a lidar frame) the estimator was fed; filled
            by the runner, as the timing is (``workbench.metrics.summary`` says which frames
            have no pose). None when not recorded.
    """

    causal: StateHistory
    diagnostics: Diagnostics
    smoothed: StateHistory | None = None
    landmarks: LandmarkMap | None = None
    timing: StepTiming | None = None
    notes: tuple[str, ...] = ()
    frame_times: np.ndarray | None = None


class Estimator(Protocol):
    """The protocol shared by every filter and smoother.

    Class attributes:
        Config: pydantic model of the estimator's options (``--set key=value``).
        sensor_options: alternatives of sensor sets; the estimator runs on a sequence that
            provides every sensor of at least one alternative.
        dimensions: the dimensions (2, 3) it supports.
    """

    Config: ClassVar[type[BaseModel]]
    sensor_options: ClassVar[tuple[frozenset[Sensor], ...]]
    dimensions: ClassVar[frozenset[int]]

    def __init__(self, config: BaseModel, sequence: Sequence) -> None: ...

    def process(self, measurement: Measurement) -> None:
        """Consume one measurement (time-ordered)."""

    def estimate(self) -> Estimate:
        """Finish and return the result."""


def missing_sensors(
    options: tuple[frozenset[Sensor], ...], provided: frozenset[Sensor]
) -> frozenset[Sensor]:
    """Sensors missing for the closest alternative; empty when one alternative is satisfied."""
    gaps = [option - provided for option in options]
    return min(gaps, key=len) if gaps else frozenset()


class EstimateRecorder:
    """Accumulates an estimator's history and diagnostics, then builds an ``Estimate``.

    One mechanism for every estimator:
    - a pose or block recorded again at the *same* time replaces the earlier entry, so an
      estimator records after every step and the history holds one posterior per time;
    - map snapshots at most every ``snapshot_interval_s`` (``snapshot_due``), the final map
      always (``final_snapshot``);
    - innovations per update (stacked, ``innovation``) and per associated measurement;
    - one association record per sighting with its ``AssociationDecision``.
    Appending to lists and stacking once at the end keeps recording O(1) per step.
    """

    def __init__(self, dimension: int, snapshot_interval_s: float = 0.0) -> None:
        self.dimension = dimension
        self.snapshot_interval_s = float(snapshot_interval_s)
        self._pose_t: list[float] = []
        self._pose_positions: list[np.ndarray] = []
        self._pose_rotations: list[np.ndarray] = []
        self._pose_covariances: list[np.ndarray | None] = []
        self._blocks: dict[
            BlockName, tuple[Frame, list[float], list[np.ndarray], list[np.ndarray | None]]
        ] = {}
        self._landmark_snapshots: list[LandmarkMap] = []
        self._last_snapshot_t = -np.inf
        self._nis: list[tuple[float, float, int]] = []
        self._scan_nis: list[tuple[float, float, int]] = []
        self._assoc: list[tuple[float, int, int]] = []
        self._assoc_decisions: list[str] = []
        self._assoc_reasons: list[str] = []
        self._assoc_inflation: list[float] = []
        self._assoc_alternatives: list[int] = []
        self._counts: list[tuple[float, int]] = []
        self._events: list[Event] = []
        self._extras: dict[str, list[np.ndarray]] = {}

    def pose(
        self,
        t: float,
        position: np.ndarray,
        rotation: np.ndarray | float,
        covariance: np.ndarray | None,
    ) -> None:
        """Record a pose (interface conventions: see ``Trajectory``); replaces the last one
        when ``t`` equals its time."""
        if self._pose_t and self._pose_t[-1] == float(t):
            self._pose_t.pop()
            self._pose_positions.pop()
            self._pose_rotations.pop()
            self._pose_covariances.pop()
        self._pose_t.append(float(t))
        self._pose_positions.append(np.array(position, dtype=float))
        self._pose_rotations.append(np.array(rotation, dtype=float))
        self._pose_covariances.append(
            None if covariance is None else np.array(covariance, dtype=float)
        )

    def block(
        self,
        name: BlockName,
        t: float,
        value: np.ndarray,
        covariance: np.ndarray | None,
        frame: Frame = Frame.BODY,
    ) -> None:
        """Record one vector block value (velocity, gyro_bias, accel_bias); replaces the
        last one when ``t`` equals its time."""
        entry = self._blocks.setdefault(BlockName(name), (frame, [], [], []))
        if entry[1] and entry[1][-1] == float(t):
            for column in entry[1:]:
                column.pop()
        entry[1].append(float(t))
        entry[2].append(np.array(value, dtype=float).ravel())
        entry[3].append(None if covariance is None else np.array(covariance, dtype=float))

    def snapshot_due(self, t: float) -> bool:
        """Whether a map snapshot at ``t`` is due (``snapshot_interval_s`` since the last)."""
        return float(t) - self._last_snapshot_t >= self.snapshot_interval_s

    def landmarks(self, snapshot: LandmarkMap) -> None:
        """Record a landmark map snapshot (callers ask ``snapshot_due`` first)."""
        self._landmark_snapshots.append(snapshot)
        if snapshot.t is not None:
            self._last_snapshot_t = float(snapshot.t)

    def final_snapshot(self, snapshot: LandmarkMap) -> None:
        """Record the final map unless a snapshot at its time exists already."""
        if snapshot.t is None or float(snapshot.t) != self._last_snapshot_t:
            self.landmarks(snapshot)

    def nis(self, t: float, value: float, dof: int) -> None:
        """One associated measurement's NIS against its own block of S."""
        self._nis.append((float(t), float(value), int(dof)))

    def innovation(
        self, t: float, nis: float, dof: int, group_nis: np.ndarray, group_dof: np.ndarray
    ) -> None:
        """One update: its stacked NIS (``dof`` rows) and the NIS of each of its groups."""
        self._scan_nis.append((float(t), float(nis), int(dof)))
        for value, rows in zip(group_nis, group_dof, strict=True):
            self.nis(t, float(value), int(rows))

    def association(
        self,
        t: float,
        measurement_index: int,
        landmark_id: int,
        decision: AssociationDecision | str,
        reason: str = "",
        inflation: float = 1.0,
        alternatives: int = -1,
    ) -> None:
        """One sighting: the map id it matched or created (-1 otherwise), the decision,
        why it was not used, its noise inflation, and how many other interpretations a
        geometric decision had (``ScanAssociation.alternatives_of``; -1: not judged)."""
        decision = AssociationDecision(decision)
        self._assoc.append((float(t), int(measurement_index), int(landmark_id)))
        self._assoc_decisions.append(decision.value)
        self._assoc_reasons.append(str(reason))
        self._assoc_inflation.append(float(inflation))
        self._assoc_alternatives.append(int(alternatives))

    def landmark_count(self, t: float, count: int) -> None:
        self._counts.append((float(t), int(count)))

    def event(self, t: float, kind: str, **details: Any) -> None:
        self._events.append(Event(float(t), kind, details))

    def extra(self, name: str, row: np.ndarray | float) -> None:
        """Record one row of an estimator-specific per-step array."""
        self._extras.setdefault(name, []).append(np.asarray(row, dtype=float))

    def history(self) -> StateHistory:
        """The recorded history as a ``StateHistory``."""
        pose = None
        if self._pose_t:
            covariances = None
            if all(c is not None for c in self._pose_covariances):
                covariances = np.stack(self._pose_covariances)  # type: ignore[arg-type]
            pose = Trajectory(
                t=np.array(self._pose_t),
                positions=np.stack(self._pose_positions),
                rotations=np.stack(self._pose_rotations),
                covariances=covariances,
            )
        blocks = {}
        for name, (frame, times, values, covs) in self._blocks.items():
            stacked_covs = np.stack(covs) if all(c is not None for c in covs) else None  # type: ignore[arg-type]
            blocks[name] = StateBlock(np.array(times), np.stack(values), stacked_covs, frame)
        return StateHistory(pose=pose, blocks=blocks, landmarks=tuple(self._landmark_snapshots))

    def diagnostics(self) -> Diagnostics:
        nis = np.array(self._nis, dtype=float).reshape(-1, 3)
        scan_nis = np.array(self._scan_nis, dtype=float).reshape(-1, 3)
        assoc = np.array(self._assoc, dtype=float).reshape(-1, 3)
        counts = np.array(self._counts, dtype=float).reshape(-1, 2)
        return Diagnostics(
            nis_t=nis[:, 0],
            nis=nis[:, 1],
            nis_dof=nis[:, 2].astype(int),
            scan_nis_t=scan_nis[:, 0],
            scan_nis=scan_nis[:, 1],
            scan_nis_dof=scan_nis[:, 2].astype(int),
            assoc_t=assoc[:, 0],
            assoc_measurement_index=assoc[:, 1].astype(int),
            assoc_landmark_id=assoc[:, 2].astype(int),
            assoc_decision=np.array(self._assoc_decisions, dtype=str),
            assoc_reason=np.array(self._assoc_reasons, dtype=str),
            assoc_inflation=np.array(self._assoc_inflation, dtype=float),
            landmark_count_t=counts[:, 0],
            landmark_count=counts[:, 1].astype(int),
            events=tuple(self._events),
            extras={name: np.stack(rows) for name, rows in self._extras.items()},
            assoc_alternatives=np.array(self._assoc_alternatives, dtype=int),
        )

    def build(
        self,
        landmarks: LandmarkMap | None = None,
        smoothed: StateHistory | None = None,
        notes: tuple[str, ...] = (),
    ) -> Estimate:
        """The ``Estimate`` of everything recorded."""
        return Estimate(
            causal=self.history(),
            diagnostics=self.diagnostics(),
            smoothed=smoothed,
            landmarks=landmarks,
            notes=notes,
        )
