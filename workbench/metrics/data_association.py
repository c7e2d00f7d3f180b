"""Scoring data association and loop closures against the true landmark ids.

Inputs are an estimate's ``Diagnostics`` (one association record per measured landmark of
every scan: time, index in the scan, the estimator's map id or -1, whether it created the
landmark) and ``GroundTruth.scan_ids`` (the true id of every measured landmark, per scan).

The *majority mapping* gives every estimator map id the true id most often associated with
it (ties go to the smallest true id). With it (common.md):

* an association decision (record with map id != -1 that did not create the landmark) is
  correct when the measurement's true id equals the majority true id of that map landmark;
* a measurement is a *positive* (it should have been associated) when its true landmark was
  already in the map: some map landmark with that majority true id was first recorded
  earlier, or the record associates it correctly to a landmark that existed before (an
  anchor or a prior-map landmark has no creation record);
* precision = correct associations / associations made; recall = correct associations /
  positives;
* a loop-closure pair ``[kept_id, removed_id]`` is correct when both ids map to the same
  true id; pairs with an id that never appears in the records are not scored.

Scan times are matched to the records' times within 1e-6 s; if two scans share one time the
first is used.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.estimate import Diagnostics, Event
from datasets.state import GroundTruth
from workbench.metrics.timestamps import EXACT_TOLERANCE_S

LOOP_CLOSURE_EVENT = "loop_closure"


def true_ids_of_records(
    diagnostics: Diagnostics, scan_ids: tuple[tuple[float, np.ndarray], ...]
) -> np.ndarray:
    """True landmark id of every association record, shape (A,); -1 where unknown (no scan
    at the record's time, or an index beyond that scan's measurements)."""
    record_t = np.asarray(diagnostics.assoc_t, dtype=float)
    result = np.full(len(record_t), -1, dtype=int)
    if len(record_t) == 0 or not scan_ids:
        return result
    scan_times = np.array([float(t) for t, _ in scan_ids])
    order = np.argsort(scan_times, kind="stable")
    sorted_times = scan_times[order]
    position = np.clip(
        np.searchsorted(sorted_times, record_t - EXACT_TOLERANCE_S, side="left"),
        0,
        len(sorted_times) - 1,
    )
    matched = np.abs(sorted_times[position] - record_t) <= EXACT_TOLERANCE_S
    for record, (found, scan_position) in enumerate(zip(matched, position)):
        if not found:
            continue
        ids = np.asarray(scan_ids[order[scan_position]][1])
        index = int(diagnostics.assoc_measurement_index[record])
        if 0 <= index < len(ids):
            result[record] = int(ids[index])
    return result


def majority_mapping(map_ids: np.ndarray, true_ids: np.ndarray) -> dict[int, int]:
    """Estimator map id -> the true id most often recorded with it (ties: smallest true id).

    Records with map id -1 or unknown true id (-1) are ignored.
    """
    map_ids = np.asarray(map_ids, dtype=int)
    true_ids = np.asarray(true_ids, dtype=int)
    usable = (map_ids != -1) & (true_ids != -1)
    mapping: dict[int, int] = {}
    if not np.any(usable):
        return mapping
    pairs, counts = np.unique(
        np.column_stack([map_ids[usable], true_ids[usable]]), axis=0, return_counts=True
    )
    # np.unique sorts by map id then true id, so the first maximum is the smallest true id.
    for map_id in np.unique(pairs[:, 0]):
        rows = np.flatnonzero(pairs[:, 0] == map_id)
        mapping[int(map_id)] = int(pairs[rows[np.argmax(counts[rows])], 1])
    return mapping


def landmark_id_mapping(diagnostics: Diagnostics, ground_truth: GroundTruth) -> dict[int, int]:
    """Estimator map id -> true id, for comparing maps with the true map.

    The majority mapping of the association records; a map id without any scored record
    (e.g. an anchor the estimator was given, or a source that passes true ids through
    without recording associations) maps to itself when the true map has that id.
    """
    mapping = majority_mapping(
        diagnostics.assoc_landmark_id, true_ids_of_records(diagnostics, ground_truth.scan_ids)
    )
    if ground_truth.landmarks is not None:
        # Identity only fills gaps: it never overrides a majority decision.
        for true_id in np.asarray(ground_truth.landmarks.ids, dtype=int):
            mapping.setdefault(int(true_id), int(true_id))
    return mapping


@dataclass(frozen=True)
class AssociationScore:
    """Counts and rates of association decisions (see module docstring).

    Attributes:
        records: association records with a known true id.
        associations: decisions to pair with an existing landmark.
        correct: correct ones among ``associations``.
        positives: measurements whose landmark was already in the map.
        new_landmarks: records that created a landmark.
        rejected: records with map id -1.
        precision, recall: None when the denominator is 0.
    """

    records: int
    associations: int
    correct: int
    positives: int
    new_landmarks: int
    rejected: int
    precision: float | None
    recall: float | None


def score_associations(
    diagnostics: Diagnostics, scan_ids: tuple[tuple[float, np.ndarray], ...]
) -> AssociationScore:
    """Precision and recall of the association decisions against the true ids."""
    true_ids = true_ids_of_records(diagnostics, scan_ids)
    known = true_ids != -1
    times = np.asarray(diagnostics.assoc_t, dtype=float)[known]
    map_ids = np.asarray(diagnostics.assoc_landmark_id, dtype=int)[known]
    is_new = np.asarray(diagnostics.assoc_is_new, dtype=bool)[known]
    true_ids = true_ids[known]
    mapping = majority_mapping(map_ids, true_ids)

    first_seen: dict[int, float] = {}
    for map_id, time in zip(map_ids, times):
        if map_id != -1:
            first_seen[int(map_id)] = min(first_seen.get(int(map_id), np.inf), float(time))
    earliest_for_true: dict[int, float] = {}
    for map_id, first in first_seen.items():
        true_id = mapping[map_id]
        earliest_for_true[true_id] = min(earliest_for_true.get(true_id, np.inf), first)

    associated = (map_ids != -1) & ~is_new
    correct = associated & np.array(
        [mapping.get(int(m), -2) == int(t) for m, t in zip(map_ids, true_ids)], dtype=bool
    )
    seen_before = np.array(
        [earliest_for_true.get(int(t), np.inf) < time for t, time in zip(true_ids, times)],
        dtype=bool,
    )
    positives = seen_before | correct
    n_associated, n_correct, n_positive = (
        int(np.sum(associated)),
        int(np.sum(correct)),
        int(np.sum(positives)),
    )
    return AssociationScore(
        records=int(len(true_ids)),
        associations=n_associated,
        correct=n_correct,
        positives=n_positive,
        new_landmarks=int(np.sum(is_new & (map_ids != -1))),
        rejected=int(np.sum(map_ids == -1)),
        precision=n_correct / n_associated if n_associated else None,
        recall=n_correct / n_positive if n_positive else None,
    )


@dataclass(frozen=True)
class LoopClosureScore:
    """Loop-closure events and the precision of their landmark pairs.

    Attributes:
        events: number of ``loop_closure`` events.
        pairs: landmark pairs in them; scored: pairs whose ids are both mapped.
        correct: scored pairs whose ids map to the same true id.
        precision: correct / scored, None when nothing was scored.
    """

    events: int
    pairs: int
    scored: int
    correct: int
    precision: float | None


def score_loop_closures(events: tuple[Event, ...], mapping: dict[int, int]) -> LoopClosureScore:
    """Score ``loop_closure`` events (details ``pairs=[[kept_id, removed_id], ...]``)."""
    closures = [event for event in events if event.kind == LOOP_CLOSURE_EVENT]
    pairs = [pair for event in closures for pair in event.details.get("pairs", [])]
    scored = [
        (mapping[int(kept)], mapping[int(removed)])
        for kept, removed in pairs
        if int(kept) in mapping and int(removed) in mapping
    ]
    correct = sum(1 for kept, removed in scored if kept == removed)
    return LoopClosureScore(
        events=len(closures),
        pairs=len(pairs),
        scored=len(scored),
        correct=correct,
        precision=correct / len(scored) if scored else None,
    )
