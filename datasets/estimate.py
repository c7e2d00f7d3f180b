"""``Estimate``: what every estimator returns, and the protocol every estimator follows.

Metrics read only an ``Estimate``. Estimators fill it through ``EstimateRecorder`` so that
every one of them records histories and diagnostics the same way (filterpy's lesson:
keep prior/posterior and innovation diagnostics, and NEES/NIS come for free).
"""

from __future__ import annotations

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


@dataclass(frozen=True)
class Diagnostics:
    """Per-step diagnostics of a run.

    Attributes:
        nis_t, nis, nis_dof: one entry per innovation (per associated landmark, or per
            stacked update, as the estimator documents), shapes (M,).
        assoc_t, assoc_measurement_index, assoc_landmark_id, assoc_is_new: one entry per
            measured landmark in every scan, shapes (A,): the estimator's map id it was
            associated with (``-1`` when rejected), and whether it created that landmark.
        landmark_count_t, landmark_count: landmarks in the state after each scan, (S,).
        events: discrete events (loop closures, skipped inputs, ...).
        extras: estimator-specific per-step arrays saved into the run's npz.
    """

    nis_t: np.ndarray
    nis: np.ndarray
    nis_dof: np.ndarray
    assoc_t: np.ndarray
    assoc_measurement_index: np.ndarray
    assoc_landmark_id: np.ndarray
    assoc_is_new: np.ndarray
    landmark_count_t: np.ndarray
    landmark_count: np.ndarray
    events: tuple[Event, ...] = ()
    extras: dict[str, np.ndarray] = field(default_factory=dict)


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
    """

    causal: StateHistory
    diagnostics: Diagnostics
    smoothed: StateHistory | None = None
    landmarks: LandmarkMap | None = None
    timing: StepTiming | None = None
    notes: tuple[str, ...] = ()


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

    Appending to lists and stacking once at the end keeps recording O(1) per step.
    """

    def __init__(self, dimension: int) -> None:
        self.dimension = dimension
        self._pose_t: list[float] = []
        self._pose_positions: list[np.ndarray] = []
        self._pose_rotations: list[np.ndarray] = []
        self._pose_covariances: list[np.ndarray | None] = []
        self._blocks: dict[
            BlockName, tuple[Frame, list[float], list[np.ndarray], list[np.ndarray | None]]
        ] = {}
        self._landmark_snapshots: list[LandmarkMap] = []
        self._nis: list[tuple[float, float, int]] = []
        self._assoc: list[tuple[float, int, int, bool]] = []
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
        """Record a pose (interface conventions: see ``Trajectory``)."""
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
        """Record one vector block value (velocity, gyro_bias, accel_bias)."""
        entry = self._blocks.setdefault(BlockName(name), (frame, [], [], []))
        entry[1].append(float(t))
        entry[2].append(np.array(value, dtype=float).ravel())
        entry[3].append(None if covariance is None else np.array(covariance, dtype=float))

    def landmarks(self, snapshot: LandmarkMap) -> None:
        """Record a landmark map snapshot (callers subsample if maps are large)."""
        self._landmark_snapshots.append(snapshot)

    def nis(self, t: float, value: float, dof: int) -> None:
        self._nis.append((float(t), float(value), int(dof)))

    def association(self, t: float, measurement_index: int, landmark_id: int, is_new: bool) -> None:
        self._assoc.append((float(t), int(measurement_index), int(landmark_id), bool(is_new)))

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
        assoc = np.array(self._assoc, dtype=float).reshape(-1, 4)
        counts = np.array(self._counts, dtype=float).reshape(-1, 2)
        return Diagnostics(
            nis_t=nis[:, 0],
            nis=nis[:, 1],
            nis_dof=nis[:, 2].astype(int),
            assoc_t=assoc[:, 0],
            assoc_measurement_index=assoc[:, 1].astype(int),
            assoc_landmark_id=assoc[:, 2].astype(int),
            assoc_is_new=assoc[:, 3].astype(bool),
            landmark_count_t=counts[:, 0],
            landmark_count=counts[:, 1].astype(int),
            events=tuple(self._events),
            extras={name: np.stack(rows) for name, rows in self._extras.items()},
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
